"""Finger contact points on the surfaces of a patch assembly (``pito_core.contact``)."""

from __future__ import annotations

import numpy as np

from ._grasp import FINGER_LAYOUTS

__all__ = ["contacts_on_assembly"]


def contacts_on_assembly(name: str, n_fingers: int, seed: int = 0):
    """Contacts ``[(face, point (3,), normal (3,))]`` (face frames, m) for a finger layout.

    Each finger's (x, y) of :data:`FINGER_LAYOUTS` is projected along the face normal onto
    the surface of the assembly's patch on that face.
    """
    try:
        from ..contact import load_assembly
    except ImportError:  # pragma: no cover - depends on the contact package
        raise ValueError(f"assembly: patch assemblies are not available (pito_core.contact), got {name!r}") from None
    raise ValueError(f"assembly: not supported yet, got {name!r}")  # filled in below once contact exists

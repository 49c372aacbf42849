"""The patched object as the app shows it: the library's assemblies, display meshes, weight."""

from __future__ import annotations

import pyvista as pv

from pito_core.contact import list_assemblies as _list_assemblies
from pito_core.contact import load_assembly
from pito_core.frames import FACES

__all__ = ["list_assemblies", "load_assembly", "display_meshes", "weight"]


def list_assemblies() -> list[str]:
    """Object assemblies of the patch library (``assets/patches/``), ``pito_mixed`` first."""
    return sorted(_list_assemblies(), key=lambda n: (n != "pito_mixed", n))


def display_meshes(assembly) -> dict | None:
    """Face → pyvista mesh (core frame, m) of each patch, or None for the bare cube."""
    if assembly is None:
        return None
    return {i: pv.wrap(assembly.face_mesh(i)) for i in FACES}


def weight(assembly) -> float:
    """m·g of the object, N (0.3 kg when the assembly does not say)."""
    mass = getattr(assembly, "mass", None)
    return float(mass if mass else 0.3) * 9.81

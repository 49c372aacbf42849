"""One colour per face, shared by the 3D scene, every plot and the report.

The face colours are ``pito_core.frames.FACE_COLORS`` (the analysis figures use them too): six
distinct colours from the Okabe–Ito palette (colour-blind safe). The contact itself is drawn in :data:`CONTACT_COLOR`
(white, the papers' scene), its force arrow and torsion ring in the face's colour.
"""

from __future__ import annotations

from pito_core.frames import FACE_COLORS

__all__ = ["FACE_COLORS", "CONTACT_COLOR", "FLAGGED_CONTACT_COLOR", "hex_rgb"]

#: the contact sphere: high contrast against the patches and the dark background
CONTACT_COLOR = "#ffffff"

#: the sphere of a contact that one fingertip cannot explain (``ContactEstimate.single_contact`` False)
FLAGGED_CONTACT_COLOR = "#ff3b6b"


def hex_rgb(color: str) -> tuple[float, float, float]:
    """``#rrggbb`` → (r, g, b) in 0..1."""
    color = color.lstrip("#")
    return tuple(int(color[k : k + 2], 16) / 255.0 for k in (0, 2, 4))

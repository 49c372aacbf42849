"""One colour per face, shared by the 3D scene, every plot and the report.

Six distinct colours from the Okabe–Ito palette (colour-blind safe), chosen to read on the
dark background: its dark blue ``#0072B2`` and black are left out, so no two faces share a
hue (faces 1 and 5 were two blues). The contact itself is drawn in :data:`CONTACT_COLOR`
(white, the papers' scene), its force arrow and torsion ring in the face's colour.
"""

from __future__ import annotations

__all__ = ["FACE_COLORS", "CONTACT_COLOR", "FLAGGED_CONTACT_COLOR", "hex_rgb"]

#: face (1..6) → colour ``#rrggbb``
FACE_COLORS = {
    1: "#56B4E9",  # sky blue
    2: "#E69F00",  # orange
    3: "#009E73",  # bluish green
    4: "#CC79A7",  # reddish purple
    5: "#F0E442",  # yellow
    6: "#D55E00",  # vermillion
}

#: the contact sphere: high contrast against the patches and the dark background
CONTACT_COLOR = "#ffffff"

#: the sphere of a contact that one fingertip cannot explain (``ContactEstimate.single_contact`` False)
FLAGGED_CONTACT_COLOR = "#ff3b6b"


def hex_rgb(color: str) -> tuple[float, float, float]:
    """``#rrggbb`` → (r, g, b) in 0..1."""
    color = color.lstrip("#")
    return tuple(int(color[k : k + 2], 16) / 255.0 for k in (0, 2, 4))

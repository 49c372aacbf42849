"""One colour per face, for every view of the faces: the app's scene and plots, its report, the analysis figures.

Six distinct colours from the Okabe–Ito palette (colour-blind safe), chosen to read on a dark
background as on white: its dark blue ``#0072B2`` and black are left out, so no two faces share a hue.
"""

from __future__ import annotations

__all__ = ["FACE_COLORS"]

#: face (1..6) → colour ``#rrggbb``
FACE_COLORS = {
    1: "#56B4E9",  # sky blue
    2: "#E69F00",  # orange
    3: "#009E73",  # bluish green
    4: "#CC79A7",  # reddish purple
    5: "#F0E442",  # yellow
    6: "#D55E00",  # vermillion
}

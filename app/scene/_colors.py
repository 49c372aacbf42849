"""The scene's own colours (``#rrggbb``): the object's core and plates, the mount, the highlights.

The faces' and the contacts' colours are the app's (:mod:`app.palette`: one module for the
scene, the plots and the report).
"""

from __future__ import annotations

__all__ = ["PLATE_COLOR", "CORE_COLOR", "CONNECTED_COLOR", "ACTIVE_COLOR", "FLANGE_COLOR", "ATI_COLOR",
           "STAND_COLOR", "BACKGROUND"]

#: a face plate that is not highlighted
PLATE_COLOR = "#b8c2cc"
#: the cube's core between the plates
CORE_COLOR = "#5b6570"
#: the face on the calibration flange (:meth:`CubeScene.highlight`)
CONNECTED_COLOR = "#f0a030"
#: the face to load next (:meth:`CubeScene.highlight`)
ACTIVE_COLOR = "#2ecc71"
#: the calibration flange and its posts
FLANGE_COLOR = "#8a8f96"
#: the reference (ATI) sensor
ATI_COLOR = "#3a3f45"
#: the stand under the reference sensor
STAND_COLOR = "#4a5560"
#: the view's background
BACKGROUND = "#1e2329"

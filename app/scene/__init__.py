"""The 3D scene (pyvista in a native VTK window): the object, the calibration mount, contact glyphs.

One module per job:

- :mod:`._scene`: :class:`CubeScene`, the widget (the cube or a patched object, face numbers,
  the camera, the drawing thread);
- :mod:`._glyphs`: :class:`ContactGlyphs`, per face a contact sphere, force arrow, torsion
  ring, clamp collar and uncertainty ellipsoid, moved in place;
- :mod:`._poses`: the glyphs' and the camera's poses (numpy only; the general rotation is
  :func:`pito_core.frames.rotation_from_x`);
- :mod:`._mount`: the calibration mount's meshes;
- :mod:`._widget`: :func:`native_plotter`, the native GL window and its frame-rate limit;
- :mod:`._grab`: :func:`grab_scene`, :func:`grab_window` (screenshots, tests);
- :mod:`._colors`: the scene's own colours (the faces' are :mod:`app.palette`'s).

All geometry is in the core frame, metres.
"""

from ..palette import FACE_COLORS
from ._colors import ACTIVE_COLOR, BACKGROUND, CONNECTED_COLOR
from ._glyphs import FULL_SCALE_FORCE, ContactGlyphs
from ._grab import grab_scene, grab_window
from ._poses import arrow_matrix, disc_matrix, ellipsoid_matrix
from ._scene import PATCH_DISPLAY_CELLS, CubeScene
from ._widget import MAX_FRAME_RATE, is_software_gl, native_plotter

__all__ = [
    "ACTIVE_COLOR",
    "BACKGROUND",
    "CONNECTED_COLOR",
    "ContactGlyphs",
    "CubeScene",
    "FACE_COLORS",
    "FULL_SCALE_FORCE",
    "MAX_FRAME_RATE",
    "PATCH_DISPLAY_CELLS",
    "arrow_matrix",
    "disc_matrix",
    "ellipsoid_matrix",
    "grab_scene",
    "grab_window",
    "is_software_gl",
    "native_plotter",
]

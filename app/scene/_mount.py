"""The calibration mount's meshes: the flange on a face, the reference (ATI) sensor, its stand.

Drawn by :meth:`app.scene.CubeScene.set_mount` on the connected face. The shapes are a
sketch of the bench, sized by the cube's edge, not a CAD model.
"""

from __future__ import annotations

import pyvista as pv

from ._colors import ATI_COLOR, FLANGE_COLOR, STAND_COLOR

__all__ = ["mount_meshes"]


def mount_meshes(flange: str, edge: float) -> list[tuple[str, pv.PolyData, str]]:
    """The mount's parts in the connected face's frame (its normal +z, outwards), m.

    Parameters
    ----------
    flange : str
        ``"face"`` (a flange on the face itself), ``"frame_hole"`` (a plate with a hole) or
        ``"frame"`` (a solid plate); a plate holds the core's frame by four posts.
    edge : float
        The cube's edge, m.

    Returns
    -------
    list of (name, mesh, colour)
        ``"flange"``, the posts (``"post…"``, plate mounts only), ``"ati"`` and ``"stand"``.
    """
    e = edge
    meshes = []
    if flange == "face":
        meshes.append(("flange", pv.Cylinder(center=(0, 0, 0.08 * e), direction=(0, 0, 1), radius=0.38 * e, height=0.16 * e, resolution=48), FLANGE_COLOR))
        z0 = 0.16 * e
    else:
        z0 = 0.25 * e
        if flange == "frame_hole":
            plate = pv.Disc(inner=0.22 * e, outer=0.75 * e, r_res=1, c_res=48).extrude((0, 0, 0.08 * e), capping=True)
            plate = plate.translate((0, 0, z0 - 0.04 * e), inplace=False)
        else:
            plate = pv.Box(bounds=(-0.7 * e, 0.7 * e, -0.7 * e, 0.7 * e, z0 - 0.04 * e, z0 + 0.04 * e))
        meshes.append(("flange", plate, FLANGE_COLOR))
        # posts from the plate to the core frame's corners (the frame holds the core, not the face)
        for sx in (-1, 1):
            for sy in (-1, 1):
                meshes.append((f"post{sx}{sy}", pv.Box(bounds=(sx * 0.6 * e - 0.05 * e, sx * 0.6 * e + 0.05 * e, sy * 0.6 * e - 0.05 * e, sy * 0.6 * e + 0.05 * e, -0.55 * e, z0)), FLANGE_COLOR))
        z0 += 0.04 * e
    meshes.append(("ati", pv.Cylinder(center=(0, 0, z0 + 0.2 * e), direction=(0, 0, 1), radius=0.3 * e, height=0.4 * e, resolution=48), ATI_COLOR))
    meshes.append(("stand", pv.Box(bounds=(-1.0 * e, 1.0 * e, -1.0 * e, 1.0 * e, z0 + 0.4 * e, z0 + 0.5 * e)), STAND_COLOR))
    return meshes

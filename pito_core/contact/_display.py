"""Closed display solids for analytic patches (face frame, m).

A patch solid is the region between the face plane ``z = base_z`` and the patch surface
over the patch's boundary: a polar grid over the (star-shaped) boundary outline, mapped
onto the surface along the boundary's projection (vertical rays, or rays from the apex),
a flat base on the face and side walls joining the two outlines. Every solid is
watertight with outward normals, so an object made of the core and its six patch solids
is closed.
"""

from __future__ import annotations

import numpy as np

from ._surfaces import Ellipsoid, Plane

__all__ = ["patch_solid", "ray_surface"]


def ray_surface(surface, origins: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """Outermost intersection ``(N, 3)`` of rays ``o + t d`` with an analytic surface.

    For a quadric the larger root is taken (a ray that only grazes or misses is clamped
    to the closest approach); for a plane the single intersection.
    """
    if isinstance(surface, Plane):
        t = (surface.offset - origins @ surface.normal) / (directions @ surface.normal)
        return origins + t[:, None] * directions
    if isinstance(surface, Ellipsoid):
        R, a = surface.rotation, surface.semi_axes
        o = ((origins - surface.center) @ R) / a
        d = (directions @ R) / a
        A = (d * d).sum(1)
        B = (o * d).sum(1)
        C = (o * o).sum(1) - 1.0
        disc = np.maximum(B * B - A * C, 0.0)
        t = (-B + np.sqrt(disc)) / A
        return origins + t[:, None] * directions
    raise ValueError(f"surface: no analytic ray intersection for {type(surface).__name__}")


def patch_solid(surface, boundary, *, base_z: float = 0.0, rings: int = 12, segments: int = 96):
    """Watertight ``trimesh.Trimesh`` of an analytic patch on its face (face frame, m).

    Parameters
    ----------
    surface : Plane, Sphere or Ellipsoid
        The patch surface.
    boundary : PatchBoundary
        Its boundary (must have a shape; its outline must be star-shaped about its mean).
    base_z : float
        Height of the base (the face plane), m.
    rings, segments : int
        Radial and angular resolution of the grid.
    """
    import trimesh  # deferred: ~1 s to import; analytic patches are solved without it

    outline = boundary.outline(segments)
    M = len(outline)
    o2 = outline.mean(axis=0)
    r = np.arange(1, rings + 1) / rings
    grid = o2 + r[:, None, None] * (outline - o2)[None, :, :]  # (rings, M, 2)
    pts2 = np.vstack([o2[None, :], grid.reshape(-1, 2)])  # centre, then ring by ring
    base = np.c_[pts2, np.full(len(pts2), base_z)]
    if boundary.projection == "parallel":
        origins = np.c_[pts2, np.full(len(pts2), base_z)]
        dirs = np.tile([0.0, 0.0, 1.0], (len(pts2), 1))
        if isinstance(surface, Ellipsoid):  # start below the quadric: take its upper root
            origins[:, 2] = surface.center[2] - 2 * surface.semi_axes.max()
    else:
        apex = boundary.apex
        origins = np.tile(apex, (len(pts2), 1))
        dirs = np.c_[pts2, np.zeros(len(pts2))] - apex
    top = ray_surface(surface, origins, dirs)

    nv = len(pts2)
    faces = []
    ring0 = 1 + np.arange(M)
    nxt = np.roll(np.arange(M), -1)
    faces.append(np.c_[np.zeros(M, int), ring0, 1 + nxt])  # centre fan
    for k in range(rings - 1):
        a = 1 + k * M + np.arange(M)
        b = 1 + (k + 1) * M + np.arange(M)
        an, bn = 1 + k * M + nxt, 1 + (k + 1) * M + nxt
        faces.append(np.c_[a, b, bn])
        faces.append(np.c_[a, bn, an])
    top_faces = np.vstack(faces)
    bot_faces = top_faces[:, ::-1] + nv
    last = 1 + (rings - 1) * M + np.arange(M)
    lastn = 1 + (rings - 1) * M + nxt
    walls = np.vstack([np.c_[last + nv, lastn + nv, lastn], np.c_[last + nv, lastn, last]])
    mesh = trimesh.Trimesh(
        vertices=np.vstack([top, base]),
        faces=np.vstack([top_faces, bot_faces, walls]),
        process=True,
    )
    return mesh

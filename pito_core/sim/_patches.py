"""Finger contact points on the surfaces of a patch assembly (``pito_core.contact``).

Imported lazily by the live grasp source only: the simulator needs the patch library's
surfaces (face frames, m), not its solvers.
"""

from __future__ import annotations

import numpy as np

from ..contact import load_assembly
from ._grasp import FINGER_LAYOUTS

__all__ = ["contacts_on_assembly", "point_above"]


def point_above(surface, x: float, y: float) -> np.ndarray:
    """The outermost point ``(3,)`` of ``surface`` on the face-normal line through (x, y), m.

    Parameters
    ----------
    surface : pito_core.contact Plane, Sphere, Ellipsoid or MeshSurface
        Patch surface in its face frame.
    x, y : float
        In-plane coordinates in the face frame, m.

    Raises
    ------
    ValueError
        If the line misses the surface.
    """
    kind = getattr(surface, "kind", None)
    if kind == "plane":
        n = surface.normal
        if abs(n[2]) < 1e-9:
            raise ValueError("surface: a plane parallel to the face normal has no point above (x, y)")
        z = (surface.offset - n[0] * x - n[1] * y) / n[2]
        return np.array([x, y, z])
    if kind in ("sphere", "ellipsoid"):
        R, a, c = surface.rotation, surface.semi_axes, surface.center
        d = (R.T @ np.array([0.0, 0.0, 1.0])) / a
        q0 = (R.T @ (np.array([x, y, 0.0]) - c)) / a
        A, B, C = d @ d, 2 * q0 @ d, q0 @ q0 - 1
        disc = B * B - 4 * A * C
        if disc < 0:
            raise ValueError(f"surface: the line through ({x}, {y}) misses the {kind}")
        z = (-B + np.sqrt(disc)) / (2 * A)
        return np.array([x, y, z])
    if kind == "mesh":
        locs, _, _ = surface.mesh.ray.intersects_location([[x, y, 1.0]], [[0.0, 0.0, -1.0]])
        if len(locs) == 0:
            raise ValueError(f"surface: the line through ({x}, {y}) misses the mesh")
        return np.asarray(locs[np.argmax(locs[:, 2])], dtype=float)
    raise ValueError(f"surface: expected a Plane, Sphere, Ellipsoid or MeshSurface, got {type(surface).__name__}")


def contacts_on_assembly(name, n_fingers: int, seed: int = 0):
    """Contacts ``[(face, point (3,), normal (3,))]`` (face frames, m) of a finger layout.

    Each finger's (x, y) of :data:`FINGER_LAYOUTS` (jittered by ±2 mm with ``seed``) is
    taken straight above on the surface of the assembly's patch on that face; the normal
    is the surface's outward normal there.

    Parameters
    ----------
    name : str
        Assembly name of ``pito_core.contact.load_assembly`` ("cube", "sphere",
        "ellipsoid", "pito_mixed") or a path to an assembly file.
    n_fingers : {2, 3, 4, 5}
    seed : int
    """
    if n_fingers not in FINGER_LAYOUTS:
        raise ValueError(f"n_fingers: expected one of {tuple(FINGER_LAYOUTS)}, got {n_fingers!r}")
    try:
        asm = load_assembly(name)
    except (OSError, FileNotFoundError) as exc:
        raise ValueError(f"assembly: cannot load {name!r}: {exc}") from None
    rng = np.random.default_rng([int(seed), 0x96A5])
    out = []
    for _, face, (u, v) in FINGER_LAYOUTS[n_fingers][0]:
        du, dv = rng.uniform(-0.002, 0.002, 2)
        surf = asm.patches[face].surface
        p = point_above(surf, u + du, v + dv)
        n = np.asarray(surf.normal_at(p[None, :]))[0]
        out.append((face, p, n))
    return out

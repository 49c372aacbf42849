"""Pose maths of the scene (numpy only: no Qt, no VTK): where glyphs go and where the camera looks.

A glyph is a unit mesh (a +x arrow, a sphere, a disc in its xy plane) placed by a ``(4, 4)``
pose (its ``user_matrix``); the functions here make those poses, and the camera's. The
general rotation (``rotation_from_x``) is the core's (:mod:`pito_core.frames`). All in the
core frame, metres.
"""

from __future__ import annotations

import math

import numpy as np

from pito_core.frames import FACE_NORMALS, FACES, rotation_from_x

__all__ = ["arrow_matrix", "ellipsoid_matrix", "disc_matrix", "default_camera", "mount_camera", "framing_distance",
           "VIEW_ANGLE"]

#: degrees: the scene camera's vertical field of view
VIEW_ANGLE = 30.0


def arrow_matrix(tip, force, scale: float, width: float, max_length: float = np.inf, gap: float = 0.0) -> np.ndarray:
    """``(4, 4)`` pose of a unit +x arrow drawn as ``force`` pushing at ``tip``.

    Parameters
    ----------
    tip : array-like, shape (3,)
        Where the arrow ends (the contact point), m.
    force : array-like, shape (3,)
        The force, N (non-zero).
    scale : float
        Arrow length per newton, m/N.
    width : float
        Shaft scale, m (the unit arrow's radii are multiplied by this).
    max_length : float
        Longest arrow drawn, m (longer ones are clamped to it).
    gap : float
        The arrow ends this far before ``tip``, m (on the surface of the contact sphere).
    """
    force = np.asarray(force, dtype=float)
    length = min(math.sqrt(float(force @ force)) * scale, max_length)
    R = rotation_from_x(force)
    M = np.eye(4)
    M[:3, :3] = R @ np.diag([length, width, width])
    M[:3, 3] = np.asarray(tip, dtype=float) - R[:, 0] * (length + gap)
    return M


def ellipsoid_matrix(center, covariance, n_sigma: float = 2.0) -> np.ndarray:
    """``(4, 4)`` pose of a unit sphere drawn as the ``n_sigma`` ellipsoid of ``covariance`` (m²)."""
    cov = np.asarray(covariance, dtype=float)
    w, V = np.linalg.eigh(0.5 * (cov + cov.T))
    M = np.eye(4)
    M[:3, :3] = V @ np.diag(n_sigma * np.sqrt(np.clip(w, 0.0, None)))
    M[:3, 3] = center
    return M


def disc_matrix(center, normal, radius: float) -> np.ndarray:
    """Pose of a unit disc (in its xy plane, normal +z) centred at ``center`` facing ``normal``, scaled to ``radius``."""
    R = rotation_from_x(np.asarray(normal, dtype=float))
    R = R[:, [1, 2, 0]]  # z := normal
    M = np.eye(4)
    M[:3, :3] = R * radius
    M[:3, 3] = center
    return M


def default_camera(edge: float, distance: float = 4.6) -> list[tuple]:
    """The usual view of a cube of ``edge`` m, ``distance`` (in units of 1.35 edges) from its centre.

    Returns pyvista's ``camera_position``: ``[position, focal point, view up]``, m.
    """
    d = np.array([0.4, -1.0, 0.55])
    d *= distance * edge / np.linalg.norm(d) * 1.35
    return [tuple(d), (0, 0, 0), (0, 0, 1)]


def mount_camera(edge: float, connected_face: int, active_face: int | None = None, distance: float = 4.8,
                 elevation: float | None = None) -> list[tuple]:
    """A view of the cube on the calibration mount: the flange's face down, as on the bench.

    The active face (the one to load) is turned towards the viewer, seen from above
    (``elevation``, in units of the distance; higher up for the top face). Returns pyvista's
    ``camera_position``: ``[position, focal point, view up]``, m.
    """
    up = -np.array(FACE_NORMALS[connected_face])
    if active_face is not None and active_face != connected_face and abs(np.dot(FACE_NORMALS[active_face], up)) < 0.5:
        front = np.array(FACE_NORMALS[active_face])
    else:
        front = np.array(next(FACE_NORMALS[i] for i in FACES if abs(np.dot(FACE_NORMALS[i], up)) < 0.5))
    side = np.cross(up, front)
    if elevation is None:
        top = active_face is not None and np.allclose(FACE_NORMALS[active_face], up)
        elevation = 0.9 if top else 0.55  # the top face: look from higher up
    direction = front + 0.55 * side + elevation * up
    direction /= np.linalg.norm(direction)
    centre = -up * 0.25 * edge
    return [tuple(centre + distance * edge * direction), tuple(centre), tuple(up)]


def framing_distance(radius: float, width: int, height: int) -> float:
    """Camera distance, m, at which a sphere of ``radius`` m fits a ``width`` × ``height`` px view.

    The narrower field of view counts (the vertical one is :data:`VIEW_ANGLE`; the aspect is
    taken between 0.6 and 1, and as 1 for an unknown size).
    """
    half_v = np.radians(VIEW_ANGLE) / 2
    aspect = min(1.0, max(0.6, width / height)) if width > 0 and height > 0 else 1.0
    half = min(half_v, np.arctan(np.tan(half_v) * aspect))
    return float(radius / np.sin(half))

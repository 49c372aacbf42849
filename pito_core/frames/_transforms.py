"""Rigid transforms and wrench / twist changes of frame.

Conventions (docs/conventions.md, "Units and vectors" and "Poses"): a pose ``T_a_b`` is the 4x4 homogeneous matrix of
frame b expressed in frame a, so ``p_a = T_a_b @ p_b``. A wrench is
``[fx, fy, fz, tx, ty, tz]`` in N and N·m with the moment taken about the origin
of the frame it is expressed in. A twist is ``[vx, vy, vz, wx, wy, wz]`` in m/s
and rad/s, the velocity of the point at the frame's origin and the angular
velocity.
"""

from __future__ import annotations

import math

import numpy as np

from ._checks import check_pose, check_vectors

__all__ = [
    "WRENCH_COMPONENTS",
    "WRENCH_UNITS",
    "cross_rows",
    "pose_from_rotation_translation",
    "rotation_from_x",
    "invert_pose",
    "wrench_adjoint",
    "transform_wrench",
    "transform_twist",
    "transform_points",
    "transform_directions",
]


#: The order of a wrench's six components, everywhere in pito (arrays, files, channels, tables).
WRENCH_COMPONENTS = ("fx", "fy", "fz", "tx", "ty", "tz")
#: The units of :data:`WRENCH_COMPONENTS`: forces in N, moments in N·m.
WRENCH_UNITS = ("N", "N", "N", "N·m", "N·m", "N·m")

#: component indices (1, 2, 0) and (2, 0, 1): ``(a × b)_k = a_{k+1} b_{k+2} − a_{k+2} b_{k+1}``
_NEXT, _PREV = np.array([1, 2, 0]), np.array([2, 0, 1])


def cross_rows(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise cross product of ``(..., 3)`` arrays (broadcast), without ``np.cross``'s call overhead."""
    if a.shape == b.shape and a.dtype == b.dtype == np.float64:  # the common case: four gathers and three ufunc calls (np.cross's arithmetic)
        out = a.take(_NEXT, axis=-1) * b.take(_PREV, axis=-1)
        out -= a.take(_PREV, axis=-1) * b.take(_NEXT, axis=-1)
        return out
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    np.multiply(a1, b2, out=out[..., 0])
    out[..., 0] -= a2 * b1
    np.multiply(a2, b0, out=out[..., 1])
    out[..., 1] -= a0 * b2
    np.multiply(a0, b1, out=out[..., 2])
    out[..., 2] -= a1 * b0
    return out


def pose_from_rotation_translation(R, p) -> np.ndarray:
    """Pose ``T`` from a rotation ``R (3, 3)`` and a translation ``p (3,)`` in m."""
    R = np.asarray(R, dtype=float)
    p = np.asarray(p, dtype=float)
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = p
    return check_pose(T, "T")


def rotation_from_x(direction) -> np.ndarray:
    """The rotation taking the x axis onto ``direction``: its first column is ``direction``, normalised.

    Parameters
    ----------
    direction : array-like, shape (3,)
        Any non-zero vector (its length does not matter).

    Returns
    -------
    R : ndarray, shape (3, 3)
        A proper rotation (orthonormal, det +1). Its y axis is ``z × x`` (``y × x`` when the
        direction is within ~25° of ±z), so it changes smoothly with ``direction``.

    Notes
    -----
    Scalar arithmetic and no input checks: the live view calls it for every glyph on every
    drawn frame, where ``np.cross`` and ``np.linalg.norm`` on 3-vectors cost more in call
    overhead than in arithmetic.
    """
    x0, x1, x2 = (float(v) for v in direction)
    n = math.sqrt(x0 * x0 + x1 * x1 + x2 * x2)
    x0, x1, x2 = x0 / n, x1 / n, x2 / n
    if abs(x2) < 0.9:  # y = (0, 0, 1) × x
        y0, y1, y2 = -x1, x0, 0.0
    else:  # y = (0, 1, 0) × x
        y0, y1, y2 = x2, 0.0, -x0
    m = math.sqrt(y0 * y0 + y1 * y1 + y2 * y2)
    y0, y1, y2 = y0 / m, y1 / m, y2 / m
    z0, z1, z2 = x1 * y2 - x2 * y1, x2 * y0 - x0 * y2, x0 * y1 - x1 * y0  # z = x × y
    return np.array([[x0, y0, z0], [x1, y1, z1], [x2, y2, z2]])


def invert_pose(T_a_b) -> np.ndarray:
    """``T_b_a`` from ``T_a_b``, using the rotation's transpose (exact, no general inverse)."""
    T_a_b = check_pose(T_a_b, "T_a_b")
    R = T_a_b[:3, :3]
    p = T_a_b[:3, 3]
    T_b_a = np.eye(4)
    T_b_a[:3, :3] = R.T
    T_b_a[:3, 3] = -R.T @ p
    return T_b_a


def _skew(p: np.ndarray) -> np.ndarray:
    x, y, z = p
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def wrench_adjoint(T_a_b) -> np.ndarray:
    """6x6 matrix ``X`` with ``wrench_b = X @ wrench_a`` for the same load.

    Parameters
    ----------
    T_a_b : array-like, shape (4, 4)
        Pose of frame b in frame a.

    Returns
    -------
    X : ndarray, shape (6, 6)
        Maps ``[f_a, m_a]`` (moment about a's origin) to ``[f_b, m_b]``
        (moment about b's origin, components in b):
        ``f_b = Rᵀ f_a``, ``m_b = Rᵀ (m_a − p × f_a)``.
    """
    T_a_b = check_pose(T_a_b, "T_a_b")
    R = T_a_b[:3, :3]
    p = T_a_b[:3, 3]
    X = np.zeros((6, 6))
    X[:3, :3] = R.T
    X[3:, 3:] = R.T
    X[3:, :3] = -R.T @ _skew(p)
    return X


def transform_wrench(wrench, T_a_b) -> np.ndarray:
    """The same load, from frame a to frame b.

    Parameters
    ----------
    wrench : array-like, shape (..., 6)
        ``[fx, fy, fz, tx, ty, tz]`` in N and N·m, expressed in frame a,
        moment about a's origin.
    T_a_b : array-like, shape (4, 4)
        Pose of frame b in frame a.

    Returns
    -------
    wrench_b : ndarray, shape (..., 6)
        The same load expressed in frame b, moment about b's origin.
    """
    w = check_vectors(wrench, 6, "wrench")
    return w @ wrench_adjoint(T_a_b).T


def transform_twist(twist, T_a_b) -> np.ndarray:
    """The same rigid motion, from frame a to frame b.

    Parameters
    ----------
    twist : array-like, shape (..., 6)
        ``[vx, vy, vz, wx, wy, wz]`` (m/s, rad/s) in frame a: velocity of the
        body point at a's origin and angular velocity.
    T_a_b : array-like, shape (4, 4)
        Pose of frame b in frame a.

    Returns
    -------
    twist_b : ndarray, shape (..., 6)
        Velocity of the body point at b's origin and angular velocity, in b.
        Power is frame independent: ``twist_b · wrench_b == twist_a · wrench_a``.
    """
    t = check_vectors(twist, 6, "twist")
    T_a_b = check_pose(T_a_b, "T_a_b")
    R = T_a_b[:3, :3]
    p = T_a_b[:3, 3]
    v, w = t[..., :3], t[..., 3:]
    v_b = (v + np.cross(w, p)) @ R
    w_b = w @ R
    return np.concatenate([v_b, w_b], axis=-1)


def transform_points(points, T_a_b) -> np.ndarray:
    """Points ``(..., 3)`` in m given in frame b, expressed in frame a."""
    p = check_vectors(points, 3, "points")
    T_a_b = check_pose(T_a_b, "T_a_b")
    return p @ T_a_b[:3, :3].T + T_a_b[:3, 3]


def transform_directions(directions, T_a_b) -> np.ndarray:
    """Free vectors ``(..., 3)`` given in frame b, expressed in frame a (rotation only)."""
    d = check_vectors(directions, 3, "directions")
    T_a_b = check_pose(T_a_b, "T_a_b")
    return d @ T_a_b[:3, :3].T

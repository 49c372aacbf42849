"""Validation at the edge: turn input into float arrays and say what was expected."""

from __future__ import annotations

import numpy as np

#: Tolerance on ``RᵀR = I`` and ``det R = 1`` for a pose's rotation block.
ROTATION_TOL = 1e-6

__all__ = ["ROTATION_TOL", "check_pose", "check_vectors", "check_face"]


def check_vectors(x, size: int, name: str) -> np.ndarray:
    """Float array of shape ``(..., size)``; raises ``ValueError`` naming ``name``."""
    a = np.asarray(x, dtype=float)
    if a.ndim == 0 or a.shape[-1] != size:
        raise ValueError(f"{name}: expected shape (..., {size}), got {a.shape}")
    return a


def check_pose(T, name: str) -> np.ndarray:
    """Float ``(4, 4)`` rigid transform (orthonormal rotation, det +1, last row 0 0 0 1)."""
    a = np.asarray(T, dtype=float)
    if a.shape != (4, 4):
        raise ValueError(f"{name}: expected a 4x4 pose, got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name}: expected finite values, got NaN or inf")
    if not np.allclose(a[3], [0.0, 0.0, 0.0, 1.0], atol=ROTATION_TOL):
        raise ValueError(f"{name}: expected last row [0, 0, 0, 1], got {a[3].tolist()}")
    R = a[:3, :3]
    if not np.allclose(R.T @ R, np.eye(3), atol=ROTATION_TOL) or np.linalg.det(R) < 0:
        raise ValueError(f"{name}: expected a proper rotation block (RᵀR = I, det R = +1)")
    return a


def check_face(face, name: str = "face") -> int:
    """Face number 1..6 as an ``int``."""
    try:
        i = int(face)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected a face number 1..6, got {face!r}") from None
    if i != face or not 1 <= i <= 6:
        raise ValueError(f"{name}: expected a face number 1..6, got {face!r}")
    return i

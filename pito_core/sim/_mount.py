"""Load paths (docs/conventions.md): which face carries what under each mount."""

from __future__ import annotations

import numpy as np

from ..frames import FACES, CubeCore, check_face, invert_pose, wrench_adjoint
from ..io import FLANGES

__all__ = ["MOUNTS", "check_mount", "check_flanged_mount", "face_wrenches_from_applied", "core_from_face_adjoints",
           "face_from_core_adjoints"]

#: Flanges (docs/conventions.md, "Calibration mounts") plus ``None`` for a free grasp.
MOUNTS = FLANGES + (None,)


def check_mount(flange, connected_face):
    """Validated ``(flange, connected_face)``; ``connected_face`` is None for a free grasp."""
    if flange not in MOUNTS:
        raise ValueError(f"flange: expected one of {MOUNTS}, got {flange!r}")
    if flange is None:
        return None, None
    return flange, check_face(connected_face, "connected_face")


def check_flanged_mount(flange, connected_face, run: str = ""):
    """Validated ``(flange, connected_face)`` of a run that needs a flange (not a free grasp).

    ``run`` names the run in the error (e.g. ``"calibration run"``).
    """
    flange, connected_face = check_mount(flange, connected_face)
    if flange is None:
        raise ValueError(f"flange: expected one of {MOUNTS[:-1]}{' for a ' + run if run else ''}, got None")
    return flange, connected_face


def face_from_core_adjoints(core: CubeCore) -> np.ndarray:
    """``(6, 6, 6)``: ``X[i-1] @ W_core`` is a core-frame wrench expressed in face i's frame."""
    return np.stack([wrench_adjoint(core.face_pose(i)) for i in FACES])


def core_from_face_adjoints(core: CubeCore) -> np.ndarray:
    """``(6, 6, 6)``: ``X[i-1] @ F_i`` is face i's wrench expressed in the core frame."""
    return np.stack([wrench_adjoint(invert_pose(core.face_pose(i))) for i in FACES])


def face_wrenches_from_applied(applied_core, flange, connected_face, core: CubeCore):
    """Wrench on each face from the loads applied on each face, for a mount.

    Parameters
    ----------
    applied_core : array-like, shape (N, 6, 6)
        ``W_j``: load applied on face j at ``[:, j-1, :]``, core frame, ``[fx, fy, fz, tx,
        ty, tz]`` in N and N·m, moment about the core centre.
    flange : {"frame", "frame_hole", "face", None}
        The mount; None is a free grasp (no flange).
    connected_face : int or None
        Face the flange is on, 1..6 (ignored for a free grasp).
    core : CubeCore
        Geometry.

    Returns
    -------
    face_wrenches : ndarray, shape (N, 6, 6)
        ``F_i`` in face i's frame (moment about the face centre).
    W_total : ndarray, shape (N, 6)
        ``W = Σ_j W_j``, core frame: what the reference measures.
    W_frame : ndarray, shape (N, 6) or None
        Load through the outer frame's screw joints (flange on the frame), core frame; None
        when no load passes through them (face flange, free grasp).

    Raises
    ------
    ValueError
        If a load is applied on the connected face under the ``frame`` flange (it cannot
        be loaded).
    """
    W = np.asarray(applied_core, dtype=float)
    if W.ndim != 3 or W.shape[1:] != (6, 6):
        raise ValueError(f"applied_core: expected shape (N, 6, 6), got {W.shape}")
    flange, c = check_mount(flange, connected_face)
    W_total = W.sum(axis=1)
    W_frame = None
    if flange == "frame":
        if np.any(W[:, c - 1] != 0):
            raise ValueError(f"applied_core: face {c} is connected to a 'frame' flange and cannot be loaded")
        W_frame = W_total
    elif flange == "frame_hole":
        W_frame = W_total
    X = face_from_core_adjoints(core)
    Xblk = np.zeros((36, 36))
    for f in range(6):
        Xblk[6 * f : 6 * f + 6, 6 * f : 6 * f + 6] = X[f]
    F = (W.reshape(-1, 36) @ Xblk.T).reshape(W.shape)
    if flange == "face":
        # eq. 6 of the multi-touch paper: a direct load on the connected face is carried by
        # it, and it carries the reaction of every load applied elsewhere
        F[:, c - 1] = (2.0 * W[:, c - 1] - W_total) @ X[c - 1].T
    return F, W_total, W_frame

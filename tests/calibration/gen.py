"""A small generator of calibration sessions from a known gauge model (for tests only).

The full simulator is ``pito_core.sim``; this one is linear and exact so tests can
check recovery of a known matrix: ``counts = offset + K @ F + noise`` where ``F (36,)``
stacks the six face wrenches (face frames) and ``K (36, 36)`` is the true sensitivity.
"""

from __future__ import annotations

import numpy as np

from pito_core.calibration import CalibrationSession
from pito_core.frames import CubeCore, invert_pose, pose_from_rotation_translation, transform_wrench
from scipy.spatial.transform import Rotation

FULL_SCALE = np.array([15.0, 15.0, 15.0, 0.1, 0.1, 0.1])

#: method → the :func:`make_session` arguments of a session it can be fitted on (its mount)
CASES = {
    "face_to_face": dict(flange="frame_hole"),
    "quasi_total": dict(flange="frame"),
    "total": dict(flange="face"),
    "loaded_frame": dict(flange="frame_hole"),
    "unloaded_frame": dict(flange="face", free_only=True),
}


def true_sensitivity(seed=0, coupling=0.05, force_gain=2000.0, torque_gain=2e5):
    """``K (36, 36)`` counts per (N, N·m): well-conditioned blocks + inter-face coupling."""
    rng = np.random.default_rng(seed)
    K = np.zeros((36, 36))
    gains = np.array([force_gain] * 3 + [torque_gain] * 3)
    for i in range(6):
        for j in range(6):
            B = rng.normal(size=(6, 6)) * gains
            if i == j:
                B += np.diag(gains) * 3.0
            else:
                B *= coupling
            K[6 * i : 6 * i + 6, 6 * j : 6 * j + 6] = B
    return K


def T_core_ati_for(connected_face, core=None, offset=0.03):
    """A reference frame under the flange on ``connected_face``, rotated about its normal."""
    core = core or CubeCore()
    T_face = core.face_pose(connected_face)
    R = Rotation.from_euler("z", 30, degrees=True).as_matrix()
    T_face_ati = pose_from_rotation_translation(R, [0.0, 0.0, offset])
    return T_face @ T_face_ati


def make_session(K, flange="face", connected_face=6, faces=None, k=2000, n_unloaded=300, noise=2.0,
                 offset_level=1e6, seed=1, core=None, directions=None, squeeze_pairs=(), counts_dtype=np.int64,
                 free_only=False, response=None, reference_noise=0.0, load_scale=1.0):
    """A session with ``k`` single-face loads per face in ``faces`` (+ squeeze pairs).

    ``free_only`` leaves the connected face unloaded. ``directions`` (6,) bool limits the excited wrench components. Counts are rounded
    to integers unless ``counts_dtype`` is float. ``response`` (optional) replaces the linear
    ``F @ K.T``: a callable of the face wrenches ``F (n, 6, 6)`` (face frames) giving counts less
    the offset ``(n, 36)``. ``reference_noise`` is the reference's own noise (standard deviation
    as a fraction of ``FULL_SCALE`` per axis of S_A, on every sample, the unloaded ones too).
    ``load_scale`` scales every load (1: uniform in ± full scale).
    """
    rng = np.random.default_rng(seed)
    core = core or CubeCore()
    c = connected_face
    if faces is None:
        faces = [f for f in range(1, 7) if not ((flange == "frame" or free_only) and f == c)]
    T_core_ati = T_core_ati_for(c, core)
    T_ati_core = invert_pose(T_core_ati)
    poses = core.face_poses()
    rows_loaded, rows_W = [], []  # per sample: loaded mask, applied loads per face in core frame
    for f in faces:
        W = rng.uniform(-1, 1, size=(k, 6)) * FULL_SCALE * load_scale
        if directions is not None:
            W[:, ~np.asarray(directions)] = 0.0
        Wc = transform_wrench(W, invert_pose(poses[f - 1]))  # face frame -> core frame
        applied = np.zeros((k, 6, 6))
        applied[:, f - 1] = Wc
        m = np.zeros((k, 6), bool)
        m[:, f - 1] = True
        rows_loaded.append(m)
        rows_W.append(applied)
    for a, b in squeeze_pairs:
        applied = np.zeros((k, 6, 6))
        m = np.zeros((k, 6), bool)
        for f in (a, b):
            W = rng.uniform(-1, 1, size=(k, 6)) * FULL_SCALE * load_scale
            applied[:, f - 1] = transform_wrench(W, invert_pose(poses[f - 1]))
            m[:, f - 1] = True
        rows_loaded.append(m)
        rows_W.append(applied)
    loaded = np.vstack([np.zeros((n_unloaded, 6), bool)] + rows_loaded)
    applied = np.vstack([np.zeros((n_unloaded, 6, 6))] + rows_W)  # core frame, about core centre
    total = applied.sum(axis=1)
    carried = applied.copy()
    if flange == "face":  # eq. 6 of the multi-touch paper: the connected face carries its own load, −W of the others
        carried[:, c - 1] = applied[:, c - 1] - (total - applied[:, c - 1])
    elif flange == "frame":
        carried[:, c - 1] = 0.0
    F = np.stack([transform_wrench(carried[:, i], poses[i]) for i in range(6)], axis=1)  # face frames
    offset = offset_level * rng.uniform(0.5, 1.0, size=36)
    clean = F.reshape(-1, 36) @ K.T if response is None else response(F)
    counts = offset + clean + rng.normal(scale=noise, size=(len(F), 36)) if noise else offset + clean
    if np.issubdtype(counts_dtype, np.integer):
        counts = np.round(counts).astype(counts_dtype)
    reference = transform_wrench(total, T_core_ati)
    if reference_noise:
        reference = reference + rng.normal(size=reference.shape) * reference_noise * FULL_SCALE
    s = CalibrationSession(counts, reference, loaded, T_core_ati, flange, c, core=core, meta={"generator": "tests"})
    s.true_face_wrenches = F
    s.true_offset = offset
    return s

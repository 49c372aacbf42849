"""Fingertip touches on the flat patch: the contact-point test of the PITO paper."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..frames import check_face
from ._model import VirtualCube
from ._mount import check_flanged_mount, core_from_face_adjoints
from ._protocols import (
    _PROTOCOL_STREAM,
    PATCH_HEIGHT,
    PATCH_SIZE,
    TOUCH_POINTS,
    SimTruth,
    _block_trajectory,
    _Builder,
    _check_k,
    _model_or_default,
    _run,
    _tare_samples,
)

__all__ = ["TouchTruth", "simulate_touches"]


@dataclass(frozen=True)
class TouchTruth:
    """Ground truth of fingertip touches on a patch (face frame of the touched face).

    Attributes
    ----------
    face : int
        The touched face.
    point_index : ndarray of int, shape (N,)
        Index into ``points`` of the touched point, −1 when nothing touches.
    points : ndarray, shape (P, 3)
        Test points on the patch surface, m.
    point : ndarray, shape (N, 3)
        Contact point per sample, m (NaN when nothing touches).
    normal : ndarray, shape (N, 3)
        Outward surface normal at the contact (NaN when nothing touches).
    force : ndarray, shape (N, 3)
        Force of the fingertip on the patch, N.
    torsion : ndarray, shape (N,)
        Moment about the normal, N·m.
    sim : SimTruth
        The run's full truth.
    placed : ndarray, shape (T, 3)
        Where each touch actually landed (T = P × repeats, in touch order), m: the target
        point plus the placement scatter.
    placement_scatter : float
        Standard deviation of the placement per in-plane axis, m (0: ideal touches).
    """

    face: int
    point_index: np.ndarray
    points: np.ndarray
    point: np.ndarray
    normal: np.ndarray
    force: np.ndarray
    torsion: np.ndarray
    sim: SimTruth
    placed: np.ndarray | None = None
    placement_scatter: float = 0.0


def simulate_touches(
    face: int = 5,
    flange: str = "face",
    connected_face: int = 6,
    k: int = 1_000,
    seed: int = 0,
    points=None,
    model: VirtualCube | None = None,
    *,
    patch_height: float = PATCH_HEIGHT,
    reference="delta",
    t0: float = 0.0,
    tare_fraction: float = 0.05,
    placement_scatter: float = 0.0,
    repeats: int = 1,
):
    """Fingertip touches on the flat 46 × 46 mm patch of ``face``, one test point at a time.

    Parameters
    ----------
    face : int
        The touched face (must not be the connected face).
    flange, connected_face :
        The mount holding the object (default ``face`` flange on face 6).
    k : int
        Samples per touch (press, hold, release).
    points : array-like, shape (P, 2) or (P, 3), optional
        Touch points in the face frame, m; (x, y) on the flat patch at height
        ``patch_height``. Default :data:`TOUCH_POINTS` (8 edge points of a 26 × 26 mm
        square, then its centre).
    patch_height : float
        Height of the patch surface above the face centre, m.
    seed, model, reference, t0, tare_fraction :
        As :func:`simulate_calibration`.
    placement_scatter : float
        Placement error of a fingertip or pencil aimed at a marked point, m: each touch
        lands at the target plus an independent Gaussian offset of this standard deviation
        per in-plane axis (isotropic, fixed during the touch; clipped to the patch). A person
        aiming at a printed mark lands ~1–3 mm off; 0 (default) gives ideal touches.
    repeats : int
        Touches per point (the points are visited in order, ``repeats`` rounds).

    Returns
    -------
    session : CalibrationSession
        ``loaded[:, face-1]`` is True during the touches.
    truth : TouchTruth
        Contact points, normals, forces and torsions per sample.

    Notes
    -----
    Soft-finger contact (docs/conventions.md, "Contact model"): the face wrench is ``[f, c × f + τ n]`` with the normal
    force 2–8 N pressing into the patch, a tangential force under 0.3 of it and a torsion
    within ±2 mN·m.
    """
    flange, connected_face = check_flanged_mount(flange, connected_face, "touch run")
    face = check_face(face, "face")
    if face == connected_face:
        raise ValueError(f"face: expected a free face, got the connected face {face}")
    k = _check_k(k)
    model = _model_or_default(model)
    if points is None:
        points = TOUCH_POINTS
    pts = np.asarray(points, dtype=float)
    if pts.ndim != 2 or pts.shape[1] not in (2, 3) or pts.shape[0] < 1:
        raise ValueError(f"points: expected shape (P, 2) or (P, 3), got {pts.shape}")
    if pts.shape[1] == 2:
        pts = np.column_stack([pts, np.full(len(pts), float(patch_height))])
    if np.any(np.abs(pts[:, :2]) > PATCH_SIZE / 2):
        raise ValueError(f"points: expected points on the {PATCH_SIZE * 1000:.0f} mm patch (|x|, |y| <= {PATCH_SIZE / 2} m)")
    placement_scatter = float(placement_scatter)
    if not np.isfinite(placement_scatter) or placement_scatter < 0:
        raise ValueError(f"placement_scatter: expected a standard deviation >= 0 m, got {placement_scatter}")
    if int(repeats) != repeats or repeats < 1:
        raise ValueError(f"repeats: expected an integer >= 1, got {repeats}")
    repeats = int(repeats)
    rng = np.random.default_rng([int(seed), _PROTOCOL_STREAM["touches"], face, connected_face])
    # placement scatter from its own stream, so ideal runs (scatter 0) keep their loads
    rng_place = np.random.default_rng([int(seed), _PROTOCOL_STREAM["touches"], face, connected_face, 7])
    b = _Builder(model)
    b.rest(_tare_samples(k * len(pts) * repeats, tare_fraction))
    n_gap = max(5, k // 10)
    normal = np.array([0.0, 0.0, 1.0])
    order = np.tile(np.arange(len(pts)), repeats)
    placed = pts[order].copy()
    if placement_scatter > 0:
        placed[:, :2] += rng_place.normal(0.0, placement_scatter, (len(order), 2))
        placed[:, :2] = np.clip(placed[:, :2], -PATCH_SIZE / 2, PATCH_SIZE / 2)
    for t_idx, (p_idx, c) in enumerate(zip(order, placed)):
        fn = rng.uniform(2.0, 8.0)
        ang = rng.uniform(0, 2 * np.pi)
        ft = rng.uniform(0, 0.3) * fn
        tau = rng.uniform(-0.002, 0.002)
        press = np.array([ft * np.cos(ang), ft * np.sin(ang), -fn, tau])
        kp = np.stack([np.zeros(4), press, press * rng.uniform(0.8, 1.0), np.zeros(4)])
        ft_traj = _block_trajectory(k, kp, model.params.rate)  # (k, 4): f, τ
        f = ft_traj[:, :3]
        w = np.concatenate([f, np.cross(c, f) + ft_traj[:, 3:4] * normal], axis=1)
        b.load({face: w}, k, label=t_idx)
        b.rest(n_gap)
    applied, loaded, labels = b.finish()
    meta = {"protocol": "touches", "seed": int(seed), "face": face, "points": pts.tolist(), "k": k,
            "placement_scatter_m": placement_scatter, "repeats": repeats}
    session, sim = _run(model, applied, loaded, flange, connected_face, reference, rng, t0, meta, True)
    X = core_from_face_adjoints(model.core)[face - 1]
    w_face = np.linalg.solve(X, applied[:, face - 1].T).T  # back to the face frame
    touching = (labels >= 0) & (w_face[:, 2] < 0)  # the fingertip presses on the patch
    index = np.where(touching, order[np.maximum(labels, 0)], -1)
    point = np.full((len(labels), 3), np.nan)
    point[touching] = placed[labels[touching]]
    nrm = np.full((len(labels), 3), np.nan)
    nrm[touching] = normal
    torsion = np.where(touching, w_face[:, 5] - np.cross(np.nan_to_num(point), w_face[:, :3])[:, 2], 0.0)
    truth = TouchTruth(face, index, pts, point, nrm, w_face[:, :3], torsion, sim, placed, placement_scatter)
    return session, truth

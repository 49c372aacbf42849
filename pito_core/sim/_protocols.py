"""The papers' protocols on the simulator: tare, face by face, squeeze (touches: ``_touches``).

Each protocol builds the loads applied on the faces as smooth keypoint trajectories
(ramp, still hold, next direction), routes them through the mount (``_mount``), reads
them with the virtual cube and the reference, and returns a session in the core's format
(``CalibrationSession``), optionally with the ground truth (``SimTruth``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..frames import FACES, check_face
from ..io import CalibrationSession
from ._model import VirtualCube
from ._mount import check_flanged_mount, core_from_face_adjoints, face_wrenches_from_applied
from ._params import FULL_SCALE_FACE
from ._reference import ReferenceSensor, reference_pose
from ._signals import KeypointTrajectory

__all__ = [
    "SimTruth",
    "SQUEEZE_PAIRS",
    "TOUCH_POINTS",
    "PATCH_SIZE",
    "PATCH_HEIGHT",
    "simulate_calibration",
    "simulate_squeeze",
    "default_faces",
]

#: The squeeze pairs of the PITO paper, in its order.
SQUEEZE_PAIRS = ((1, 3), (2, 4), (3, 5), (4, 5), (2, 5), (1, 5), (1, 4), (1, 2))

#: Side of the flat patch, m (46 × 46 mm).
PATCH_SIZE = 0.046

#: Height of the flat patch's surface above its face's centre, m (face frame z; the library's
#: ``flat_46mm`` patch).
PATCH_HEIGHT = 0.003

#: Fingertip test points on the flat patch, face frame (x, y) in m: 8 points on the edges
#: of a 26 × 26 mm square (corners and mid-edges, counter-clockwise), then its centre.
TOUCH_POINTS = np.array(
    [
        (0.013, 0.013),
        (0.0, 0.013),
        (-0.013, 0.013),
        (-0.013, 0.0),
        (-0.013, -0.013),
        (0.0, -0.013),
        (0.013, -0.013),
        (0.013, 0.0),
        (0.0, 0.0),
    ]
)

#: At least this many load directions per face (or pair), so small runs still excite all
#: six wrench directions well.
_MIN_SEGMENTS = 24

_PROTOCOL_STREAM = {"calibration": 1, "squeeze": 2, "grasp": 3, "touches": 4}


@dataclass(frozen=True)
class SimTruth:
    """Ground truth of a simulated run (what no hardware can tell).

    Attributes
    ----------
    face_wrenches : ndarray, shape (N, 6, 6)
        Wrench on each face, face frames, N and N·m (moment about the face centre).
    applied : ndarray, shape (N, 6, 6)
        Load applied on each face ``W_j``, core frame, moment about the core centre.
    total : ndarray, shape (N, 6)
        ``W = Σ_j W_j``, core frame (what the reference measures, before its noise).
    time : ndarray, shape (N,)
        Sample times, s since the tare.
    temperature : ndarray, shape (N,)
        Temperature change since the tare, K.
    through_frame : bool
        Whether the load passed through the frame's screw joints (flange on the frame).
    """

    face_wrenches: np.ndarray
    applied: np.ndarray
    total: np.ndarray
    time: np.ndarray
    temperature: np.ndarray
    through_frame: bool


def default_faces(flange: str, connected_face: int) -> tuple:
    """Faces loaded in a calibration run: all six, but not the connected face of ``frame``."""
    return tuple(i for i in FACES if not (flange == "frame" and i == connected_face))


def _check_k(k, name="k", minimum=10) -> int:
    try:
        kk = int(k)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected an integer number of samples, got {k!r}") from None
    if kk != k or kk < minimum:
        raise ValueError(f"{name}: expected an integer >= {minimum}, got {k!r}")
    return kk


def _model_or_default(model) -> VirtualCube:
    if model is None:
        return VirtualCube()
    if not isinstance(model, VirtualCube):
        raise ValueError(f"model: expected a VirtualCube, got {type(model).__name__}")
    return model


def _block_trajectory(n: int, keypoints: np.ndarray, rate: float) -> np.ndarray:
    """Sample ``n`` points of a keypoint trajectory that ends on its last keypoint."""
    K = keypoints.shape[0] - 1
    period = n / (K * rate)
    traj = KeypointTrajectory(keypoints, period, ramp=0.6)
    return traj(np.arange(n) / rate)


def _random_keypoints(rng, n_segments: int, lo, hi, rest_every: int = 0) -> np.ndarray:
    """``(n_segments + 1, d)`` keypoints, zero at both ends and every ``rest_every``-th."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    kp = rng.uniform(lo, hi, size=(n_segments + 1, lo.size))
    kp[0] = 0.0
    kp[-1] = 0.0
    if rest_every:
        kp[rest_every::rest_every] = 0.0
    return kp


class _Builder:
    """Collects blocks of applied loads (face frames) and loaded masks, then fills one array."""

    def __init__(self, model: VirtualCube):
        self.model = model
        self.X_core_face = core_from_face_adjoints(model.core)
        self.blocks = []  # (n, {face: (n, 6) face-frame wrench}, label)

    def rest(self, n: int, label: int = -1):
        self.blocks.append((n, {}, label))

    def load(self, loads_face: dict, n: int, label: int = -1):
        """``loads_face``: {face: (n, 6) wrench in that face's frame at its centre}."""
        self.blocks.append((n, loads_face, label))

    def finish(self):
        """``applied (N, 6, 6)`` core frame, ``loaded (N, 6)``, ``labels (N,)``."""
        N = sum(n for n, _, _ in self.blocks)
        A = np.zeros((N, 6, 6))
        L = np.zeros((N, 6), dtype=bool)
        labels = np.empty(N, dtype=np.int64)
        start = 0
        for n, loads, label in self.blocks:
            for j, w in loads.items():
                A[start : start + n, j - 1] = w @ self.X_core_face[j - 1].T
                L[start : start + n, j - 1] = True
            labels[start : start + n] = label
            start += n
        return A, L, labels


def _run(model, applied, loaded, flange, connected_face, reference, rng, t0, meta, return_truth):
    """Route the applied loads through the mount, read the cube and the reference."""
    n = applied.shape[0]
    t = t0 + np.arange(n) / model.params.rate
    F, W_total, W_frame = face_wrenches_from_applied(applied, flange, connected_face, model.core)
    counts = model.counts_from_face_wrenches(F, t, W_frame=W_frame, rng=rng)
    T_core_ati = reference_pose(flange, connected_face, model.core)
    ref = ReferenceSensor(T_core_ati, reference)
    reading = ref.measure(W_total, rng=rng)
    meta = dict(meta)
    meta.update(
        simulated=True,
        cube_seed=model.seed,
        reference_model=ref.spec.name,
        sim_params=model.params.to_dict(),
        rate_hz=model.params.rate,
    )
    session = CalibrationSession(
        counts,
        reading,
        loaded,
        T_core_ati,
        flange,
        connected_face,
        core=model.core,
        time=t,
        meta=meta,
        counts_range=model.counts_range,
    )
    if not return_truth:
        return session
    truth = SimTruth(F, applied, W_total, t, model.temperature(t), W_frame is not None)
    return session, truth


def _tare_samples(n_loaded: int, fraction: float) -> int:
    if not 0 < fraction < 1:
        raise ValueError(f"tare_fraction: expected a fraction in (0, 1), got {fraction!r}")
    return max(20, int(np.ceil(fraction * n_loaded / (1 - fraction))))


def simulate_calibration(
    flange: str,
    connected_face: int,
    k: int = 10_000,
    seed: int = 0,
    faces=None,
    model: VirtualCube | None = None,
    *,
    reference="delta",
    t0: float = 0.0,
    tare_fraction: float = 0.05,
    segment_samples: int = 250,
    return_truth: bool = False,
):
    """A calibration session as the papers ran it: tare, then face by face.

    Parameters
    ----------
    flange : {"frame", "frame_hole", "face"}
        The calibration mount.
    connected_face : int
        Face the flange is on, 1..6.
    k : int
        Samples per loaded face (the papers: ~10⁴).
    seed : int
        Seed of the run (load directions, noise); the cube is ``model``'s.
    faces : sequence of int, optional
        Faces loaded one at a time, in order. Default: all six, without the connected
        face under the ``frame`` flange (it cannot be loaded). Under ``face`` a load on
        the connected face is carried by that face (eq. 6 of the multi-touch paper).
    model : VirtualCube, optional
        The simulated cube (default ``VirtualCube()``, seed 0).
    reference : {"delta", "nano17"} or ReferenceSpec
        The reference sensor.
    t0 : float
        Time of the first sample, s since the cube's tare (temperature drift).
    tare_fraction : float
        Fraction of the samples that are unloaded, at the start (offset), default 5 %.
    segment_samples : int
        Samples per move-and-hold segment of the loading gestures (shorter when k is
        small: at least 24 segments per face).
    return_truth : bool
        Also return the :class:`SimTruth`.

    Returns
    -------
    session : CalibrationSession
        ``counts (N, 36)`` int32, ``reference (N, 6)`` (N, N·m, reference frame, tared),
        ``loaded (N, 6)``; unloaded samples first; ``time`` in s; ``meta["simulated"]``.
    truth : SimTruth
        Only with ``return_truth=True``.

    Notes
    -----
    Each face's applied wrench (face frame, at the face centre) moves between random
    keypoints uniform in ±15 N and ±0.1 N·m per axis, holding still between moves; it
    starts from and returns to zero at the ends of the face's block (short rests between
    faces are unloaded samples).
    """
    flange, connected_face = check_flanged_mount(flange, connected_face, "calibration run")
    k = _check_k(k)
    segment_samples = _check_k(segment_samples, "segment_samples", minimum=2)
    model = _model_or_default(model)
    if faces is None:
        faces = default_faces(flange, connected_face)
    faces = tuple(check_face(f, "faces") for f in faces)
    if not faces:
        raise ValueError("faces: expected at least one face")
    if flange == "frame" and connected_face in faces:
        raise ValueError(f"faces: face {connected_face} is connected to a 'frame' flange and cannot be loaded")
    rng = np.random.default_rng([int(seed), _PROTOCOL_STREAM["calibration"], connected_face, len(flange)])
    fs = np.asarray(FULL_SCALE_FACE)
    b = _Builder(model)
    b.rest(_tare_samples(k * len(faces), tare_fraction))
    n_gap = max(5, k // 100)
    for idx, j in enumerate(faces):
        n_seg = max(_MIN_SEGMENTS, int(np.ceil(k / segment_samples)))
        kp = _random_keypoints(rng, n_seg, -fs, fs, rest_every=0)
        b.load({j: _block_trajectory(k, kp, model.params.rate)}, k, label=j)
        if idx < len(faces) - 1:
            b.rest(n_gap)
    applied, loaded, _ = b.finish()
    meta = {"protocol": "calibration", "seed": int(seed), "faces": list(faces), "k": k}
    return _run(model, applied, loaded, flange, connected_face, reference, rng, t0, meta, return_truth)


def simulate_squeeze(
    flange: str = "face",
    connected_face: int = 6,
    k: int = 5_000,
    seed: int = 0,
    pairs=SQUEEZE_PAIRS,
    model: VirtualCube | None = None,
    *,
    reference="delta",
    t0: float = 0.0,
    tare_fraction: float = 0.05,
    segment_samples: int = 250,
    return_truth: bool = False,
):
    """Squeeze runs: two faces loaded at once, pair after pair (the PITO paper's pairs).

    Parameters
    ----------
    flange, connected_face :
        The mount (default ``face`` flange on face 6, below the paper's pairs).
    k : int
        Samples per pair.
    pairs : sequence of (int, int)
        Face pairs, default :data:`SQUEEZE_PAIRS` (1–3, 2–4, 3–5, 4–5, 2–5, 1–5, 1–4, 1–2).
        Pairs including the connected face of a ``frame`` flange are skipped.
    seed, model, reference, t0, tare_fraction, segment_samples, return_truth :
        As :func:`simulate_calibration`.

    Returns
    -------
    session : CalibrationSession
        Two True entries per loaded row of ``loaded``; ``meta["pairs"]`` lists the pairs run.
    truth : SimTruth
        Only with ``return_truth=True``.

    Notes
    -----
    Each face of a pair is pressed (face-frame ``fz`` in −15 … −1 N, i.e. pushing into
    the face), sheared (``fx, fy`` within ±5 N) and twisted (torques within ±0.1 N·m),
    independently of the other.
    """
    flange, connected_face = check_flanged_mount(flange, connected_face, "squeeze run")
    k = _check_k(k)
    model = _model_or_default(model)
    run_pairs = []
    for p in pairs:
        if len(p) != 2:
            raise ValueError(f"pairs: expected pairs of two faces, got {p!r}")
        a, c = check_face(p[0], "pairs"), check_face(p[1], "pairs")
        if a == c:
            raise ValueError(f"pairs: expected two different faces, got {p!r}")
        if flange == "frame" and connected_face in (a, c):
            continue
        run_pairs.append((a, c))
    if not run_pairs:
        raise ValueError("pairs: no pair can be loaded under this mount")
    rng = np.random.default_rng([int(seed), _PROTOCOL_STREAM["squeeze"], connected_face, len(flange)])
    lo = np.array([-5.0, -5.0, -15.0, -0.1, -0.1, -0.1])
    hi = np.array([5.0, 5.0, -1.0, 0.1, 0.1, 0.1])
    b = _Builder(model)
    b.rest(_tare_samples(k * len(run_pairs), tare_fraction))
    n_gap = max(5, k // 100)
    for idx, (a, c) in enumerate(run_pairs):
        n_seg = max(_MIN_SEGMENTS, int(np.ceil(k / segment_samples)))
        loads = {}
        for f in (a, c):
            kp = _random_keypoints(rng, n_seg, lo, hi, rest_every=0)
            kp[0] = kp[-1] = 0.0
            loads[f] = _block_trajectory(k, kp, model.params.rate)
        b.load(loads, k, label=idx)
        if idx < len(run_pairs) - 1:
            b.rest(n_gap)
    applied, loaded, _ = b.finish()
    meta = {"protocol": "squeeze", "seed": int(seed), "pairs": [list(p) for p in run_pairs], "k": k}
    return _run(model, applied, loaded, flange, connected_face, reference, rng, t0, meta, return_truth)

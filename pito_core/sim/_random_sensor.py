"""Random virtual cubes, unlike ``VirtualCube``'s structured hub model (SIMULATED data).

For checking the calibration against the papers' plain least squares on sensors nobody
designed: every face's 6×6 gain block is a random matrix of a chosen condition number,
every off-diagonal block is dense random coupling, the gauge noise is anisotropic, the
offsets are large. The model is linear, so the truth is exact::

    counts = round(offset + K · [F_1 … F_6] + noise),   noise ~ N(0, diag(noise_std²))

with ``F_i`` the wrench on face i (face frame, N and N·m) from the loads applied, routed
by the mount's load paths (``face_wrenches_from_applied``, docs/conventions.md).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..frames import FACES, N_GAUGES, CubeCore, invert_pose, transform_wrench
from ..io import CalibrationSession
from ._mount import check_mount, face_wrenches_from_applied
from ._params import FULL_SCALE_FACE
from ._reference import reference_pose

__all__ = ["RandomSensor", "random_sensor", "random_sensor_session"]

_FS = np.asarray(FULL_SCALE_FACE)


@dataclass
class RandomSensor:
    """A random linear cube (SIMULATED).

    Attributes
    ----------
    sensitivity : ndarray, shape (36, 36)
        ``K``: counts per unit of the stacked face wrenches (face frames, N and N·m);
        block (i, j) is face j's load read on face i's gauges.
    offset : ndarray, shape (36,)
        Zero-load counts.
    noise_std : ndarray, shape (36,)
        Gaussian noise of each gauge, counts.
    core : CubeCore
    seed : int
    conditions : ndarray, shape (6,)
        Condition number of each face's own block in full-scale units.
    coupling : ndarray, shape (6, 6)
        Size of each off-diagonal block relative to the receiving face's gain (0 on the diagonal).
    """

    sensitivity: np.ndarray
    offset: np.ndarray
    noise_std: np.ndarray
    core: CubeCore
    seed: int
    conditions: np.ndarray
    coupling: np.ndarray

    def counts(self, face_wrenches, rng) -> np.ndarray:
        """Counts ``(N, 36)`` (float, integer-valued) for ``face_wrenches (N, 6, 6)`` (face frames)."""
        F = np.asarray(face_wrenches, dtype=float).reshape(-1, 36)
        c = self.offset + F @ self.sensitivity.T + rng.standard_normal(F.shape) * self.noise_std
        return np.rint(c)


def random_sensor(seed: int = 0, *, condition=(1.0, 1e3), coupling=(0.0, 0.10), noise=(0.5, 5.0),
                  offset=3e7, gain=(1e3, 1e5), core: CubeCore | None = None) -> RandomSensor:
    """A random linear cube (SIMULATED).

    Parameters
    ----------
    seed : int
        The same seed is the same sensor.
    condition : (float, float)
        Range of each face's own-block condition number (log-uniform), in full-scale units
        (±15 N, ±0.1 N·m).
    coupling : (float, float)
        Range of each off-diagonal block's size relative to the receiving face's gain (uniform).
    noise : (float, float)
        Range of each gauge's noise standard deviation, counts (log-uniform).
    offset : float
        Offsets are uniform in ``±offset`` counts.
    gain : (float, float)
        Range of each face's largest full-scale response, counts (log-uniform).
    core : CubeCore, optional
    """
    rng = np.random.default_rng([int(seed), 0x7A4D])
    core = CubeCore() if core is None else core
    logu = lambda lo, hi, size=None: np.exp(rng.uniform(np.log(lo), np.log(hi), size))  # noqa: E731
    K = np.zeros((36, 36))
    conds = logu(*condition, 6) if condition[1] > condition[0] else np.full(6, float(condition[0]))
    gains = logu(*gain, 6) if gain[1] > gain[0] else np.full(6, float(gain[0]))
    cpl = np.zeros((6, 6))
    for i in range(6):
        Q1, _ = np.linalg.qr(rng.standard_normal((6, 6)))
        Q2, _ = np.linalg.qr(rng.standard_normal((6, 6)))
        s = gains[i] * np.logspace(0.0, -np.log10(conds[i]), 6)
        K[6 * i : 6 * i + 6, 6 * i : 6 * i + 6] = (Q1 * s) @ Q2.T / _FS
        for j in range(6):
            if j != i:
                cpl[i, j] = rng.uniform(*coupling)
                G = rng.standard_normal((6, 6)) / np.sqrt(6)
                K[6 * i : 6 * i + 6, 6 * j : 6 * j + 6] = cpl[i, j] * gains[i] * G / _FS
    return RandomSensor(
        sensitivity=K,
        offset=rng.uniform(-offset, offset, N_GAUGES),
        noise_std=logu(*noise, N_GAUGES),
        core=core,
        seed=int(seed),
        conditions=conds,
        coupling=cpl,
    )


def random_sensor_session(sensor: RandomSensor, flange: str, connected_face: int, k: int, *, n_tare: int = 100,
                          faces=None, squeeze_pairs=(), k_squeeze: int | None = None, seed: int = 0,
                          reference_noise: float = 0.0):
    """A SIMULATED calibration session of ``sensor`` under a mount, with its truth.

    Parameters
    ----------
    sensor : RandomSensor
    flange : {"frame", "frame_hole", "face"}
    connected_face : int
    k : int
        Single-face samples per loaded face; loads uniform in ±15 N, ±0.1 N·m per axis
        (face frame, at the face centre).
    n_tare : int
        Unloaded samples, at the start.
    faces : sequence of int, optional
        Faces loaded one at a time (default all, without the connected face of ``frame``).
    squeeze_pairs : sequence of (int, int)
        Pairs of faces loaded together (``k_squeeze`` samples each, default ``k``).
    seed : int
    reference_noise : float
        Standard deviation of the reference's noise relative to full scale (0: exact).

    Returns
    -------
    session : CalibrationSession
        ``meta["simulated"] = True``.
    face_wrenches : ndarray, shape (N, 6, 6)
        The true wrench on each face (face frames, N and N·m).
    """
    flange, c = check_mount(flange, connected_face)
    rng = np.random.default_rng([int(seed), sensor.seed, 0x5E55])
    if faces is None:
        faces = tuple(i for i in FACES if not (flange == "frame" and i == c))
    k_sq = int(k if k_squeeze is None else k_squeeze)
    poses = sensor.core.face_poses()
    groups = [(f,) for f in faces] + [tuple(p) for p in squeeze_pairs]
    n = int(n_tare) + int(k) * len(faces) + k_sq * len(squeeze_pairs)
    applied = np.zeros((n, 6, 6))
    loaded = np.zeros((n, 6), dtype=bool)
    start = int(n_tare)
    for g in groups:
        m = int(k) if len(g) == 1 else k_sq
        for f in g:
            W = rng.uniform(-1.0, 1.0, (m, 6)) * _FS
            applied[start : start + m, f - 1] = transform_wrench(W, invert_pose(poses[f - 1]))
            loaded[start : start + m, f - 1] = True
        start += m
    F, W_total, _ = face_wrenches_from_applied(applied, flange, c, sensor.core)
    counts = sensor.counts(F, rng)
    T_core_ati = reference_pose(flange, c, sensor.core)
    reference = transform_wrench(W_total, T_core_ati)
    if reference_noise:
        reference = reference + rng.standard_normal(reference.shape) * reference_noise * _FS
    session = CalibrationSession(counts, reference, loaded, T_core_ati, flange, c, core=sensor.core,
                                 meta={"simulated": True, "generator": "pito_core.sim.random_sensor",
                                       "sensor_seed": sensor.seed})
    return session, F

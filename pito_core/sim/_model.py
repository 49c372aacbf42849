"""The virtual cube: 36 strain gauges on six 3-spoke hubs, coupled, drifting, noisy, saturating."""

from __future__ import annotations

import numpy as np

from ..frames import FACES, N_GAUGES, OPPOSITE_FACE, CubeCore
from ._params import FULL_SCALE_FACE, FULL_SCALE_FRAME, SimParams
from ._signals import play_operator

__all__ = ["VirtualCube", "hub_sensitivity"]

#: Samples per block in :meth:`VirtualCube.counts_from_face_wrenches` (memory and cache).
_BLOCK = 32768


def hub_sensitivity(params: SimParams, angle0: float = np.pi / 2) -> np.ndarray:
    """Ideal gauge sensitivity ``(6, 6)`` of one 3-spoke hub, counts per (N, N·m).

    Three spokes at ``angle0 + k·120°`` in the face plane, radius ``spoke_radius``. The hub's
    wrench (face frame, about the face centre) is shared among the spoke tips as the
    minimum-norm set of tip forces; spoke k carries an out-of-plane gauge (reads the tip
    force along the face normal) and a tangential gauge (reads the in-plane force across
    the spoke, ``inplane_ratio`` as sensitive, plus ``radial_crosstalk`` of the axial force).
    Gauges are ordered ``[z_1, t_1, z_2, t_2, z_3, t_3]``: every gauge mixes force and torque.
    """
    r = params.spoke_radius
    A = np.zeros((6, 9))  # hub wrench from the three tip forces
    meas = np.zeros((6, 9))
    for k in range(3):
        th = angle0 + 2.0 * np.pi * k / 3.0
        p = np.array([r * np.cos(th), r * np.sin(th), 0.0])
        radial = np.array([np.cos(th), np.sin(th), 0.0])
        tangent = np.array([-np.sin(th), np.cos(th), 0.0])
        A[:3, 3 * k : 3 * k + 3] = np.eye(3)
        px, py, pz = p
        A[3:, 3 * k : 3 * k + 3] = np.array([[0.0, -pz, py], [pz, 0.0, -px], [-py, px, 0.0]])
        meas[2 * k, 3 * k + 2] = 1.0
        meas[2 * k + 1, 3 * k : 3 * k + 3] = params.inplane_ratio * tangent + params.radial_crosstalk * radial
    return params.spoke_gain * meas @ np.linalg.pinv(A)


class VirtualCube:
    """A simulated PITO cube: face wrenches in, 36 gauge counts out.

    Parameters
    ----------
    params : SimParams, optional
        Physical parameters (default ``SimParams()``).
    seed : int
        Seed of the cube itself (sensitivities, coupling, offsets, temperature
        coefficients, frame joints): the same seed is the same cube.

    Attributes
    ----------
    core : CubeCore
        Geometry (edge = ``params.edge``).
    sensitivity : ndarray, shape (36, 36)
        ``M``: counts per unit of the stacked face wrenches ``[F_1 … F_6]`` (face frames,
        N and N·m); block (i, j) is face j's load read on face i's gauges.
    offset : ndarray, shape (36,)
        Zero-load counts at the tare temperature.
    temperature_coefficient : ndarray, shape (36,)
        Offset drift, counts per K.
    """

    def __init__(self, params: SimParams | None = None, seed: int = 0):
        if params is None:
            params = SimParams()
        if not isinstance(params, SimParams):
            raise ValueError(f"params: expected a SimParams, got {type(params).__name__}")
        self.params = params
        self.seed = int(seed)
        self.core = CubeCore(params.edge)
        rng = np.random.default_rng([self.seed, 0x5117])
        D = np.diag(FULL_SCALE_FACE)
        Dinv = np.diag(1.0 / np.asarray(FULL_SCALE_FACE))
        M = np.zeros((N_GAUGES, N_GAUGES))
        blocks = {}
        for i in FACES:
            S = hub_sensitivity(params, angle0=np.pi / 2 + rng.uniform(-0.05, 0.05))
            gains = np.exp(params.gain_spread * rng.standard_normal(6))
            mix = np.eye(6) + params.misalignment * rng.standard_normal((6, 6)) / np.sqrt(6)
            blocks[i] = (gains[:, None] * S) @ D @ mix @ Dinv
        for i in FACES:
            for j in FACES:
                if i == j:
                    B = blocks[i]
                else:
                    c = params.coupling_opposite if OPPOSITE_FACE[i] == j else params.coupling_adjacent
                    G = rng.standard_normal((6, 6)) / np.sqrt(6)
                    B = c * blocks[i] @ D @ G @ Dinv
                M[6 * (i - 1) : 6 * i, 6 * (j - 1) : 6 * j] = B
        self.sensitivity = M
        self.offset = params.offset_std * rng.standard_normal(N_GAUGES)
        self.temperature_coefficient = params.drift_std * rng.standard_normal(N_GAUGES)
        self._temp_phase = rng.uniform(0, 2 * np.pi, len(params.temperature_periods))
        # full-scale signal of a gauge: rms counts for a full-scale face load
        self.signal_scale = float(np.sqrt(np.mean((np.stack([blocks[i] for i in FACES]) @ D) ** 2)))
        self._element_nl = params.element_nonlinearity * self.signal_scale * rng.standard_normal((6, 6, 6)) / np.sqrt(6)
        E = np.zeros((N_GAUGES, N_GAUGES))
        for f in range(6):
            E[6 * f : 6 * f + 6, 6 * f : 6 * f + 6] = self._element_nl[f]
        # one matrix for the hub's linear and quadratic parts: counts = [F, u²] @ _linquad
        self._inv_fs = np.tile(1.0 / np.asarray(FULL_SCALE_FACE), 6)
        self._linquad = np.ascontiguousarray(np.vstack([self.sensitivity.T, E.T]))
        n_feat = 6 + 15
        self._frame_nl = params.frame_nonlinearity * self.signal_scale * rng.standard_normal((N_GAUGES, n_feat)) / np.sqrt(n_feat)
        self._frame_hyst = params.frame_hysteresis * self.signal_scale * rng.standard_normal((N_GAUGES, 6)) / np.sqrt(6)
        self._pairs = np.array([(a, b) for a in range(6) for b in range(a + 1, 6)])
        self._frame_mat = np.ascontiguousarray(np.vstack([self._frame_nl.T, self._frame_hyst.T]))  # (27, 36)

    def __repr__(self) -> str:
        return f"VirtualCube(seed={self.seed}, edge={self.params.edge} m)"

    # ------------------------------------------------------------------ pieces
    @property
    def counts_range(self) -> tuple[int, int]:
        """ADC limits ``(lo, hi)`` in counts."""
        return self.params.counts_range

    def temperature(self, t) -> np.ndarray:
        """Temperature change from the tare ``(n,)`` in K at times ``t (n,)`` s (0 at t = 0)."""
        t = np.asarray(t, dtype=float)
        p = self.params
        out = np.zeros_like(t)
        for P, ph in zip(p.temperature_periods, self._temp_phase):
            out += np.sin(2 * np.pi * t / P + ph) - np.sin(ph)
        return p.temperature_amplitude * out / len(p.temperature_periods)

    def offsets_at(self, t) -> np.ndarray:
        """Zero-load counts ``(n, 36)`` (float, noise free) at times ``t (n,)`` s."""
        return self.offset[None, :] + self.temperature(t)[:, None] * self.temperature_coefficient[None, :]

    def element_counts(self, face_wrenches) -> np.ndarray:
        """Counts ``(N, 36)`` from each hub's own quadratic response to ``face_wrenches (N, 6, 6)``."""
        F = np.asarray(face_wrenches, dtype=float)
        u = F.reshape(F.shape[0], 36) * self._inv_fs
        return (u * u) @ self._linquad[36:]

    def frame_slip(self, W_frame, y0=None) -> np.ndarray:
        """Slip of the frame's screw joints ``(N, 6)`` in [−1, 1] for a load sequence.

        ``(u − play(u)) / play_width`` with ``u = W_frame / FULL_SCALE_FRAME``: the joint
        lags the load by up to the play, on the side of the last motion (hysteresis).
        """
        u = np.asarray(W_frame, dtype=float) / np.asarray(FULL_SCALE_FRAME)
        r = self.params.frame_play
        return (u - play_operator(u, r, y0)) / r

    def frame_counts(self, W_frame, slip=None) -> np.ndarray:
        """Extra counts ``(N, 36)`` from the load through the frame's screw joints.

        Parameters
        ----------
        W_frame : array-like, shape (N, 6)
            Total load through the frame's screw joints, core frame, N and N·m (moment
            about the core centre), as a time sequence.
        slip : array-like, shape (N, 6), optional
            Joint slip in [−1, 1]; by default computed from the sequence (play operator).
        """
        u = np.asarray(W_frame, dtype=float) / np.asarray(FULL_SCALE_FRAME)
        if slip is None:
            slip = self.frame_slip(W_frame)
        feats = np.empty((u.shape[0], 6 + 15 + 6))
        feats[:, :6] = u * np.abs(u)
        for k, (a, b) in enumerate(self._pairs):
            np.multiply(u[:, a], u[:, b], out=feats[:, 6 + k])
        feats[:, 21:] = slip
        return feats @ self._frame_mat

    # ------------------------------------------------------------------ main
    def counts_from_face_wrenches(
        self,
        face_wrenches,
        t=None,
        *,
        W_frame=None,
        frame_slip=None,
        noise=None,
        rng=None,
    ) -> np.ndarray:
        """Gauge counts for the wrenches on the faces.

        Parameters
        ----------
        face_wrenches : array-like, shape (N, 6, 6)
            Wrench on each face ``[:, i-1, :]``, face i's frame, ``[fx, fy, fz, tx, ty, tz]``
            in N and N·m (the load reaching the sensing element, see docs/conventions.md).
        t : array-like, shape (N,), optional
            Sample times in s since the tare (temperature drift); default ``arange(N)/rate``.
        W_frame : array-like, shape (N, 6), optional
            Load through the outer frame's screw joints (flange on the frame), core frame,
            N and N·m; None (face flange, free grasp) adds no frame term.
        frame_slip : array-like, shape (N, 6), optional
            Precomputed joint slip (live sources); default from the ``W_frame`` sequence.
        noise : array-like, shape (N, 36), optional
            Standard-normal draws for the gauge noise (scaled by ``noise_std``); default
            drawn from ``rng``.
        rng : numpy.random.Generator, optional
            Source of the noise when ``noise`` is None (default: seeded by the cube's seed).

        Returns
        -------
        counts : ndarray of int32, shape (N, 36)
            Rounded and clipped to the ADC range (saturated values sit at the limits).
        """
        F = np.asarray(face_wrenches, dtype=float)
        if F.ndim != 3 or F.shape[1:] != (6, 6):
            raise ValueError(f"face_wrenches: expected shape (N, 6, 6), got {F.shape}")
        n = F.shape[0]
        if t is None:
            t = np.arange(n) / self.params.rate
        t = np.asarray(t, dtype=float)
        if t.shape != (n,):
            raise ValueError(f"t: expected shape ({n},), got {t.shape}")
        if W_frame is not None:
            W_frame = np.asarray(W_frame, dtype=float)
            if W_frame.shape != (n, 6):
                raise ValueError(f"W_frame: expected shape ({n}, 6), got {W_frame.shape}")
            if frame_slip is None:
                frame_slip = self.frame_slip(W_frame)  # needs the whole sequence
        if noise is None:
            if rng is None:
                rng = np.random.default_rng([self.seed, 0x401])
            noise = rng.standard_normal((n, N_GAUGES), dtype=np.float32)
        out = np.empty((n, N_GAUGES), dtype=np.int32)
        Fn = F.reshape(n, 36)
        lo, hi = self.counts_range
        feats = np.empty((min(n, _BLOCK), 72))
        for a in range(0, n, _BLOCK):  # blocks stay in cache; rows never depend on each other
            b = min(n, a + _BLOCK)
            f = feats[: b - a]
            f[:, :36] = Fn[a:b]
            np.multiply(f[:, :36], self._inv_fs, out=f[:, 36:])
            np.square(f[:, 36:], out=f[:, 36:])
            c = f @ self._linquad  # linear hub response and coupling, plus each hub's quadratic part
            c += self.offset
            c += np.multiply.outer(self.temperature(t[a:b]), self.temperature_coefficient)
            if W_frame is not None:
                c += self.frame_counts(W_frame[a:b], frame_slip[a:b])
            c += self.params.noise_std * np.asarray(noise[a:b], dtype=float)
            np.clip(c, lo, hi, out=c)
            np.rint(c, out=c)
            out[a:b] = c
        return out

    def ideal_calibration(self) -> np.ndarray:
        """``M⁻¹ (36, 36)``: stacked face wrenches from offset-free counts, noise-free linear part."""
        return np.linalg.inv(self.sensitivity)

    def inverse_condition_number(self) -> float:
        """σmin/σmax of the sensitivity matrix (equal to that of its inverse)."""
        s = np.linalg.svd(self.sensitivity, compute_uv=False)
        return float(s[-1] / s[0])

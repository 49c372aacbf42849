"""Building blocks for signals: counter-based noise, keypoint trajectories, the play operator.

Everything here is a pure, vectorised function of its arrays. The counter-based noise
(``hashed_normal``) is a deterministic function of ``(seed, sample index, channel)``, so a
live source polled at any times gives the same values for the same sample.
"""

from __future__ import annotations

import numpy as np

__all__ = ["hashed_uniform", "hashed_normal", "smoothstep", "KeypointTrajectory", "play_operator"]

_M64 = np.uint64(0xFFFFFFFFFFFFFFFF)


def _splitmix64(x: np.ndarray) -> np.ndarray:
    with np.errstate(over="ignore"):
        x = x + np.uint64(0x9E3779B97F4A7C15)
        z = x
        z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
        z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
        return z ^ (z >> np.uint64(31))


def hashed_uniform(seed: int, index, n_channels: int, stream: int = 0) -> np.ndarray:
    """Uniform numbers in (0, 1), a deterministic function of ``(seed, stream, index, channel)``.

    Parameters
    ----------
    seed, stream : int
        Keys of the generator.
    index : array-like of int, shape (n,)
        Sample indices (any order, repeats allowed).
    n_channels : int
        Number of independent channels.

    Returns
    -------
    u : ndarray, shape (n, n_channels)
    """
    idx = np.asarray(index, dtype=np.int64).astype(np.uint64)
    key = _splitmix64(np.uint64((int(seed) * 1_000_003 + int(stream) * 7919) & 0xFFFFFFFFFFFFFFFF))
    with np.errstate(over="ignore"):
        x = idx[:, None] * np.uint64(n_channels) + np.arange(n_channels, dtype=np.uint64)[None, :]
        h = _splitmix64(x ^ key)
    return ((h >> np.uint64(11)).astype(np.float64) + 0.5) / float(1 << 53)


def hashed_normal(seed: int, index, n_channels: int, stream: int = 0) -> np.ndarray:
    """Standard normal numbers ``(n, n_channels)``, deterministic in ``(seed, stream, index, channel)``."""
    u1 = hashed_uniform(seed, index, n_channels, 2 * stream)
    u2 = hashed_uniform(seed, index, n_channels, 2 * stream + 1)
    return np.sqrt(-2.0 * np.log(u1)) * np.cos(2.0 * np.pi * u2)


def smoothstep(s: np.ndarray) -> np.ndarray:
    """``(1 − cos πs) / 2`` on ``s`` clipped to [0, 1]: 0 → 1 with zero slope at both ends."""
    s = np.clip(s, 0.0, 1.0)
    return 0.5 - 0.5 * np.cos(np.pi * s)


class KeypointTrajectory:
    """A load that moves between keypoints and holds still at each.

    Segment m runs over ``[m·period, (m+1)·period)``: a smooth ramp from keypoint m to
    keypoint m+1 over the first ``ramp`` fraction, then a still hold. Every component is
    monotone within a segment, which makes the play operator exact per segment.

    Parameters
    ----------
    keypoints : array-like, shape (K, d)
        Values at the keypoints (any units); the trajectory starts at ``keypoints[0]`` and
        holds ``keypoints[-1]`` after the last segment.
    period : float
        Duration of a segment, s.
    ramp : float
        Fraction of a segment spent moving, in (0, 1].
    """

    def __init__(self, keypoints, period: float, ramp: float = 0.6):
        kp = np.asarray(keypoints, dtype=float)
        if kp.ndim != 2 or kp.shape[0] < 1:
            raise ValueError(f"keypoints: expected shape (K, d) with K >= 1, got {kp.shape}")
        if not period > 0:
            raise ValueError(f"period: expected a positive duration in s, got {period!r}")
        if not 0 < ramp <= 1:
            raise ValueError(f"ramp: expected a fraction in (0, 1], got {ramp!r}")
        self.keypoints = kp
        self.period = float(period)
        self.ramp = float(ramp)

    @property
    def duration(self) -> float:
        """Time to reach the last keypoint, s."""
        return (self.keypoints.shape[0] - 1) * self.period

    def segment(self, t) -> tuple[np.ndarray, np.ndarray]:
        """Segment index ``m (n,)`` and progress ``s (n,)`` in [0, 1] at times ``t`` (s)."""
        t = np.asarray(t, dtype=float)
        K = self.keypoints.shape[0]
        m = np.clip(np.floor(t / self.period), 0, max(K - 2, 0)).astype(np.int64)
        frac = (t - m * self.period) / (self.period * self.ramp)
        s = smoothstep(frac) if K > 1 else np.zeros_like(t)
        return m, s

    def __call__(self, t) -> np.ndarray:
        """Values ``(n, d)`` at times ``t (n,)`` in s."""
        m, s = self.segment(t)
        kp = self.keypoints
        if kp.shape[0] == 1:
            return np.repeat(kp, np.size(t), axis=0)
        return kp[m] * (1.0 - s)[:, None] + kp[m + 1] * s[:, None]


def play_operator(x: np.ndarray, r, y0=None) -> np.ndarray:
    """Play (backlash) operator, exact for any sequence, vectorised over monotone runs.

    ``y[n] = clip(y[n-1], x[n] − r, x[n] + r)``: the output follows the input with a dead
    band of half-width r, like a screw joint that slips once friction is overcome.

    Parameters
    ----------
    x : ndarray, shape (N, d)
        Input sequence.
    r : float or array-like, shape (d,)
        Half-width of the play, units of x, > 0.
    y0 : array-like, shape (d,), optional
        State before the first sample (default 0).

    Returns
    -------
    y : ndarray, shape (N, d)
    """
    x = np.asarray(x, dtype=float)
    n, d = x.shape
    r = np.broadcast_to(np.asarray(r, dtype=float), (d,))
    y_prev = np.zeros(d) if y0 is None else np.asarray(y0, dtype=float).copy()
    y = np.empty_like(x)
    if n == 0:
        return y
    for c in range(d):
        xc = x[:, c]
        dx = np.diff(xc)
        sgn = np.sign(dx)
        # carry the last non-zero direction forward so flat stretches stay in their run
        nz = np.flatnonzero(sgn)
        if nz.size:
            fill = np.maximum.accumulate(np.where(sgn != 0, np.arange(sgn.size), -1))
            sgn = np.where(fill >= 0, sgn[np.maximum(fill, 0)], 0.0)
        # runs: sample 0 alone, then samples grouped by the sign of their incoming step
        # (sample n arrives by step n-1; a run starts where that sign changes)
        starts = np.concatenate(([0, 1], 2 + np.flatnonzero(sgn[1:] != sgn[:-1])))
        starts = starts[starts < n]
        state = y_prev[c]
        run_state = np.empty(starts.size)
        ends = np.append(starts[1:], n)
        for k, (a, b) in enumerate(zip(starts, ends)):
            run_state[k] = state
            # within a monotone run the output is clip(state, x - r, x + r); its end value
            state = min(max(state, xc[b - 1] - r[c]), xc[b - 1] + r[c])
        lengths = ends - starts
        s = np.repeat(run_state, lengths)
        y[:, c] = np.minimum(np.maximum(s, xc - r[c]), xc + r[c])
    return y

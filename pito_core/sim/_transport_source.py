"""Sources for the simulated transports: the protocol, a labelled test signal, the simulated clock."""

from __future__ import annotations

import threading
import time
from typing import Protocol

import numpy as np

from ..frames import N_GAUGES
from ._live import default_live_source

__all__ = ["Source", "TestSignalSource", "default_simulated_source"]


class Source(Protocol):
    """What the simulated transports stream."""

    def counts_at(self, t: np.ndarray) -> np.ndarray:
        """``(n, 36)`` int gauge counts at times ``t`` (s since start)."""

    def reference_at(self, t: np.ndarray) -> np.ndarray:
        """``(n, 6)`` reference wrench ``[fx, fy, fz, tx, ty, tz]`` in N and N·m, reference frame."""


class TestSignalSource:
    """A simulated test signal: sine loads through a fixed random gauge matrix.

    Not a physical model of the cube (``pito_core.sim`` has that): the reference wrench is a
    sum of sines per axis, and ``counts = offset + G @ wrench + noise`` with a fixed random
    ``G (36, 6)`` in counts per N / N·m. Deterministic for a given ``seed`` and ``t``.

    Parameters
    ----------
    seed : int
        Seeds ``G``, the offsets and the sine phases.
    amplitude : (6,) array-like, optional
        Peak load per axis, default 2 N and 0.02 N·m.
    noise_counts : float, optional
        Standard deviation of the gauge noise (a deterministic hash of t), default 0.
    """

    __test__ = False  # not a pytest class
    label = "simulated test signal"

    def __init__(self, seed: int = 0, amplitude=(2.0, 2.0, 2.0, 0.02, 0.02, 0.02), noise_counts: float = 0.0):
        rng = np.random.default_rng(seed)
        self.amplitude = np.asarray(amplitude, dtype=float)
        if self.amplitude.shape != (6,):
            raise ValueError(f"amplitude: expected shape (6,), got {self.amplitude.shape}")
        self.gain = rng.normal(0.0, 1.0, (N_GAUGES, 6)) * np.array([2e4, 2e4, 2e4, 2e6, 2e6, 2e6])
        self.offset = rng.integers(-50_000, 50_000, N_GAUGES)
        self.freq = rng.uniform(0.2, 2.0, 6)
        self.phase = rng.uniform(0, 2 * np.pi, 6)
        self.noise_counts = float(noise_counts)

    def reference_at(self, t) -> np.ndarray:
        t = np.asarray(t, dtype=float).reshape(-1, 1)
        return self.amplitude * np.sin(2 * np.pi * self.freq * t + self.phase)

    def counts_at(self, t) -> np.ndarray:
        t = np.asarray(t, dtype=float).reshape(-1)
        c = self.offset + self.reference_at(t) @ self.gain.T
        if self.noise_counts:
            h = np.sin(np.outer(t * 1e3 + 0.5, np.arange(1, N_GAUGES + 1)) * 12.9898) * 43758.5453
            c = c + self.noise_counts * 3.4 * (h - np.floor(h) - 0.5)  # uniform, std ≈ noise_counts
        return np.rint(c).astype(np.int64)


def default_simulated_source(seed: int = 0):
    """The simulator's default live source (:func:`default_live_source`, a looping grasp).

    Returns ``(source, label)``. A broken simulator raises: there is no silent fallback to
    :class:`TestSignalSource` (ask for it by name when a test signal is wanted).
    """
    src = default_live_source(seed=seed)
    return src, getattr(src, "label", "simulated cube (pito_core.sim)")


class _Clock:
    """Simulated time: ``speed`` simulated seconds per wall second (inf: as fast as possible).

    Simulated time 0 is at ``epoch`` (a ``time.monotonic()`` value; default: now). Devices
    sharing an epoch see the same simulated world at the same wall time.
    """

    def __init__(self, speed: float, epoch: float | None = None):
        if not speed > 0:
            raise ValueError(f"speed: expected > 0 (inf for as fast as possible), got {speed!r}")
        self.speed = float(speed)
        self.t0 = time.monotonic() if epoch is None else float(epoch)

    def now(self) -> float:
        """Current simulated time (0 with an infinite speed)."""
        if np.isinf(self.speed):
            return 0.0
        return max(0.0, (time.monotonic() - self.t0) * self.speed)

    def wait_until(self, t_sim: float, stop: threading.Event) -> bool:
        """Sleep until simulated time ``t_sim``; False if ``stop`` was set."""
        if np.isinf(self.speed):
            return not stop.is_set()
        delay = self.t0 + t_sim / self.speed - time.monotonic()
        if delay > 0:
            return not stop.wait(delay)
        return not stop.is_set()

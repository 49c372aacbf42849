"""Capture rules of a calibration's loading step (the wizard's; pure numpy): still, new, covered, conditioned.

The loading step watches the stream of samples of one face. A window of samples is
kept (a *capture*) only when the load on the face is still (small spread over the
window), new (far, in full-scale units, from every capture kept so far) and, where the
caller says which samples those are, on that face (its gauges deflect the most,
:func:`on_face`: after a change of face the operator may still press the last one). Coverage
is the largest fraction of full scale reached on each axis and sign; the condition
number is that of the kept loads scaled by full scale.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..defaults import FULL_SCALE_FACE

FULL_SCALE = np.array(FULL_SCALE_FACE)  # [fx, fy, fz, tx, ty, tz] full scale, N and N·m

__all__ = ["CaptureRules", "Capture", "FaceCaptures", "is_still", "on_face", "scaled"]

#: What :meth:`FaceCaptures.feed` reports.
EVENTS = ("waiting", "moving", "no load", "not new", "wrong face", "kept", "growing")


@dataclass
class CaptureRules:
    """Thresholds of the loading step, in fractions of full scale (±15 N, ±0.1 N·m).

    Attributes
    ----------
    window : float
        Length of a capture window, s.
    still : float
        Largest drift of the load over the window (spread of the means of its thirds),
        fraction of full scale per axis.
    min_load : float
        Smallest load (scaled norm) that counts as loaded.
    novelty : float
        Smallest distance (scaled norm) of a new capture's mean load to every kept one.
    required : float
        Coverage each axis and sign must reach for the face to be done.
    k : int
        Samples to collect on each face.
    min_captures : int
        Distinct still loads needed on each face (a face's 6 wrench directions need at
        least 6; twice that leaves margin for the held-out check).
    trim : float
        Seconds dropped from the end of a capture when the load leaves it, s.
    max_condition : float
        Largest condition number of the kept loads (scaled by full scale) for a face to be done.
    """

    window: float = 0.06
    still: float = 0.012
    min_load: float = 0.08
    novelty: float = 0.10
    required: float = 0.3
    k: int = 2000
    min_captures: int = 16
    max_condition: float = 30.0
    trim: float = 0.06


def scaled(wrench) -> np.ndarray:
    """``wrench (..., 6)`` in N, N·m divided by full scale (dimensionless)."""
    return np.asarray(wrench, dtype=float) / FULL_SCALE


def is_still(wrench_face, rules: CaptureRules) -> bool:
    """Whether the window of loads ``(n, 6)`` (N, N·m) is still.

    The window is cut in thirds; it is still when, on every axis, the means of the thirds
    differ by less than ``rules.still`` (fraction of full scale). Means average the sensor
    noise out; a moving load shifts them.
    """
    w = scaled(wrench_face)
    if w.shape[0] < 6:
        return False
    thirds = np.array([p.mean(axis=0) for p in np.array_split(w, 3)])
    return bool(np.all(thirds.max(axis=0) - thirds.min(axis=0) < rules.still))


def on_face(counts, tare, face: int, skip: int | None = None) -> np.ndarray:
    """``(n,)`` whether face ``face``'s six gauges (counts ``6 (face − 1)`` on) deflect from ``tare (36,)`` at
    least as far as every other face's, for ``counts (n, 36)``: the load is on that face. The six
    faces' gauges are alike, so their deflections compare in counts; ``skip``: a face left out (the
    connected face of a face flange, which carries every load's reaction)."""
    d = np.linalg.norm((np.asarray(counts, dtype=float) - np.asarray(tare, dtype=float)).reshape(-1, 6, 6), axis=2)
    others = np.delete(d, sorted({face - 1} | ({skip - 1} if skip else set())), axis=1)
    return d[:, face - 1] >= others.max(axis=1, initial=0.0)


@dataclass
class Capture:
    """One kept window: raw arrays and its load on the face."""

    counts: np.ndarray  # (n, 36) counts
    reference: np.ndarray  # (n, 6) N, N·m in the reference frame
    time: np.ndarray  # (n,) s
    wrench_face: np.ndarray  # (n, 6) N, N·m on the loaded face, face frame

    @property
    def mean_scaled(self) -> np.ndarray:
        return scaled(self.wrench_face).mean(axis=0)


@dataclass
class FaceCaptures:
    """The captures of one face, in order, with coverage and conditioning."""

    face: int
    rules: CaptureRules = field(default_factory=CaptureRules)
    captures: list = field(default_factory=list)
    _buffer: list = field(default_factory=list)
    _open: bool = False

    @property
    def n_samples(self) -> int:
        return int(sum(c.counts.shape[0] for c in self.captures))

    def is_new(self, wrench_face) -> bool:
        """Whether a window's mean load is far from every kept capture (and is a load at all)."""
        m = scaled(wrench_face).mean(axis=0)
        if np.linalg.norm(m) < self.rules.min_load:
            return False
        return all(np.linalg.norm(m - c.mean_scaled) >= self.rules.novelty for c in self.captures)

    def offer(self, counts, reference, time, wrench_face) -> bool:
        """Keep the window if still and new; return whether it was kept."""
        if not (is_still(wrench_face, self.rules) and self.is_new(wrench_face)):
            return False
        self.captures.append(Capture(np.array(counts, float), np.array(reference, float), np.array(time, float),
                                     np.array(wrench_face, float)))
        return True

    def feed(self, time, counts, reference, wrench_face, on_face=None) -> str:
        """Consume new samples; open a capture when the last ``window`` s are still, new and (``on_face
        (n,)`` bool, :func:`on_face`; None: not checked) on this face, grow it while the load stays still
        where it is and on this face. Returns one of :data:`EVENTS`."""
        time = np.asarray(time, dtype=float)
        if time.size == 0:
            return "waiting"
        here = np.ones(time.size, dtype=bool) if on_face is None else np.asarray(on_face, dtype=bool).reshape(-1)
        chunk = (time, np.asarray(counts, float), np.asarray(reference, float), np.asarray(wrench_face, float), here)
        if self._open and self.captures:
            cap = self.captures[-1]
            dev = np.abs(scaled(chunk[3]).mean(axis=0) - cap.mean_scaled)
            recent = np.concatenate([cap.wrench_face[-2 * chunk[3].shape[0]:], chunk[3]])
            if np.all(dev < self.rules.still) and is_still(recent, self.rules) and here.all():
                cap.counts = np.concatenate([cap.counts, chunk[1]])
                cap.reference = np.concatenate([cap.reference, chunk[2]])
                cap.time = np.concatenate([cap.time, chunk[0]])
                cap.wrench_face = np.concatenate([cap.wrench_face, chunk[3]])
                return "growing"
            self._close_open()
        self._buffer.append(chunk)
        t_last = time[-1]
        while len(self._buffer) > 1 and self._buffer[1][0][0] <= t_last - self.rules.window:
            self._buffer.pop(0)
        t, c, r, w, h = (np.concatenate([b[i] for b in self._buffer]) for i in range(5))
        keep = t > t_last - self.rules.window
        if t[-1] - t[0] < 0.8 * self.rules.window:
            return "waiting"
        t, c, r, w, h = t[keep], c[keep], r[keep], w[keep], h[keep]
        if not is_still(w, self.rules):
            return "moving"
        if np.linalg.norm(scaled(w).mean(axis=0)) < self.rules.min_load:
            return "no load"
        if not self.is_new(w):
            return "not new"
        if not h.all():
            return "wrong face"
        self.captures.append(Capture(c, r, t, w))
        self._open = True
        self._buffer = []
        return "kept"

    def _close_open(self) -> None:
        """End the growing capture, dropping its last ``rules.trim`` s: the load may have begun
        to move there before the motion showed (and the two devices' clocks differ by a few ms)."""
        if self._open and self.captures:
            cap = self.captures[-1]
            keep = cap.time <= cap.time[-1] - self.rules.trim
            if keep.sum() >= max(6, cap.time.size // 2):
                cap.counts, cap.reference = cap.counts[keep], cap.reference[keep]
                cap.time, cap.wrench_face = cap.time[keep], cap.wrench_face[keep]
        self._open = False
        self._buffer = []

    def close(self) -> None:
        """End the open capture (e.g. when the operator switches face)."""
        self._close_open()

    def undo(self) -> bool:
        """Drop the last capture; False if there was none."""
        if not self.captures:
            return False
        self.captures.pop()
        self._open = False
        return True

    def clear(self) -> None:
        self.captures.clear()
        self.close()

    def coverage(self) -> np.ndarray:
        """``(6, 2)`` largest fraction of full scale reached per axis, ``[:, 0]`` negative, ``[:, 1]`` positive."""
        out = np.zeros((6, 2))
        if not self.captures:
            return out
        w = scaled(np.concatenate([c.wrench_face for c in self.captures]))
        out[:, 0] = np.clip(-w.min(axis=0), 0, 1)
        out[:, 1] = np.clip(w.max(axis=0), 0, 1)
        return out

    def condition_number(self) -> float:
        """σmax/σmin of the kept loads scaled by full scale, ``(n, 6)``; inf until 6 directions are excited."""
        if not self.captures:
            return float("inf")
        w = scaled(np.concatenate([c.wrench_face for c in self.captures]))
        if w.shape[0] < 6:
            return float("inf")
        s = np.linalg.svd(w, compute_uv=False)
        return float(s[0] / s[-1]) if s[-1] > 1e-12 * s[0] else float("inf")

    @property
    def sufficient(self) -> bool:
        """Enough samples and distinct loads, every axis covered on both signs, well conditioned."""
        r = self.rules
        return (self.n_samples >= r.k and len(self.captures) >= r.min_captures
                and bool(np.all(self.coverage() >= r.required)) and self.condition_number() <= r.max_condition)

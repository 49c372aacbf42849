"""Where the pipeline's new samples come from: a running acquisition (by cursor) or a recording.

Both readers answer ``read() -> NewSamples`` (the rows since the previous call), ``stats()``
and ``close()``, so the app's worker, ``pito record`` and replay drive the same
:class:`~pito_core.pipeline.Pipeline` the same way.
"""

from __future__ import annotations

import time
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..devices import StreamClock, TickUnwrapper
from ..frames import CUBE_ADC_LIMIT
from ..io import read_recording

__all__ = ["NewSamples", "AcquisitionReader", "RecordingReader", "recording_samples", "device_time_base",
           "recording_times"]


@dataclass
class NewSamples:
    """The rows of one read.

    Attributes
    ----------
    cube : dict or None
        ``time (n,)`` s (pairing rule), ``counts (n, 36)``, ``tick (n,)`` µs, ``host_time (n,)`` s, ...
    reference : dict or None
        ``time (m,)`` s, ``wrench (m, 6)`` N and N·m, ``host_time (m,)`` s, ...
    events : list of dict
        Recording events in this read (e.g. a ``tare`` with ``from_tick``).
    restart : bool
        The stream jumped (replay seek or loop): start the pipeline's histories over.
    """

    cube: dict | None
    reference: dict | None = None
    events: list = field(default_factory=list)
    restart: bool = False

    def __len__(self) -> int:
        return 0 if self.cube is None else len(self.cube["time"])


class _Rate:
    """Samples per second over the last ``span`` s of reads (O(1) per read)."""

    def __init__(self, span: float = 2.0):
        self.span = span
        self.points: deque = deque()
        self.total = 0

    def add(self, n: int, now: float) -> None:
        self.total += int(n)
        self.points.append((now, self.total))
        while len(self.points) > 2 and now - self.points[1][0] >= self.span:
            self.points.popleft()

    def rate(self) -> float:
        if len(self.points) < 2:
            return 0.0
        (t0, n0), (t1, n1) = self.points[0], self.points[-1]
        return (n1 - n0) / (t1 - t0) if t1 > t0 else 0.0


class AcquisitionReader:
    """The new rows of a running :class:`~pito_core.devices.Acquisition`, read by cursor.

    Parameters
    ----------
    acquisition : Acquisition
    simulated : bool
        The devices are simulated (shown in ``stats``).
    owns : bool
        :meth:`close` closes the acquisition.
    history : float
        On the first read, start this many seconds back (at the nominal rate).
    """

    def __init__(self, acquisition, simulated: bool = False, owns: bool = False, history: float = 0.1,
                 rate_hz: float = 1000.0):
        self.acq = acquisition
        self.simulated = bool(simulated)
        self.owns = bool(owns)
        c, r = acquisition.cursors()
        back = int(history * rate_hz)
        self.cursors = (max(0, c - back), max(0, r - back))
        self.lost = [0, 0]
        self._rates = (_Rate(), _Rate())
        self._saturated = 0
        self.backlog = 0.0

    @property
    def has_reference(self) -> bool:
        return self.acq.has_reference

    def read(self) -> NewSamples:
        """Rows appended since the previous read (work ∝ new rows)."""
        p, f, self.cursors, lost = self.acq.read_since(*self.cursors)
        self.lost[0] += lost[0]
        self.lost[1] += lost[1]
        now = time.monotonic()
        self._rates[0].add(len(p["time"]), now)
        if f is not None:
            self._rates[1].add(len(f["time"]), now)
            if len(f["time"]) and len(p["time"]):
                self.backlog = float(f["time"][-1] - p["time"][-1])
        if len(p["time"]):
            self._saturated += int((np.abs(p["counts"]) >= CUBE_ADC_LIMIT).any(axis=1).sum())
        return NewSamples(p, f)

    def stats(self) -> dict:
        s = self.acq.stats()
        net = s.get("netft") or {}
        cube = s.get("pito") or {}
        return {
            "rate_cube": self._rates[0].rate(),
            "rate_reference": self._rates[1].rate() if s.get("netft") is not None else None,
            "saturated": self._saturated + int(net.get("saturated", 0) or 0),
            "dropped": int(cube.get("dropped", 0) or 0) + int(net.get("lost", 0) or 0),
            "simulated": self.simulated,
            "backlog": self.backlog,
            "lost_in_buffer": list(self.lost),
            "connected": bool(cube.get("connected", True)),
            "devices": s,  # the drivers' own stats (stalled, out_of_order, rate_mismatch, ...): health_words()
        }

    def close(self) -> None:
        if self.owns:
            self.acq.close()


def recording_samples(recording) -> tuple[dict, dict]:
    """Both streams of a recording with their sample times by the pairing rule.

    Returns ``(cube, reference)`` dicts: cube ``time, tick, counts (float), host_time, seq``;
    reference ``time, tick, wrench, host_time, rdt_seq``; each with ``device_time`` (s, the
    device's own clock: cube ``tick`` · 10⁻⁶, reference ``tick`` / RDT rate). The same clock as the live
    acquisition: continued from the state it had when the recording began (the recording's
    ``clock`` event), or started at the recording's first row (recordings without one). A
    :class:`~pito_core.io.RecordingChunks` gives its clocks, with zero-width ``counts`` and ``wrench``
    (those stay in the file, read by rows).
    """
    p, a = recording.pito, recording.netft
    chunked = hasattr(recording, "rows")  # a RecordingChunks: its clocks; counts and wrenches stay in the file
    counts = np.zeros((recording.n_pito, 0)) if chunked else np.asarray(p["counts"], dtype=np.float64)
    wrench = np.zeros((recording.n_netft, 0)) if chunked else np.asarray(a["wrench"], dtype=np.float64)
    rate = float(recording.meta.get("reference_rate_hz", 1000.0))
    start = next((e for e in recording.events if e.get("type") == "clock"), None)

    def clocks(name):  # where the live acquisition's clocks stood at the first recorded sample, if it says
        if start is None:
            return TickUnwrapper(), StreamClock()
        return TickUnwrapper.from_state(start[name]["ticks"]), StreamClock.from_state(start[name]["clock"])

    unwrap, clock = clocks("pito")
    tick = unwrap(p["time_us"])
    cube = {"tick": tick, "time": clock(tick * 1e-6, p["host_time"], unwrap.restarts),
            "counts": counts, "host_time": np.asarray(p["host_time"]),
            "seq": np.asarray(p["seq"]), "device_time": tick * 1e-6}
    unwrap, clock = clocks("netft")
    rtick = unwrap(a["rdt_seq"])
    ref = {"tick": rtick, "time": clock(rtick / rate, a["host_time"], unwrap.restarts),
           "wrench": wrench, "host_time": np.asarray(a["host_time"]),
           "rdt_seq": np.asarray(a["rdt_seq"]), "device_time": rtick / rate}
    return cube, ref


def device_time_base(cube: dict, reference: dict | None) -> tuple[np.ndarray, np.ndarray]:
    """The one time base of a recording's exports: the cube's device clock, s from its first sample.

    Parameters
    ----------
    cube, reference : dict
        As :func:`recording_samples` gives them (``time`` by the pairing rule, ``device_time`` s).

    Returns
    -------
    cube_time : ndarray, shape (n,)
        The cube's clock (``time_us``, unwrapped), s from the first sample of either stream,
        strictly increasing; a dropped frame leaves a gap, never a repeated time.
    reference_time : ndarray, shape (m,)
        The reference's own clock (``rdt_sequence`` / RDT rate, unwrapped) on the same base: shifted
        by one offset per recording, the median over the reference samples of the offset the
        pairing rule gives them against the cube's clock. Strictly increasing too (a relative
        drift of the two device clocks within the recording is not followed here; the pairing is).
    """
    dev_c = np.asarray(cube["device_time"], np.float64)
    if dev_c.size == 0:
        return np.zeros(0), np.zeros(0)
    if reference is None or np.size(reference["time"]) == 0:
        return dev_c - dev_c[0], np.zeros(0)
    tau_c = np.asarray(cube["time"], np.float64)
    tau_r = np.asarray(reference["time"], np.float64)
    k = np.clip(np.searchsorted(tau_c, tau_r, side="right") - 1, 0, dev_c.size - 1)
    dev_r = np.asarray(reference["device_time"], np.float64)
    offset = float(np.median(tau_r - (tau_c[k] - dev_c[k]) - dev_r))
    t_r = dev_r + offset
    zero = min(dev_c[0], t_r[0])
    return dev_c - zero, t_r - zero


class RecordingReader:
    """A recording played back in real time (or ``speed`` times faster), looping and seekable.

    Parameters
    ----------
    recording : path or Recording
        Incomplete recordings (a killed recorder) are read up to their last intact chunk.
    speed : float
        Recording seconds per wall second (``inf``: everything at the first read).
    loop : bool
        Start over at the end.

    Notes
    -----
    Sample times are recomputed from the recorded device clocks by the pairing rule, so a
    recording made from the start of an acquisition replays the live pairing exactly.
    Tare events (``from_tick``) are handed to the pipeline at their sample.
    """

    def __init__(self, recording, speed: float = 1.0, loop: bool = True):
        if isinstance(recording, (str, Path)):
            self.path = str(recording)
            recording = read_recording(recording, recover=True)
        if not speed > 0:
            raise ValueError(f"speed: expected > 0 (inf: as fast as possible), got {speed!r}")
        self.recording = recording
        self.simulated = bool(recording.simulated)
        self.cube, self.reference = recording_samples(recording)
        if self.cube["time"].size == 0:
            raise ValueError("recording: no cube samples")
        self.has_reference = self.reference["time"].size > 0
        self.events = [e for e in recording.events if e.get("type") == "tare" and e.get("from_tick") is not None]
        self.t0 = float(self.cube["host_time"][0])
        self.duration = float(self.cube["host_time"][-1] - self.t0)
        self.loop = bool(loop)
        self.speed = float(speed)
        self._pos = 0.0  # s into the recording (host clock of the recording)
        self._wall = None
        self._i = self._j = 0
        self._restart = True
        self._rate = _Rate()

    def seek(self, t: float) -> None:
        """Continue from ``t`` s into the recording."""
        self._pos = float(np.clip(t, 0.0, self.duration))
        self._i = int(np.searchsorted(self.cube["host_time"] - self.t0, self._pos, side="right"))
        self._j = int(np.searchsorted(self.reference["host_time"] - self.t0, self._pos, side="right"))
        self._wall = time.monotonic()
        self._restart = True

    def read(self) -> NewSamples:
        now = time.monotonic()
        if self._wall is None:
            self._wall = now
        self._pos = np.inf if np.isinf(self.speed) else self._pos + (now - self._wall) * self.speed
        self._wall = now
        restart = self._restart
        if self._pos > self.duration and self._i >= self.cube["time"].size:
            if self.loop:
                self.seek(0.0)
                restart = True
            self._pos = min(self._pos, self.duration)
        end = self.t0 + self._pos
        i1 = max(self._i, int(np.searchsorted(self.cube["host_time"], end, side="right")))
        if self._pos >= self.duration:  # the end: every reference row too (the last Net F/T packet
            j1 = self.reference["host_time"].size  # may have arrived after the last cube frame)
        else:
            j1 = max(self._j, int(np.searchsorted(self.reference["host_time"], end, side="right")))
        cube = {k: v[self._i : i1] for k, v in self.cube.items()}
        ref = {k: v[self._j : j1] for k, v in self.reference.items()} if self.has_reference else None
        events = []
        if cube["tick"].size:
            # a tare takes effect from the first sample at or after its from_tick (the tick after
            # the last one seen when it was made: it may lie between two reads' samples)
            lo = int(self.cube["tick"][self._i - 1]) if self._i > 0 else -np.inf
            hi = int(cube["tick"][-1])
            events = [e for e in self.events if lo < int(e["from_tick"]) <= hi]
        self._i, self._j = i1, j1
        self._restart = False
        self._rate.add(cube["time"].size, now)
        return NewSamples(cube, ref, events, restart)

    @property
    def finished(self) -> bool:
        """Every cube sample has been read (and ``loop`` is off, or the next read starts over)."""
        return self._i >= self.cube["time"].size

    def stats(self) -> dict:
        return {"position": min(self._pos, self.duration), "duration": self.duration, "replay": True,
                "rate_cube": self._rate.rate(), "simulated": self.simulated}

    def close(self) -> None:
        pass


def recording_times(recording) -> tuple[np.ndarray, np.ndarray]:
    """``(cube times (n,), reference times (m,))`` s of a :class:`~pito_core.io.Recording`, row for row.

    The one time base of every export (:func:`device_time_base`): CSV/MAT ``time``, NWB, MCAP, analysis.
    A :class:`~pito_core.io.RecordingChunks` gives the same from its clock columns alone.
    """
    cube, ref = recording_samples(recording)
    return device_time_base(cube, ref if ref["time"].size else None)

"""Acquisition: both streams with host timestamps, ring buffers, live tare, calibration sessions.

Typical use (the desktop wizard does the same, from its worker thread)::

    with Acquisition(PitoSerial(port), NetFT(host)) as acq:
        time.sleep(1.0); acq.tare()                  # unloaded: offsets of both
        t0 = acq.now(); ...apply loads on face 2...; t1 = acq.now()
        session = acq.to_session(t0, t1, loaded=2, flange="frame", connected_face=6,
                                 T_core_ati=T)

Time alignment (:meth:`Acquisition.to_session`): every sample carries the host clock
(``time.monotonic()``, s) at which its bytes arrived, which jitters by the transport's
batching. Each stream is put back on a regular clock by fitting
``host_time ≈ a + b · k`` over the window, where ``k`` is the device's own tick (the cube's
``time_us``; the Net F/T's ``rdt_sequence``), with ``b`` from least squares refitted on
the 20 % earliest arrivals and ``a`` at the lower envelope (the smallest transport latency), which removes the jitter and any
drift between the clocks. The reference is then interpolated linearly at the cube's sample
times. A constant difference of transport latency between the two devices is not
observable from the data: pass it as ``reference_delay`` (s, default 0).
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass

import numpy as np

from ._frame import N_CHANNELS
from ._netft import NetFTBatch
from ._serial import PitoBatch

__all__ = ["Acquisition", "ClockFit", "fit_clock"]


@dataclass(frozen=True)
class ClockFit:
    """``host_time ≈ offset + slope · tick`` for one stream (see module docstring)."""

    offset: float
    slope: float
    residual_max: float  # s, largest arrival delay above the fitted line (transport jitter)

    def __call__(self, tick) -> np.ndarray:
        return self.offset + self.slope * np.asarray(tick, dtype=float)


def fit_clock(tick, host_time) -> ClockFit:
    """Fit ``host_time ≈ a + b · tick`` with ``a`` on the lower envelope.

    Parameters
    ----------
    tick : array-like, shape (n,)
        Device tick, increasing (unwrapped).
    host_time : array-like, shape (n,)
        Arrival times, s.
    """
    k = np.asarray(tick, dtype=float)
    h = np.asarray(host_time, dtype=float)
    if k.shape != h.shape or k.ndim != 1:
        raise ValueError(f"tick, host_time: expected two (n,) arrays, got {k.shape} and {h.shape}")
    if k.size < 2 or np.ptp(k) == 0:
        return ClockFit(float(h.min() - 0.0) if h.size else 0.0, 0.0, 0.0)
    sel = np.ones(k.size, bool)
    for _ in range(3):  # least squares, then again on the points nearest the lower envelope
        km, hm = k[sel].mean(), h[sel].mean()
        den = ((k[sel] - km) ** 2).sum()
        if den == 0:
            break
        slope = float(((k[sel] - km) * (h[sel] - hm)).sum() / den)
        resid = h - slope * k
        sel = resid <= np.quantile(resid, 0.2)
    resid = h - slope * k
    offset = float(resid.min())
    return ClockFit(offset, slope, float(resid.max() - offset))


class _Ring:
    """Fixed-capacity ring buffer of named arrays (first axis = samples)."""

    def __init__(self, capacity: int, fields: dict):
        self.capacity = int(capacity)
        self.data = {k: np.zeros((self.capacity,) + shape, dtype=dt) for k, (dt, shape) in fields.items()}
        self.count = 0  # total samples ever appended

    def append(self, **arrays) -> None:
        n = len(next(iter(arrays.values())))
        if n == 0:
            return
        if n > self.capacity:
            arrays = {k: v[-self.capacity :] for k, v in arrays.items()}
            self.count += n - self.capacity
            n = self.capacity
        start = self.count % self.capacity
        first = min(n, self.capacity - start)
        for k, v in arrays.items():
            self.data[k][start : start + first] = v[:first]
            self.data[k][: n - first] = v[first:]
        self.count += n

    def last(self, n: int | None = None) -> dict:
        avail = min(self.count, self.capacity)
        n = avail if n is None else max(0, min(int(n), avail))
        idx = (np.arange(self.count - n, self.count)) % self.capacity
        return {k: v[idx] for k, v in self.data.items()}


class Acquisition:
    """Collect the cube and the reference in a thread, with host timestamps.

    Parameters
    ----------
    pito : PitoSerial
        The cube (started here if not yet started).
    netft : NetFT, optional
        The reference sensor (started here if not yet started). Without it, sessions
        cannot be built but recording and live display work.
    buffer_seconds : float, optional
        Seconds kept in the ring buffers, at ``rate_hz``; default 600.
    rate_hz : float, optional
        Nominal sample rate used to size the buffers, default 1000.
    recorder : RecordingWriter, optional
        Every sample collected is also appended to it (from the collecting thread).
    meta : dict, optional
        Extra metadata copied into the sessions' ``meta`` (e.g. ``{"simulated": True}``).

    Notes
    -----
    All public methods are thread-safe. Times are host monotonic seconds (:meth:`now`).
    """

    def __init__(self, pito, netft=None, *, buffer_seconds: float = 600.0, rate_hz: float = 1000.0,
                 recorder=None, meta: dict | None = None):
        if not buffer_seconds > 0:
            raise ValueError(f"buffer_seconds: expected > 0, got {buffer_seconds!r}")
        if not rate_hz > 0:
            raise ValueError(f"rate_hz: expected > 0, got {rate_hz!r}")
        self.pito, self.netft, self.recorder = pito, netft, recorder
        self.meta = dict(meta or {})
        cap = int(buffer_seconds * rate_hz * 1.2) + 1
        self._pito_ring = _Ring(cap, {"seq": (np.uint32, ()), "time_us": (np.uint32, ()), "tick": (np.int64, ()),
                                      "counts": (np.int32, (N_CHANNELS,)), "host_time": (np.float64, ())})
        self._ft_ring = _Ring(cap, {"rdt_seq": (np.uint32, ()), "ft_seq": (np.uint32, ()), "tick": (np.int64, ()),
                                    "status": (np.uint32, ()), "wrench": (np.float64, (6,)),
                                    "host_time": (np.float64, ()), "saturated": (bool, ())})
        self._unwrap = {"pito": None, "netft": None}
        self._lock = threading.Lock()
        self._collect_lock = threading.Lock()
        self._stop = threading.Event()
        self._thread = None
        self.counts_offset = np.zeros(N_CHANNELS)
        self.reference_bias = np.zeros(6)
        self.tared_at: float | None = None

    # ------------------------------------------------------------------ lifecycle
    @staticmethod
    def now() -> float:
        """The host clock used for every timestamp (``time.monotonic()``, s)."""
        return time.monotonic()

    def start(self) -> "Acquisition":
        """Start the devices (if needed) and the collecting thread."""
        if self._thread is None:
            self.pito.start()
            if self.netft is not None:
                self.netft.start()
            self._stop.clear()
            self._thread = threading.Thread(target=self._run, name="Acquisition", daemon=True)
            self._thread.start()
        return self

    def stop(self) -> None:
        """Stop collecting (the devices stay open); flushes the recorder."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
            self._thread = None
        self._drain()
        if self.recorder is not None:
            self.recorder.flush()

    def close(self) -> None:
        """Stop collecting and close both devices."""
        self.stop()
        self.pito.close()
        if self.netft is not None:
            self.netft.close()

    def __enter__(self) -> "Acquisition":
        return self.start()

    def __exit__(self, *exc) -> None:
        self.close()

    def _run(self) -> None:
        while not self._stop.is_set():
            self._collect(timeout=0.02)

    def _drain(self) -> None:
        self._collect(timeout=0)

    def _collect(self, timeout: float) -> None:
        with self._collect_lock:  # read + append atomically: order is kept across threads
            b = self.pito.read(timeout=timeout)
            f = self.netft.read(timeout=0) if self.netft is not None else None
            if b is not None:
                self._add_pito(b)
            if f is not None:
                self._add_netft(f)
            if self.recorder is not None:
                self.recorder.maybe_flush()

    def _tick(self, name: str, raw: np.ndarray) -> np.ndarray:
        """Unwrap a u32 counter to int64; a backward jump (device restart) continues by +1."""
        prev = self._unwrap[name]
        r = raw.astype(np.int64)
        d = np.diff(r, prepend=r[0] if prev is None else prev[0]) % 2**32
        d[d >= 2**31] = 1
        if prev is None:
            d[0] = 0
        ticks = (0 if prev is None else prev[1]) + np.cumsum(d)
        self._unwrap[name] = (int(r[-1]), int(ticks[-1]))
        return ticks

    def _add_pito(self, b: PitoBatch) -> None:
        with self._lock:
            tick = self._tick("pito", b.time_us)
            self._pito_ring.append(seq=b.seq, time_us=b.time_us, tick=tick, counts=b.counts, host_time=b.host_time)
        if self.recorder is not None:
            self.recorder.append_pito(b.seq, b.time_us, b.host_time, b.counts)

    def _add_netft(self, f: NetFTBatch) -> None:
        with self._lock:
            tick = self._tick("netft", f.rdt_seq)
            self._ft_ring.append(rdt_seq=f.rdt_seq, ft_seq=f.ft_seq, tick=tick, status=f.status,
                                 wrench=f.wrench, host_time=f.host_time, saturated=f.saturated)
        if self.recorder is not None:
            self.recorder.append_netft(f.rdt_seq, f.ft_seq, f.status, f.host_time, f.wrench)

    # ------------------------------------------------------------------ views
    def latest(self, n: int | None = None, *, tared: bool = False):
        """The last ``n`` samples of each stream (all buffered if None).

        Returns
        -------
        (PitoBatch, NetFTBatch or None)
            Counts (n, 36) and wrench (m, 6) in N, N·m, with host times. With
            ``tared=True`` the counts are float, minus :attr:`counts_offset`, and the
            wrench is minus :attr:`reference_bias`.
        """
        with self._lock:
            p = self._pito_ring.last(n)
            f = self._ft_ring.last(n) if self.netft is not None else None
        counts = p["counts"] - self.counts_offset if tared else p["counts"]
        pb = PitoBatch(p["seq"], p["time_us"], counts, p["host_time"])
        if f is None:
            return pb, None
        wrench = f["wrench"] - self.reference_bias if tared else f["wrench"]
        return pb, NetFTBatch(f["rdt_seq"], f["ft_seq"], f["status"], wrench, f["host_time"], f["saturated"])

    def _window(self, ring: _Ring, t0, t1) -> dict:
        with self._lock:
            d = ring.last()
        t = d["host_time"]
        m = np.ones(t.shape, bool)
        if t0 is not None:
            m &= t >= t0
        if t1 is not None:
            m &= t <= t1
        return {k: v[m] for k, v in d.items()}

    def tare(self, duration: float = 0.5) -> dict:
        """Take the mean of the last ``duration`` s of both streams as the unloaded offsets.

        Sets :attr:`counts_offset` ``(36,)`` (counts) and :attr:`reference_bias` ``(6,)``
        (N, N·m), records a ``tare`` event in the recorder if any, and returns them.

        Raises
        ------
        ValueError
            If a stream has no sample in that window.
        """
        if not duration > 0:
            raise ValueError(f"duration: expected > 0 s, got {duration!r}")
        self._drain()
        now = self.now()
        p = self._window(self._pito_ring, now - duration, None)
        if p["counts"].shape[0] == 0:
            raise ValueError(f"duration: no cube sample in the last {duration} s")
        counts_offset = p["counts"].mean(axis=0)
        bias = self.reference_bias
        if self.netft is not None:
            f = self._window(self._ft_ring, now - duration, None)
            if f["wrench"].shape[0] == 0:
                raise ValueError(f"duration: no reference sample in the last {duration} s")
            bias = f["wrench"].mean(axis=0)
        self.counts_offset, self.reference_bias, self.tared_at = counts_offset, bias, now
        out = {"counts_offset": counts_offset.tolist(), "reference_bias": bias.tolist(), "host_time": now,
               "duration": duration}
        if self.recorder is not None:
            self.recorder.append_event({"type": "tare", **out})
        return out

    def stats(self) -> dict:
        """``{"pito": PitoSerial.stats(), "netft": NetFT.stats() or None, "buffered": {...}}``."""
        return {
            "pito": self.pito.stats(),
            "netft": None if self.netft is None else self.netft.stats(),
            "buffered": {"pito": min(self._pito_ring.count, self._pito_ring.capacity),
                         "netft": min(self._ft_ring.count, self._ft_ring.capacity)},
        }

    # ------------------------------------------------------------------ sessions
    def to_session(self, t0=None, t1=None, loaded=None, *, flange, connected_face, T_core_ati,
                   core=None, meta: dict | None = None, reference_delay: float = 0.0):
        """Build a :class:`~pito_core.calibration.CalibrationSession` from the buffered samples.

        Parameters
        ----------
        t0, t1 : float, optional
            Host-time window (s, :meth:`now`); default everything buffered.
        loaded : None, int, array-like or callable, optional
            Which faces are loaded: None (all unloaded), a face number 1..6 (that face,
            for every sample), a ``(6,)`` bool mask for every sample, an ``(N, 6)`` bool
            array for the N cube samples in the window, or ``f(time (N,)) -> (N, 6)``.
        flange, connected_face, T_core_ati, core
            As :class:`CalibrationSession`.
        meta : dict, optional
            Added to the session's ``meta`` (with the clock fits, tare and device stats).
        reference_delay : float, optional
            Extra transport latency of the reference relative to the cube, s (see module
            docstring); default 0.

        Returns
        -------
        CalibrationSession
            ``counts`` raw (the calibration removes the unloaded offset itself),
            ``reference`` interpolated at the cube samples and minus
            :attr:`reference_bias`, ``time`` the cube's de-jittered host times (s).

        Raises
        ------
        ValueError
            No reference connected, no samples in the window, or a bad ``loaded``.
        """
        from ..calibration import CalibrationSession

        if self.netft is None:
            raise ValueError("netft: a reference sensor is needed to build a session")
        self._drain()
        margin = 0.5
        p = self._window(self._pito_ring, None if t0 is None else t0 - margin, None if t1 is None else t1 + margin)
        f = self._window(self._ft_ring, None if t0 is None else t0 - margin, None if t1 is None else t1 + margin)
        if p["tick"].size < 2 or f["tick"].size < 2:
            raise ValueError("t0, t1: fewer than 2 samples of a stream in the window")
        cube_clock = fit_clock(p["tick"] * 1e-6, p["host_time"])
        ref_clock = fit_clock(f["tick"], f["host_time"])
        t_cube = cube_clock(p["tick"] * 1e-6)
        t_ref = ref_clock(f["tick"]) - reference_delay
        sel = np.ones(t_cube.shape, bool)
        if t0 is not None:
            sel &= p["host_time"] >= t0
        if t1 is not None:
            sel &= p["host_time"] <= t1
        sel &= (t_cube >= t_ref.min()) & (t_cube <= t_ref.max())  # no extrapolation
        if not sel.any():
            raise ValueError("t0, t1: no cube sample inside the reference's time span")
        t = t_cube[sel]
        order = np.argsort(t_ref, kind="stable")
        w = f["wrench"][order] - self.reference_bias
        reference = np.column_stack([np.interp(t, t_ref[order], w[:, j]) for j in range(6)])
        loaded_arr = self._loaded(loaded, t)
        info = dict(self.meta)
        info.update(meta or {})
        info["acquisition"] = {
            "clock_cube": {"offset": cube_clock.offset, "slope": cube_clock.slope, "jitter": cube_clock.residual_max},
            "clock_reference": {"offset": ref_clock.offset, "slope": ref_clock.slope, "jitter": ref_clock.residual_max},
            "reference_delay": reference_delay,
            "reference_bias": self.reference_bias.tolist(),
            "counts_offset": self.counts_offset.tolist(),
            "saturated_reference_samples": int(f["saturated"].sum()),
        }
        return CalibrationSession(p["counts"][sel], reference, loaded_arr, T_core_ati, flange, connected_face,
                                  core=core, time=t, meta=info)

    @staticmethod
    def _loaded(loaded, t: np.ndarray) -> np.ndarray:
        n = t.size
        if loaded is None:
            return np.zeros((n, 6), bool)
        if callable(loaded):
            out = np.asarray(loaded(t))
        elif np.isscalar(loaded) and not isinstance(loaded, (bool, np.bool_)):
            from ..frames import check_face

            face = check_face(loaded, "loaded")
            out = np.zeros((n, 6), bool)
            out[:, face - 1] = True
        else:
            out = np.asarray(loaded)
            if out.shape == (6,):
                out = np.broadcast_to(out, (n, 6))
        if out.shape != (n, 6):
            raise ValueError(f"loaded: expected None, a face 1..6, a (6,) mask or shape ({n}, 6), got {out.shape}")
        return out.astype(bool)

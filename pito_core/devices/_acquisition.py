"""Acquisition: both streams with host timestamps, ring buffers, live tare, calibration sessions.

Typical use (the desktop wizard does the same, from its worker thread)::

    with Acquisition(PitoSerial(port), NetFT(host)) as acq:
        time.sleep(1.0); acq.tare()                  # unloaded: offsets of both
        t0 = acq.now(); ...apply loads on face 2...; t1 = acq.now()
        session = acq.to_session(t0, t1, loaded=2, flange="frame", connected_face=6,
                                 T_core_ati=T)

Every sample is stamped on arrival with the host clock (``host_time``, ``time.monotonic()``
s) and, as it is collected, given its sample ``time`` by the one pairing rule
(:mod:`pito_core.devices._clock`: the device's own clock put on the host clock by the
smallest recent transport delay). Readers take new rows by their write cursor
(:meth:`Acquisition.read_since`), so the work per read is proportional to the new samples.
:meth:`Acquisition.to_session` pairs the reference to the cube samples by the same rule.
"""

from __future__ import annotations

import threading
import time

import numpy as np

from ..frames import N_GAUGES, check_face
from ..io import RecordingWriter, session_from_arrays
from ._clock import PAIRING_RULE, StreamClock, TickUnwrapper, pair_reference
from ._netft import NetFTBatch
from ._serial import PitoBatch
from ._tare import tare_event

__all__ = ["Acquisition"]

#: The rows of the cube's ring: name -> (dtype, shape of one row).
PITO_ROWS = {"seq": (np.uint32, ()), "time_us": (np.uint32, ()), "tick": (np.int64, ()),
             "counts": (np.int32, (N_GAUGES,)), "host_time": (np.float64, ()), "time": (np.float64, ())}
#: The rows of the reference's ring.
NETFT_ROWS = {"rdt_seq": (np.uint32, ()), "ft_seq": (np.uint32, ()), "tick": (np.int64, ()),
              "status": (np.uint32, ()), "wrench": (np.float64, (6,)), "host_time": (np.float64, ()),
              "saturated": (bool, ()), "time": (np.float64, ())}


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

    def since(self, cursor: int, limit: int | None = None) -> tuple[dict, int, int]:
        """Rows appended after ``cursor`` (a past :attr:`count`): ``(rows, new cursor, lost)``.

        Reads by the write cursor: the work is proportional to the new rows, never to the
        capacity (a wrap gives two slices). ``lost`` counts rows overwritten before they
        were read (the reader fell behind by more than the capacity). ``limit`` caps the
        rows returned (the oldest first); the cursor then stops after them.
        """
        end = self.count
        start = max(int(cursor), end - self.capacity)
        lost = start - int(cursor)
        if limit is not None:
            end = min(end, start + int(limit))
        n = end - start
        a, b = start % self.capacity, end % self.capacity
        if n == 0:
            return {k: v[:0].copy() for k, v in self.data.items()}, end, lost
        if a < b:
            rows = {k: v[a:b].copy() for k, v in self.data.items()}
        else:
            rows = {k: np.concatenate([v[a:], v[:b]]) for k, v in self.data.items()}
        return rows, end, lost

    def last(self, n: int | None = None) -> dict:
        avail = min(self.count, self.capacity)
        n = avail if n is None else max(0, min(int(n), avail))
        idx = (np.arange(self.count - n, self.count)) % self.capacity
        return {k: v[idx] for k, v in self.data.items()}


class RingReader:
    """Reading both streams' rings by write cursor (shared by :class:`Acquisition` and its remote twin).

    Subclasses own ``_pito_ring``, ``_ft_ring`` (:class:`_Ring` of :data:`PITO_ROWS`,
    :data:`NETFT_ROWS`), ``_lock`` and ``has_reference``.
    """

    def cursors(self) -> tuple[int, int]:
        """The write cursors ``(cube, reference)``: rows appended so far to each ring."""
        with self._lock:
            return self._pito_ring.count, self._ft_ring.count

    def read_since(self, cube_cursor: int, reference_cursor: int, limit: int | None = None):
        """Rows appended after the cursors: ``(cube rows, reference rows or None, new cursors, lost)``.

        Rows are dicts of arrays: cube ``seq, time_us, tick, counts (n, 36), host_time, time``;
        reference ``rdt_seq, ft_seq, tick, status, wrench (m, 6), host_time, saturated, time``
        (``time``: sample time by the pairing rule, s). Work is proportional to the new rows.
        ``lost`` ``(cube, reference)`` counts rows overwritten before they were read.
        """
        with self._lock:
            p, pc, pl = self._pito_ring.since(cube_cursor, limit)
            if self.has_reference:
                f, fc, fl = self._ft_ring.since(reference_cursor, limit)
            else:
                f, fc, fl = None, reference_cursor, 0
        return p, f, (pc, fc), (pl, fl)


class Acquisition(RingReader):
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
    reference_rate_hz : float, optional
        The Net F/T's configured RDT output rate, Hz (its ``rdt_sequence`` clock), default 1000.
    recorder : RecordingWriter, optional
        Every sample collected is also appended to it (from the collecting thread).
    meta : dict, optional
        Extra metadata copied into the sessions' ``meta`` (e.g. ``{"simulated": True}``).

    Notes
    -----
    All public methods are thread-safe. Times are host monotonic seconds (:meth:`now`).
    """

    def __init__(self, pito, netft=None, *, buffer_seconds: float = 600.0, rate_hz: float = 1000.0,
                 reference_rate_hz: float = 1000.0, recorder=None, meta: dict | None = None):
        if not buffer_seconds > 0:
            raise ValueError(f"buffer_seconds: expected > 0, got {buffer_seconds!r}")
        if not rate_hz > 0:
            raise ValueError(f"rate_hz: expected > 0, got {rate_hz!r}")
        if not reference_rate_hz > 0:
            raise ValueError(f"reference_rate_hz: expected > 0 Hz, got {reference_rate_hz!r}")
        self.reference_rate_hz = float(reference_rate_hz)
        self.pito, self.netft, self.recorder = pito, netft, recorder
        self.meta = dict(meta or {})
        cap = int(buffer_seconds * rate_hz * 1.2) + 1
        self._pito_ring = _Ring(cap, PITO_ROWS)
        self._ft_ring = _Ring(cap, NETFT_ROWS)
        self._unwrap = {"pito": TickUnwrapper(), "netft": TickUnwrapper()}
        self._clock = {"pito": StreamClock(), "netft": StreamClock()}
        self._lock = threading.Lock()
        self._collect_lock = threading.Lock()
        self._stop = threading.Event()
        self._thread = None
        self.counts_offset = np.zeros(N_GAUGES)
        self.reference_bias = np.zeros(6)
        self.tared_at: float | None = None
        #: called (no arguments, in the collecting thread) after new rows reached the rings, so a
        #: consumer can wait for data instead of polling; keep it short, it must not raise
        self.listener = None

    # ------------------------------------------------------------------ lifecycle
    @staticmethod
    def now() -> float:
        """The host clock used for every timestamp (``time.monotonic()``, s)."""
        return time.monotonic()

    @property
    def has_reference(self) -> bool:
        """A reference device (Net F/T) is connected."""
        return self.netft is not None

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
        listener = self.listener
        if listener is not None and (b is not None or f is not None):
            listener()

    def _add_pito(self, b: PitoBatch) -> None:
        with self._lock:
            tick = self._unwrap["pito"](b.time_us)
            t = self._clock["pito"](tick * 1e-6, b.host_time, self._unwrap["pito"].restarts)
            self._pito_ring.append(seq=b.seq, time_us=b.time_us, tick=tick, counts=b.counts, host_time=b.host_time,
                                   time=t)
            recorder = self.recorder
        if recorder is not None:
            recorder.append_pito(b.seq, b.time_us, b.host_time, b.counts)

    def _add_netft(self, f: NetFTBatch) -> None:
        with self._lock:
            tick = self._unwrap["netft"](f.rdt_seq)
            t = self._clock["netft"](tick / self.reference_rate_hz, f.host_time, self._unwrap["netft"].restarts)
            self._ft_ring.append(rdt_seq=f.rdt_seq, ft_seq=f.ft_seq, tick=tick, status=f.status,
                                 wrench=f.wrench, host_time=f.host_time, saturated=f.saturated, time=t)
            recorder = self.recorder
        if recorder is not None:
            recorder.append_netft(f.rdt_seq, f.ft_seq, f.status, f.host_time, f.wrench)

    # ------------------------------------------------------------------ recording
    def start_recording(self, writer) -> None:
        """Append every sample collected from now on to ``writer`` (a ``RecordingWriter``), beside any reader.

        Recording runs in the collecting thread, so a slow consumer (a screen) never loses
        samples. The recording's metadata gets ``reference_rate_hz`` if it has none.
        """
        with self._collect_lock:
            writer.meta.setdefault("reference_rate_hz", self.reference_rate_hz)
            with self._lock:
                # the clocks' state before the first recorded sample: the replay's times and pairing
                # are then the live ones from the first sample on (pipeline.recording_samples)
                writer.append_event({"type": "clock", "host_time": self.now(),
                                     **{name: {"clock": self._clock[name].state(), "ticks": self._unwrap[name].state()}
                                        for name in ("pito", "netft")}})
                self.recorder = writer

    def stop_recording(self):
        """Stop appending to the recorder and return it (not closed), or None."""
        with self._collect_lock:
            with self._lock:
                rec, self.recorder = self.recorder, None
        if rec is not None:
            rec.flush()
        return rec

    def open_recording(self, path, meta: dict | None = None) -> None:
        """Record every sample from now on to a new ``pito-recording`` file at ``path`` (see :meth:`start_recording`).

        The same call on :class:`~pito_core.devices.RemoteAcquisition` opens the file in the
        acquisition's own process.
        """
        self.start_recording(RecordingWriter(path, meta=dict(meta or {})))

    def record_event(self, event: dict) -> None:
        """Append ``event`` (a JSON-able dict, e.g. a pipeline's ``tare``) to the recording, if recording."""
        with self._collect_lock:
            if self.recorder is not None:
                self.recorder.append_event(event)

    def close_recording(self) -> dict:
        """Stop recording and close the file: ``{"rows": {"pito": n, "netft": m}, "path": str}`` (empty if none)."""
        rec = self.stop_recording()
        if rec is None:
            return {}
        rec.close()
        return {"rows": dict(rec.rows_written), "path": str(rec.path)}

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
        (N, N·m), records a ``tare`` event in the recorder if any (the event of
        ``pito_core.pipeline.Pipeline.tare``: ``from_tick`` is the next cube tick, µs), and
        returns them.

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
        wrench = np.zeros((0, 6))
        if self.netft is not None:
            f = self._window(self._ft_ring, now - duration, None)
            if f["wrench"].shape[0] == 0:
                raise ValueError(f"duration: no reference sample in the last {duration} s")
            wrench = f["wrench"]
        # the one tare event (``Pipeline.tare``'s): replay applies it from the next cube sample
        out = tare_event(p["counts"], wrench, from_tick=int(p["tick"][-1]) + 1, duration=duration,
                         previous_bias=self.reference_bias, host_time=now)
        self.counts_offset = np.asarray(out["counts_offset"])
        self.reference_bias, self.tared_at = np.asarray(out["reference_bias"]), now
        if self.recorder is not None:
            self.recorder.append_event(out)
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
        """Build a :class:`~pito_core.io.CalibrationSession` from the buffered samples.

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
            Extra transport latency of the reference relative to the cube, s (not
            observable from the data); default 0.

        Returns
        -------
        CalibrationSession
            ``counts`` raw (the calibration removes the unloaded offset itself),
            ``reference`` paired to the cube samples by the one pairing rule
            (:mod:`pito_core.devices._clock`) and minus :attr:`reference_bias`, ``time``
            the cube's sample times (s, host clock).

        Raises
        ------
        ValueError
            No reference connected, no samples in the window, or a bad ``loaded``.
        """
        if self.netft is None:
            raise ValueError("netft: a reference sensor is needed to build a session")
        self._drain()
        margin = 0.5
        p = self._window(self._pito_ring, None if t0 is None else t0 - margin, None if t1 is None else t1 + margin)
        f = self._window(self._ft_ring, None if t0 is None else t0 - margin, None if t1 is None else t1 + margin)
        if p["tick"].size < 2 or f["tick"].size < 2:
            raise ValueError("t0, t1: fewer than 2 samples of a stream in the window")
        t_cube = p["time"]
        t_ref = f["time"] - reference_delay
        sel = np.ones(t_cube.shape, bool)
        if t0 is not None:
            sel &= p["host_time"] >= t0
        if t1 is not None:
            sel &= p["host_time"] <= t1
        sel &= (t_cube >= t_ref[0]) & (t_cube <= t_ref[-1])  # no extrapolation
        if not sel.any():
            raise ValueError("t0, t1: no cube sample inside the reference's time span")
        # issue 13: a sample paired with a saturated reference record, or with a cube gauge at its
        # ADC limit, never enters a calibration
        t = t_cube[sel]
        sat_ref = pair_reference(t, t_ref, np.repeat(f["saturated"].astype(float)[:, None], 6, axis=1))[:, 0] > 0
        reference = pair_reference(t, t_ref, f["wrench"]) - self.reference_bias
        loaded_arr = self._loaded(loaded, t)
        info = dict(self.meta)
        info.update(meta or {})
        info["acquisition"] = {
            "pairing": PAIRING_RULE,
            "reference_rate_hz": self.reference_rate_hz,
            "reference_delay": reference_delay,
            "reference_bias": self.reference_bias.tolist(),
            "counts_offset": self.counts_offset.tolist(),
            "saturated_reference_samples": int(f["saturated"].sum()),
        }
        try:  # the one session builder and saturation rule (the wizard's too)
            session = session_from_arrays(p["counts"][sel], reference, loaded_arr, t, T_core_ati=T_core_ati,
                                          flange=flange, connected_face=connected_face, core=core, meta=info,
                                          reference_saturated=sat_ref)
        except ValueError as exc:
            raise ValueError(f"t0, t1: {exc} in the window") from None
        info["acquisition"]["excluded_saturated_samples"] = session.meta["excluded_saturated_samples"]
        session.meta["acquisition"] = info["acquisition"]
        return session

    @staticmethod
    def _loaded(loaded, t: np.ndarray) -> np.ndarray:
        n = t.size
        if loaded is None:
            return np.zeros((n, 6), bool)
        if callable(loaded):
            out = np.asarray(loaded(t))
        elif np.isscalar(loaded) and not isinstance(loaded, (bool, np.bool_)):
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

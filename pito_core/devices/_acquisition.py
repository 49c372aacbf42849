"""Acquisition: both streams with host timestamps, ring buffers, calibration sessions.

Typical use (the desktop wizard does the same, from its worker thread)::

    with Acquisition(PitoSerial(port), NetFT(host)) as acq:
        time.sleep(1.0); acq.apply_tare(event)       # a tare taken by the pipeline (Pipeline.tare)
        t0 = acq.now(); ...apply loads on face 2...; t1 = acq.now()
        session = acq.to_session(t0, t1, loaded=2, flange="frame", connected_face=6,
                                 T_core_ati=T)

Every sample is stamped on arrival with the host clock (``host_time``, ``time.monotonic()``
s) and, as it is collected, given its sample ``time`` by the one pairing rule
(:mod:`pito_core.devices._clock`: the device's own clock put on the host clock by the
smallest recent transport delay). Readers take new rows by their write cursor
(:meth:`Acquisition.read_since`), so the work per read is proportional to the new samples.
:meth:`Acquisition.to_session` pairs the reference to the cube samples by the same rule.

:class:`Acquisition` owns the devices, the state and the collecting thread's lifecycle; each job
lives in its own module: the rings and reading them (:mod:`._ring`), collecting
(:mod:`._collector`), recording (:mod:`._recorder`) and calibration sessions (:mod:`._session`).
A tare is taken by the one pipeline (``pito_core.pipeline.Pipeline.tare``, its checks in
:mod:`._tare`); :meth:`Acquisition.apply_tare` only applies its event to the sessions built here.
"""

from __future__ import annotations

import threading
import time

import numpy as np

from ..frames import N_GAUGES
from ._clock import StreamClock, TickUnwrapper
from ._collector import Collector
from ._netft import NetFTBatch
from ._recorder import Recorder
from ._ring import NETFT_ROWS, PITO_ROWS, Ring, RingReader
from ._serial import PitoBatch
from ._session import SessionBuilder

__all__ = ["Acquisition"]


class Acquisition(RingReader, Collector, Recorder, SessionBuilder):
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
        self._pito_ring = Ring(cap, PITO_ROWS)
        self._ft_ring = Ring(cap, NETFT_ROWS)
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

    # ------------------------------------------------------------------ views
    def apply_tare(self, event: dict) -> None:
        """Use a tare event (made by ``Pipeline.tare``) for the sessions built from now on.

        Sets :attr:`counts_offset` ``(36,)`` (counts; the event's None: zeros) and
        :attr:`reference_bias` ``(6,)`` (N, N·m), and records the event in the recorder if any.
        """
        off = event.get("counts_offset")
        bias = np.asarray(event["reference_bias"], dtype=float)
        if bias.shape != (6,):
            raise ValueError(f"reference_bias: expected 6 values (N, N·m), got shape {bias.shape}")
        offset = np.zeros(N_GAUGES) if off is None else np.asarray(off, dtype=float)
        if offset.shape != (N_GAUGES,):
            raise ValueError(f"counts_offset: expected {N_GAUGES} counts, got shape {offset.shape}")
        self.counts_offset, self.reference_bias, self.tared_at = offset, bias, self.now()
        if self.recorder is not None:
            self.recorder.append_event(dict(event))

    def latest(self, n: int | None = None):
        """The last ``n`` samples of each stream (all buffered if None), raw.

        Returns
        -------
        (PitoBatch, NetFTBatch or None)
            Counts (n, 36) and wrench (m, 6) in N, N·m, with host times.
        """
        with self._lock:
            p = self._pito_ring.last(n)
            f = self._ft_ring.last(n) if self.netft is not None else None
        pb = PitoBatch(p["seq"], p["time_us"], p["counts"], p["host_time"])
        if f is None:
            return pb, None
        return pb, NetFTBatch(f["rdt_seq"], f["ft_seq"], f["status"], f["wrench"], f["host_time"], f["saturated"])

    def stats(self) -> dict:
        """``{"pito": PitoSerial.stats(), "netft": NetFT.stats() or None, "buffered": {...}}``."""
        return {
            "pito": self.pito.stats(),
            "netft": None if self.netft is None else self.netft.stats(),
            "buffered": {"pito": min(self._pito_ring.count, self._pito_ring.capacity),
                         "netft": min(self._ft_ring.count, self._ft_ring.capacity)},
        }

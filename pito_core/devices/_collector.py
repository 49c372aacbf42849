"""The collecting side of an acquisition: read both devices, stamp the samples, fill the rings.

Every sample is stamped on arrival with the host clock and, as it is collected here, given its
sample ``time`` by the one pairing rule (:mod:`pito_core.devices._clock`); each collected batch
also goes to the recorder, if any.
"""

from __future__ import annotations

from ._netft import NetFTBatch
from ._serial import PitoBatch

__all__ = ["Collector"]


class Collector:
    """The collecting thread's work for :class:`~pito_core.devices.Acquisition`.

    Subclasses own ``pito``, ``netft``, ``recorder``, ``reference_rate_hz``, ``listener``,
    the rings ``_pito_ring``, ``_ft_ring``, the per-stream ``_unwrap`` (:class:`TickUnwrapper`)
    and ``_clock`` (:class:`StreamClock`), ``_lock``, ``_collect_lock`` and ``_stop``.
    """

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

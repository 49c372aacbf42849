"""The cube over a serial port (pyserial): a reader thread, batches of intact frames, stats."""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass

import numpy as np
import serial
from serial.tools import list_ports

from ..frames import N_GAUGES
from ._frame import FrameDecoder
from ._queue import BatchQueue

__all__ = ["PitoSerial", "PitoBatch", "DeviceError", "list_serial_ports", "DEFAULT_BAUDRATE", "StallMonitor", "STALL_AFTER"]

#: Seconds without a frame after which a device is reported "stalled".
STALL_AFTER = 0.1

#: Default baud rate. A 156-byte frame at 1 kHz is 1.56 Mbit/s with 8N1 framing; USB CDC
#: devices ignore the value.
DEFAULT_BAUDRATE = 2_000_000


class DeviceError(OSError):
    """A device could not be opened or answered in a way we cannot use."""


@dataclass(frozen=True)
class PitoBatch:
    """Consecutive intact frames from the cube.

    Attributes
    ----------
    seq : ndarray of uint32, shape (n,)
        Frame sequence numbers (device counter, wraps at 2**32).
    time_us : ndarray of uint32, shape (n,)
        Device clock, µs (wraps at 2**32).
    counts : ndarray of int32, shape (n, 36)
        Gauge counts; face i owns columns ``6(i-1) .. 6i-1``.
    host_time : ndarray of float64, shape (n,)
        Host clock (``time.monotonic()``, s) when the bytes completing each frame arrived.
    """

    seq: np.ndarray
    time_us: np.ndarray
    counts: np.ndarray
    host_time: np.ndarray

    def __len__(self) -> int:
        return int(self.seq.shape[0])

    @staticmethod
    def concatenate(batches) -> "PitoBatch":
        batches = list(batches)
        if not batches:
            return PitoBatch(
                np.zeros(0, np.uint32), np.zeros(0, np.uint32), np.zeros((0, N_GAUGES), np.int32), np.zeros(0)
            )
        return PitoBatch(*(np.concatenate([getattr(b, f) for b in batches]) for f in ("seq", "time_us", "counts", "host_time")))


def list_serial_ports() -> list[dict]:
    """Serial ports on this machine, best first: ``[{"device", "description", "hwid"}, ...]``.

    USB ports (the cube's kind) come first, then the others; each group by device path.
    """
    ports = sorted(list_ports.comports(), key=lambda p: ("USB" not in (p.description or ""), p.device))
    return [{"device": p.device, "description": p.description or "", "hwid": p.hwid or ""} for p in ports]


class SequenceTracker:
    """Counts frames missing from a wrapping u32 sequence (``dropped``), late ones and restarts.

    A forward jump of g (modulo 2**32, g < 2**31) means ``g - 1`` frames were lost. A number
    up to ``reorder_window`` behind the highest one seen is a late (out-of-order) record: it
    is counted in ``out_of_order`` and no longer as lost. A repeat of the last number or a
    larger backward jump is a device restart (``restarts``), not a loss.
    """

    def __init__(self, bits: int = 32, reorder_window: int = 1024):
        self.modulus = 2**bits
        self.reorder_window = int(reorder_window)
        self.last: int | None = None
        self.dropped = 0
        self.restarts = 0
        self.out_of_order = 0
        self._missing: set[int] = set()  # skipped numbers of the last ``reorder_window``

    def _skip(self, last: int, v: int, g: int) -> None:
        if g - 1 <= self.reorder_window:
            self._missing.update((last + k) % self.modulus for k in range(1, g))
        if len(self._missing) > 4 * self.reorder_window:
            lo = (v - self.reorder_window) % self.modulus
            self._missing = {m for m in self._missing if (m - lo) % self.modulus <= self.reorder_window}

    def update(self, seq: np.ndarray) -> None:
        if seq.size == 0:
            return
        s = seq.astype(np.int64)
        prev = np.concatenate([[self.last if self.last is not None else s[0] - 1], s[:-1]])
        gap = (s - prev) % self.modulus
        forward = (gap >= 1) & (gap < self.modulus // 2)
        if forward.all():
            self.dropped += int((gap - 1).sum())
            for i in np.flatnonzero(gap > 1).tolist():
                self._skip(int(prev[i]), int(s[i]), int(gap[i]))
            self.last = int(s[-1])
            return
        last = self.last if self.last is not None else int(s[0]) - 1
        half = self.modulus // 2
        for v in s.tolist():
            g = (v - last) % self.modulus
            if 1 <= g < half:
                self.dropped += g - 1
                if g > 1:
                    self._skip(last, v, g)
                last = v
            elif v in self._missing:
                self._missing.discard(v)
                self.out_of_order += 1  # a late record: it was counted lost when skipped
                self.dropped -= 1
            else:
                self.restarts += 1
                self._missing.clear()
                last = v
        self.last = last


class StallMonitor:
    """"Stalled" when no data came for more than ``after`` s; counted, timed, cleared on resume.

    The reader thread calls :meth:`data` when data arrive and :meth:`poll` at least every
    ``after`` / 2 s, so a stall is flagged within ``after`` + one poll period.
    """

    def __init__(self, after: float = 0.1):
        if not after > 0:
            raise ValueError(f"stall_after: expected > 0 s, got {after!r}")
        self.after = float(after)
        self.last = time.monotonic()
        self.stalled = False
        self.stalls = 0
        self.stalled_s = 0.0
        self.since: float | None = None
        self.events: list[dict] = []

    def data(self, now: float) -> None:
        if self.stalled:
            self.stalled_s += now - self.since
            self.events.append({"event": "resumed", "host_time": now, "stalled_s": now - self.since})
            self.stalled = False
        self.last = now

    def poll(self, now: float) -> None:
        if not self.stalled and now - self.last > self.after:
            self.stalled, self.since = True, self.last
            self.stalls += 1
            self.events.append({"event": "stalled", "host_time": now, "last_data": self.last})

    def stats(self, now: float | None = None) -> dict:
        now = time.monotonic() if now is None else now
        return {
            "stalled": self.stalled,
            "stalls": self.stalls,
            "stalled_s": self.stalled_s + ((now - self.since) if self.stalled else 0.0),
            "since_data_s": now - self.last,
        }


class PitoSerial:
    """The PITO cube on a serial port: frames decoded in a reader thread.

    Parameters
    ----------
    port : str
        Serial device (``/dev/ttyACM0``, ``COM3``, a pty path of the simulator, ...).
    baudrate : int, optional
        Default :data:`DEFAULT_BAUDRATE` (2 Mbaud; the stream needs 1.56 Mbit/s at 1 kHz).
    reconnect : bool, optional
        After an unplug (read error), reopen ``port`` every ``reconnect_interval`` s until
        it is back or :meth:`close` is called. Default True.
    reconnect_interval : float, optional
        Seconds between reopen attempts, default 0.25.
    max_pending : int, optional
        Frames kept for :meth:`read` if nobody reads (oldest dropped beyond, counted as
        ``overflow``). Default 600 000 (10 min at 1 kHz).
    stall_after : float, optional
        Seconds without an intact frame after which :meth:`stats` says ``stalled``
        (default :data:`STALL_AFTER`, 0.1 s; flagged within 0.15 s).

    Examples
    --------
    >>> with PitoSerial("/dev/ttyACM0") as cube:          # doctest: +SKIP
    ...     batch = cube.read(timeout=1.0)
    ...     batch.counts.shape                            # (n, 36)
    """

    def __init__(
        self,
        port: str,
        baudrate: int = DEFAULT_BAUDRATE,
        *,
        reconnect: bool = True,
        reconnect_interval: float = 0.25,
        max_pending: int = 600_000,
        stall_after: float = STALL_AFTER,
    ):
        if not isinstance(port, str) or not port:
            raise ValueError(f"port: expected a device path, got {port!r}")
        if int(baudrate) <= 0:
            raise ValueError(f"baudrate: expected a positive integer, got {baudrate!r}")
        if reconnect_interval <= 0:
            raise ValueError(f"reconnect_interval: expected > 0 s, got {reconnect_interval!r}")
        self.port = port
        self.baudrate = int(baudrate)
        self.reconnect = bool(reconnect)
        self.reconnect_interval = float(reconnect_interval)
        self.max_pending = int(max_pending)
        self._decoder = FrameDecoder()
        self._seq = SequenceTracker()
        self._serial = None
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._queue = BatchQueue(self.max_pending, PitoBatch.concatenate)
        self._reconnects = 0
        self._overflow = 0
        self._connected = False
        self._error: str | None = None
        self._stall = StallMonitor(stall_after)

    # ------------------------------------------------------------------ lifecycle
    def _open(self):
        return serial.Serial(self.port, self.baudrate, timeout=0.05)

    def start(self) -> "PitoSerial":
        """Open the port and start the reader thread. Raises :class:`DeviceError` if the port cannot be opened."""
        if self._thread is not None:
            return self
        try:
            self._serial = self._open()
        except Exception as exc:  # serial.SerialException, OSError
            raise DeviceError(f"port: cannot open {self.port!r}: {exc}") from None
        self._connected = True
        self._stall = StallMonitor(self._stall.after)
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, name=f"PitoSerial({self.port})", daemon=True)
        self._thread.start()
        return self

    def close(self) -> None:
        """Stop the reader thread and close the port (idempotent)."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
            self._thread = None
        if self._serial is not None:
            try:
                self._serial.close()
            except OSError:  # closing a port that is already gone (serial.SerialException is an OSError)
                pass
            self._serial = None
        self._connected = False
        self._queue.wake()

    def __enter__(self) -> "PitoSerial":
        return self.start()

    def __exit__(self, *exc) -> None:
        self.close()

    # ------------------------------------------------------------------ reader thread
    def _run(self) -> None:
        ser = self._serial
        while not self._stop.is_set():
            try:
                waiting = ser.in_waiting
                data = ser.read(waiting if waiting > 0 else 1)
                if waiting == 0 and data:
                    more = ser.in_waiting
                    if more:
                        data += ser.read(more)
            except Exception as exc:  # unplugged: SerialException / OSError
                self._error = str(exc)
                self._connected = False
                try:
                    ser.close()
                except OSError:  # the port is already gone (serial.SerialException is an OSError)
                    pass
                if not self.reconnect:
                    break
                ser = self._reopen()
                if ser is None:
                    break
                continue
            now = time.monotonic()
            self._stall.poll(now)
            if not data:
                continue
            frames = self._decoder.feed(data)
            if len(frames):
                self._stall.data(now)
                self._seq.update(frames.seq)
                batch = PitoBatch(frames.seq, frames.time_us, frames.counts, np.full(len(frames), now))
                dropped = self._queue.put(batch)
                if dropped:
                    self._overflow += dropped

    def _reopen(self):
        next_try = time.monotonic() + self.reconnect_interval
        while not self._stop.wait(min(self.reconnect_interval, self._stall.after / 2)):
            now = time.monotonic()
            self._stall.poll(now)  # an unplugged cube is reported stalled, too
            if now < next_try:
                continue
            next_try = now + self.reconnect_interval
            try:
                ser = self._open()
            except OSError as exc:  # still unplugged: keep the reason visible, retry at the next interval
                self._error = str(exc)
                continue
            self._decoder.reset_alignment()
            self._serial = ser
            self._reconnects += 1
            self._connected = True
            return ser
        return None

    # ------------------------------------------------------------------ consumer API
    def read(self, timeout: float | None = None) -> PitoBatch | None:
        """All frames received since the last call, or None if none came within ``timeout`` s.

        ``timeout=None`` waits until frames arrive or the device is closed; ``0`` polls.
        """
        return self._queue.get(timeout, self._stop)

    def stats(self) -> dict:
        """Counters since :meth:`start`.

        Keys: ``frames`` (intact frames), ``crc_errors``, ``dropped`` (frames missing from
        the sequence: lost on the line, corrupted, or never sent), ``resyncs``,
        ``bytes_skipped``, ``reconnects``, ``seq_restarts`` (sequence went backwards:
        device reset), ``overflow`` (frames discarded because nobody read them),
        ``connected`` (bool), ``last_error`` (str or None), ``stalled`` (bool: no intact
        frame for more than ``stall_after`` s), ``stalls`` (times it stalled), ``stalled_s``
        (s spent stalled), ``since_data_s`` (s since the last intact frame).
        """
        d = self._decoder.stats()
        return {
            **self._stall.stats(),
            "frames": d["frames"],
            "crc_errors": d["crc_errors"],
            "dropped": self._seq.dropped,
            "resyncs": d["resyncs"],
            "bytes_skipped": d["bytes_skipped"],
            "reconnects": self._reconnects,
            "seq_restarts": self._seq.restarts,
            "overflow": self._overflow,
            "connected": self._connected,
            "last_error": self._error,
        }

    #: The serial ports on this machine (see :func:`list_serial_ports`).
    list_ports = staticmethod(list_serial_ports)

    def __repr__(self) -> str:
        return f"PitoSerial({self.port!r}, baudrate={self.baudrate})"

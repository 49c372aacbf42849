"""The simulated cube: real 156-byte frames written into a pseudo-terminal, with fault injection."""

from __future__ import annotations

import contextlib
import os
import select
import tempfile
import threading
import time
import tty

import numpy as np

from ..devices import pack_frames
from ._transport_source import _Clock

__all__ = ["SimulatedPitoPort"]


class SimulatedPitoPort:
    """The virtual cube writing real 156-byte frames into a pseudo-terminal.

    :attr:`port` is a stable path (a symlink to the pty's slave device, like a udev
    ``/dev/serial/by-id`` link) that :class:`PitoSerial` opens. :meth:`unplug` and
    :meth:`replug` simulate pulling the USB cable (the link then points to a new pty).

    pyserial flushes the input when it opens a port, so bytes written before the reader
    opened it are lost (as with a real device): for exact accounting, create the port with
    ``start=False``, open the reader, then call :meth:`start`.

    Parameters
    ----------
    source : Source
        Gauge counts over time.
    rate_hz : float, optional
        Frame rate, default 1000.
    speed : float, optional
        Simulated seconds per wall second (device time follows simulated time), default 1;
        ``float('inf')`` writes as fast as the reader takes (the pty applies flow control,
        so nothing is lost).
    n_frames : int, optional
        Stop after this many frames (default: run until closed).
    drop_rate, corrupt_rate, truncate_rate, noise_rate : float, optional
        Per-frame probabilities: the frame is not sent; one byte after the sync is flipped;
        only a prefix is sent; 1..24 garbage bytes (sometimes starting with the sync bytes)
        are written before it. Default 0.
    seed : int, optional
        Seeds the fault injection.
    chunk : int, optional
        Frames per write, default 10.
    epoch : float, optional
        ``time.monotonic()`` at simulated time 0, shared with other simulated devices so
        they see the same load at the same time; a port started later begins with the
        frame of the current simulated time (as a device that was already running).
        Default: when :meth:`start` is called.

    Attributes
    ----------
    log : dict
        ``sent`` (sequence numbers sent intact), ``dropped``, ``corrupted``, ``truncated``
        (lists of sequence numbers), ``noise_bytes`` (int).
    """

    def __init__(
        self,
        source,
        rate_hz: float = 1000.0,
        *,
        speed: float = 1.0,
        n_frames: int | None = None,
        drop_rate: float = 0.0,
        corrupt_rate: float = 0.0,
        truncate_rate: float = 0.0,
        noise_rate: float = 0.0,
        seed: int = 0,
        chunk: int = 10,
        epoch: float | None = None,
        start: bool = True,
    ):
        if not rate_hz > 0:
            raise ValueError(f"rate_hz: expected > 0, got {rate_hz!r}")
        for name, p in (("drop_rate", drop_rate), ("corrupt_rate", corrupt_rate),
                        ("truncate_rate", truncate_rate), ("noise_rate", noise_rate)):
            if not 0.0 <= p <= 1.0:
                raise ValueError(f"{name}: expected a probability in [0, 1], got {p!r}")
        self.source = source
        self.rate_hz = float(rate_hz)
        self.speed = float(speed)
        self.n_frames = n_frames
        self.rates = (drop_rate, corrupt_rate, truncate_rate, noise_rate)
        self.chunk = int(chunk)
        self.epoch = epoch
        self._rng = np.random.default_rng(seed)
        self.log = {"sent": [], "dropped": [], "corrupted": [], "truncated": [], "noise_bytes": 0}
        self._dir = tempfile.mkdtemp(prefix="pito-sim-")
        self.port = os.path.join(self._dir, "pito")
        self._master = self._slave = None
        self._plugged = threading.Event()
        self._hold_until = 0.0
        self._stop = threading.Event()
        self._thread = None
        self.frames_written = 0
        self.finished = threading.Event()
        self._plug()
        if start:
            self.start()

    def _plug(self) -> None:
        master, slave = os.openpty()
        tty.setraw(slave)  # no line discipline: bytes pass unchanged before the reader configures it
        os.set_blocking(master, False)
        tmp = self.port + ".new"
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        os.symlink(os.ttyname(slave), tmp)
        os.replace(tmp, self.port)
        self._master, self._slave = master, slave
        self._plugged.set()

    def unplug(self) -> None:
        """Simulate pulling the cable: close the pty (the reader gets an I/O error)."""
        self._plugged.clear()
        time.sleep(0.02)  # let the writer leave its write loop
        for fd in (self._master, self._slave):
            with contextlib.suppress(OSError, TypeError):
                os.close(fd)
        self._master = self._slave = None
        with contextlib.suppress(FileNotFoundError):
            os.unlink(self.port)

    def replug(self) -> None:
        """Plug back in: a new pty behind the same :attr:`port` path; streaming goes on."""
        self._plug()

    def stall(self, seconds: float) -> None:
        """Inject a stall (SIMULATED): send nothing for ``seconds`` s; the frames follow late, none lost."""
        if not seconds >= 0:
            raise ValueError(f"seconds: expected >= 0, got {seconds!r}")
        self._hold_until = time.monotonic() + float(seconds)

    def start(self) -> "SimulatedPitoPort":
        if self._thread is None:
            self._thread = threading.Thread(target=self._run, name="SimulatedPitoPort", daemon=True)
            self._thread.start()
        return self

    def close(self) -> None:
        self._stop.set()
        self._plugged.set()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
            self._thread = None
        if self._master is not None:
            self.unplug()
        with contextlib.suppress(OSError):
            os.rmdir(self._dir)

    def __enter__(self) -> "SimulatedPitoPort":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def _faulty_bytes(self, seq: np.ndarray, raw: bytes) -> bytes:
        drop, corrupt, trunc, noise = self.rates
        if not any(self.rates):
            self.log["sent"].extend(seq.tolist())
            return raw
        out = bytearray()
        u = self._rng.random((seq.size, 2))
        for i, s in enumerate(seq.tolist()):
            if u[i, 1] < noise:
                g = bytearray(self._rng.integers(0, 256, int(self._rng.integers(1, 25)), dtype=np.uint8).tobytes())
                if self._rng.random() < 0.3:
                    g[:2] = b"\xaa\x55"
                out += g
                self.log["noise_bytes"] += len(g)
            frame = bytearray(raw[i * 156 : (i + 1) * 156])
            r = u[i, 0]
            if r < drop:
                self.log["dropped"].append(s)
                continue
            if r < drop + corrupt:
                k = int(self._rng.integers(2, 156))
                frame[k] ^= int(self._rng.integers(1, 256))
                self.log["corrupted"].append(s)
            elif r < drop + corrupt + trunc:
                frame = frame[: int(self._rng.integers(2, 155))]
                self.log["truncated"].append(s)
            else:
                self.log["sent"].append(s)
            out += frame
        return bytes(out)

    def _write_all(self, data: bytes) -> bool:
        view = memoryview(data)
        while view:
            if self._stop.is_set():
                return False
            if not self._plugged.is_set():
                return True  # cable out: the bytes are lost
            master = self._master
            try:
                _, w, _ = select.select([], [master], [], 0.05)
                if not w:
                    continue
                n = os.write(master, view)
                view = view[n:]
            except (OSError, ValueError, TypeError):
                if not self._plugged.is_set():
                    return True
                time.sleep(0.001)
        return True

    def _run(self) -> None:
        clock = _Clock(self.speed, self.epoch)
        dt = 1.0 / self.rate_hz
        block = max(self.chunk, int(self.rate_hz * 0.1))  # the source is asked 0.1 s at a time
        seq = seq0 = 0 if self.epoch is None else int(np.ceil(clock.now() * self.rate_hz))
        while not self._stop.is_set():
            nb = block if self.n_frames is None else min(block, seq0 + self.n_frames - seq)
            if nb <= 0:
                break
            idx_block = np.arange(seq, seq + nb)
            t_block = idx_block * dt
            counts_block = np.clip(self.source.counts_at(t_block), -(2**31), 2**31 - 1)
            raw_block = pack_frames(idx_block, np.rint(t_block * 1e6).astype(np.int64), counts_block)
            for i in range(0, nb, self.chunk):
                idx = idx_block[i : i + self.chunk]
                if not clock.wait_until(t_block[i + idx.size - 1], self._stop):
                    self.finished.set()
                    return
                while time.monotonic() < self._hold_until and not self._stop.is_set():  # injected stall
                    time.sleep(0.002)
                raw = raw_block[i * 156 : (i + idx.size) * 156]
                if self._plugged.is_set():
                    if not self._write_all(self._faulty_bytes(idx, raw)):
                        self.finished.set()
                        return
                else:
                    self.log["dropped"].extend(idx.tolist())
                seq += idx.size
                self.frames_written = seq - seq0
        self.finished.set()

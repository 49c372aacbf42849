"""Simulated devices on real transports: the cube on a pseudo-terminal, the Net F/T on loopback UDP.

The physics comes from a *source* (``pito_core.sim`` provides real ones); these classes
only move its numbers through the same bytes as the hardware, so :class:`PitoSerial` and
:class:`NetFT` run unchanged, end to end. Fault injection (dropped, corrupted, truncated
frames, line noise; lost UDP packets, saturation status) is logged exactly so tests can
check every counter.
"""

from __future__ import annotations

import contextlib
import os
import select
import socket
import struct
import tempfile
import threading
import time
import tty
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Protocol

import numpy as np

from ._frame import N_CHANNELS, pack_frames
from ._netft import (
    CMD_BIAS,
    CMD_START_BUFFERED,
    CMD_START_REALTIME,
    CMD_STOP,
    RDT_HEADER,
    RDT_RECORD_DTYPE,
    STATUS_ERROR,
    STATUS_SATURATION,
)

__all__ = [
    "Source",
    "TestSignalSource",
    "SimulatedPitoPort",
    "SimulatedNetFT",
    "open_simulated_devices",
    "default_simulated_source",
]


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
        self.gain = rng.normal(0.0, 1.0, (N_CHANNELS, 6)) * np.array([2e4, 2e4, 2e4, 2e6, 2e6, 2e6])
        self.offset = rng.integers(-50_000, 50_000, N_CHANNELS)
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
            h = np.sin(np.outer(t * 1e3 + 0.5, np.arange(1, N_CHANNELS + 1)) * 12.9898) * 43758.5453
            c = c + self.noise_counts * 3.4 * (h - np.floor(h) - 0.5)  # uniform, std ≈ noise_counts
        return np.rint(c).astype(np.int64)


def default_simulated_source(seed: int = 0):
    """The simulator's default live source (``pito_core.sim.default_live_source``) if
    available, else :class:`TestSignalSource`. Returns ``(source, label)``."""
    try:
        from ..sim import default_live_source  # type: ignore[attr-defined]
    except Exception:
        return TestSignalSource(seed), TestSignalSource.label
    src = default_live_source(seed=seed)
    return src, getattr(src, "label", "simulated cube (pito_core.sim)")


class _Clock:
    """Simulated time: ``speed`` simulated seconds per wall second (inf: as fast as possible)."""

    def __init__(self, speed: float):
        if not speed > 0:
            raise ValueError(f"speed: expected > 0 (inf for as fast as possible), got {speed!r}")
        self.speed = float(speed)
        self.t0 = time.monotonic()

    def wait_until(self, t_sim: float, stop: threading.Event) -> bool:
        """Sleep until simulated time ``t_sim``; False if ``stop`` was set."""
        if np.isinf(self.speed):
            return not stop.is_set()
        delay = self.t0 + t_sim / self.speed - time.monotonic()
        if delay > 0:
            return not stop.wait(delay)
        return not stop.is_set()


class SimulatedPitoPort:
    """The virtual cube writing real 156-byte frames into a pseudo-terminal.

    :attr:`port` is a stable path (a symlink to the pty's slave device, like a udev
    ``/dev/serial/by-id`` link) that :class:`PitoSerial` opens. :meth:`unplug` and
    :meth:`replug` simulate pulling the USB cable (the link then points to a new pty).

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
        self._rng = np.random.default_rng(seed)
        self.log = {"sent": [], "dropped": [], "corrupted": [], "truncated": [], "noise_bytes": 0}
        self._dir = tempfile.mkdtemp(prefix="pito-sim-")
        self.port = os.path.join(self._dir, "pito")
        self._master = self._slave = None
        self._plugged = threading.Event()
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
        clock = _Clock(self.speed)
        seq = 0
        dt = 1.0 / self.rate_hz
        while not self._stop.is_set():
            k = self.chunk if self.n_frames is None else min(self.chunk, self.n_frames - seq)
            if k <= 0:
                break
            idx = np.arange(seq, seq + k)
            t = idx * dt
            if not clock.wait_until(t[-1], self._stop):
                break
            counts = np.clip(self.source.counts_at(t), -(2**31), 2**31 - 1)
            raw = pack_frames(idx, np.rint(t * 1e6).astype(np.int64), counts)
            if self._plugged.is_set():
                data = self._faulty_bytes(idx, raw)
                if not self._write_all(data):
                    break
            else:
                self.log["dropped"].extend(idx.tolist())
            seq += k
            self.frames_written = seq
        self.finished.set()


# ---------------------------------------------------------------------- Net F/T


class SimulatedNetFT:
    """A simulated ATI Net F/T on 127.0.0.1: RDT over UDP and its configuration page over HTTP.

    Answers the RDT start (real-time 0x0002, buffered 0x0003), stop (0x0000) and bias
    (0x0042) requests; serves ``/netftapi2.xml`` with ``cfgcpf``, ``cfgcpt``, ``scfgfu``,
    ``scfgtu`` so :class:`NetFT` reads its scaling the real way.

    Parameters
    ----------
    source : Source
        Reference wrench over time (``reference_at``).
    rate_hz : float, optional
        Record rate, default 1000.
    speed : float, optional
        Simulated seconds per wall second, default 1.
    counts_per_force, counts_per_torque : float, optional
        Scaling served by the configuration page (counts per ``force_unit`` /
        ``torque_unit``), default 1e6 counts/N and 1e6 counts/N·m.
    force_unit, torque_unit : str, optional
        Units served, default ``"N"`` and ``"N-m"``.
    records_per_packet : int, optional
        Records per packet in buffered mode, default 10.
    loss_rate : float, optional
        Probability that a packet is not sent (lost), default 0.
    saturation_rate : float, optional
        Probability that a record carries the saturation status, default 0.
    rated_load : (6,) array-like, optional
        Records whose |wrench| exceeds this on any axis carry the saturation status.
    seed : int, optional

    Attributes
    ----------
    port, http_port : int
        The RDT UDP port and the HTTP port (ephemeral, on 127.0.0.1).
    log : dict
        ``sent`` (rdt sequence numbers of records sent), ``lost`` (records in lost packets),
        ``saturated`` (rdt sequence numbers of sent records flagged), ``requests`` (commands).
    """

    host = "127.0.0.1"

    def __init__(
        self,
        source,
        rate_hz: float = 1000.0,
        *,
        speed: float = 1.0,
        counts_per_force: float = 1e6,
        counts_per_torque: float = 1e6,
        force_unit: str = "N",
        torque_unit: str = "N-m",
        records_per_packet: int = 10,
        loss_rate: float = 0.0,
        saturation_rate: float = 0.0,
        rated_load=None,
        seed: int = 0,
    ):
        if not rate_hz > 0:
            raise ValueError(f"rate_hz: expected > 0, got {rate_hz!r}")
        for name, p in (("loss_rate", loss_rate), ("saturation_rate", saturation_rate)):
            if not 0.0 <= p <= 1.0:
                raise ValueError(f"{name}: expected a probability in [0, 1], got {p!r}")
        self.source = source
        self.rate_hz = float(rate_hz)
        self.speed = float(speed)
        self.cpf, self.cpt = float(counts_per_force), float(counts_per_torque)
        self.force_unit, self.torque_unit = force_unit, torque_unit
        self.records_per_packet = int(records_per_packet)
        self.loss_rate, self.saturation_rate = float(loss_rate), float(saturation_rate)
        self.rated_load = None if rated_load is None else np.asarray(rated_load, dtype=float)
        self._rng = np.random.default_rng(seed)
        self.log = {"sent": [], "lost": [], "saturated": [], "requests": []}
        self._bias = np.zeros(6)
        self._last_wrench = np.zeros(6)
        self._lock = threading.Lock()
        self._stream_stop = threading.Event()
        self._stop = threading.Event()
        self._stream_thread = None
        self._udp = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._udp.bind((self.host, 0))
        self._udp.settimeout(0.1)
        self.port = self._udp.getsockname()[1]
        self._http = ThreadingHTTPServer((self.host, 0), self._handler())
        self._http.daemon_threads = True
        self.http_port = self._http.server_address[1]
        self._threads = [
            threading.Thread(target=self._serve_udp, name="SimulatedNetFT-udp", daemon=True),
            threading.Thread(target=self._http.serve_forever, kwargs={"poll_interval": 0.05},
                             name="SimulatedNetFT-http", daemon=True),
        ]
        for th in self._threads:
            th.start()

    def config_xml(self) -> bytes:
        return (
            '<?xml version="1.0" encoding="UTF-8"?>\n<netft>'
            f"<cfgcpf>{self.cpf:g}</cfgcpf><cfgcpt>{self.cpt:g}</cfgcpt>"
            f"<scfgfu>{self.force_unit}</scfgfu><scfgtu>{self.torque_unit}</scfgtu>"
            "<comrdte>Enabled</comrdte><setserial>SIM-0001</setserial></netft>"
        ).encode()

    def _handler(self):
        sim = self

        class Handler(BaseHTTPRequestHandler):
            def do_GET(self):  # noqa: N802 (http.server naming)
                if self.path.split("?")[0] != "/netftapi2.xml":
                    self.send_error(404)
                    return
                body = sim.config_xml()
                self.send_response(200)
                self.send_header("Content-Type", "text/xml")
                self.send_header("Content-Length", str(len(body)))
                self.end_headers()
                self.wfile.write(body)

            def log_message(self, *args):
                pass

        return Handler

    def _serve_udp(self) -> None:
        while not self._stop.is_set():
            try:
                data, addr = self._udp.recvfrom(64)
            except socket.timeout:
                continue
            except OSError:
                break
            if len(data) != 8:
                continue
            header, command, count = struct.unpack(">HHI", data)
            if header != RDT_HEADER:
                continue
            self.log["requests"].append(command)
            if command in (CMD_START_REALTIME, CMD_START_BUFFERED):
                self._stop_stream()
                per_packet = 1 if command == CMD_START_REALTIME else self.records_per_packet
                self._stream_stop = threading.Event()
                self._stream_thread = threading.Thread(
                    target=self._stream, args=(addr, per_packet, count, self._stream_stop),
                    name="SimulatedNetFT-stream", daemon=True)
                self._stream_thread.start()
            elif command == CMD_STOP:
                self._stop_stream()
            elif command == CMD_BIAS:
                with self._lock:
                    self._bias = self._last_wrench.copy()  # zero the output at the current load

    def _stop_stream(self) -> None:
        self._stream_stop.set()
        if self._stream_thread is not None and self._stream_thread is not threading.current_thread():
            self._stream_thread.join(timeout=2.0)
            self._stream_thread = None

    def _stream(self, addr, per_packet: int, count: int, stop: threading.Event) -> None:
        clock = _Clock(self.speed)
        dt = 1.0 / self.rate_hz
        scale = np.array([self.cpf] * 3 + [self.cpt] * 3)
        from ._netft import FORCE_UNITS, TORQUE_UNITS

        si = np.array([FORCE_UNITS[self.force_unit]] * 3 + [TORQUE_UNITS[self.torque_unit]] * 3)
        k = 0  # records sent in this stream; rdt_sequence restarts at 1 per stream
        while not stop.is_set() and not self._stop.is_set():
            n = per_packet if not count else min(per_packet, count - k)
            if n <= 0:
                break
            idx = np.arange(k, k + n)
            t = idx * dt
            if not clock.wait_until(t[-1], stop):
                break
            wrench = self.source.reference_at(t)
            with self._lock:
                self._last_wrench = wrench[-1]
                w = wrench - self._bias
            rec = np.zeros(n, dtype=RDT_RECORD_DTYPE)
            rec["rdt_seq"] = (idx + 1) % 2**32
            rec["ft_seq"] = (idx * 7 + 1) % 2**32  # the box samples faster than it sends
            rec["counts"] = np.clip(np.rint(w / si * scale), -(2**31), 2**31 - 1).astype(np.int64)
            sat = self._rng.random(n) < self.saturation_rate
            if self.rated_load is not None:
                sat |= (np.abs(wrench) > self.rated_load).any(axis=1)
            rec["status"] = np.where(sat, STATUS_SATURATION | STATUS_ERROR, 0)
            seqs = rec["rdt_seq"].astype(np.int64).tolist()
            if self._rng.random() < self.loss_rate:
                self.log["lost"].extend(seqs)
            else:
                try:
                    self._udp.sendto(rec.tobytes(), addr)
                except OSError:
                    break
                self.log["sent"].extend(seqs)
                self.log["saturated"].extend(np.asarray(seqs)[sat].tolist())
            k += n

    def close(self) -> None:
        self._stop.set()
        self._stop_stream()
        self._http.shutdown()
        self._http.server_close()
        for th in self._threads:
            th.join(timeout=2.0)
        self._udp.close()

    def __enter__(self) -> "SimulatedNetFT":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


@contextlib.contextmanager
def open_simulated_devices(source=None, rate_hz: float = 1000.0, netft_rate_hz: float = 1000.0, *,
                           speed: float = 1.0, pito_options: dict | None = None,
                           netft_options: dict | None = None, seed: int = 0):
    """Start a simulated cube (pty) and a simulated Net F/T (loopback) on one source.

    Yields ``(pito_sim, netft_sim)``: open the real drivers on them with
    ``PitoSerial(pito_sim.port)`` and
    ``NetFT(netft_sim.host, netft_sim.port, http_port=netft_sim.http_port)``.
    ``source=None`` uses :func:`default_simulated_source`.
    """
    if source is None:
        source, _ = default_simulated_source(seed)
    pito_sim = SimulatedPitoPort(source, rate_hz, speed=speed, seed=seed, **(pito_options or {}))
    try:
        netft_sim = SimulatedNetFT(source, netft_rate_hz, speed=speed, seed=seed, **(netft_options or {}))
    except Exception:
        pito_sim.close()
        raise
    try:
        yield pito_sim, netft_sim
    finally:
        netft_sim.close()
        pito_sim.close()

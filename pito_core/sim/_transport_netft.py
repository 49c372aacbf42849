"""The simulated ATI Net F/T: RDT over loopback UDP and its configuration page over HTTP."""

from __future__ import annotations

import socket
import struct
import threading
import time
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

import numpy as np

from ..devices import (
    CMD_BIAS,
    CMD_START_BUFFERED,
    CMD_START_REALTIME,
    CMD_STOP,
    FORCE_UNITS,
    RDT_HEADER,
    RDT_RECORD_DTYPE,
    STATUS_ERROR,
    STATUS_SATURATION,
    TORQUE_UNITS,
)
from ._transport_source import _Clock

__all__ = ["SimulatedNetFT"]


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
    n_records : int, optional
        Stop each stream after this many records (as a request's sample count does).
    epoch : float, optional
        ``time.monotonic()`` at simulated time 0 (see :class:`SimulatedPitoPort`); a
        stream started later begins at the current simulated time. Default: each stream
        starts at simulated time 0.
    seed : int, optional
    same_port : bool, optional
        Serve the configuration page (TCP) on the RDT port's number (UDP), so one address
        ``127.0.0.1:PORT`` names the box (``pito sim-devices``). Default False.

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
        n_records: int | None = None,
        epoch: float | None = None,
        seed: int = 0,
        same_port: bool = False,
    ):
        if not rate_hz > 0:
            raise ValueError(f"rate_hz: expected > 0, got {rate_hz!r}")
        self.n_records = n_records
        self.epoch = epoch
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
        self.log = {"sent": [], "lost": [], "saturated": [], "requests": [], "injected": []}
        self._faults = {"drop": 0, "reorder": 0, "saturate": 0, "garbage": 0}
        self._hold_until = 0.0
        self._rate_factor = 1.0
        self._held_packet = None
        self._bias = np.zeros(6)
        self._last_wrench = np.zeros(6)
        self._lock = threading.Lock()
        self._stream_stop = threading.Event()
        self.finished = threading.Event()  # set when a stream reached its record count
        self._stop = threading.Event()
        self._stream_thread = None
        self._udp, self._http = self._bind(bool(same_port))
        self._udp.settimeout(0.1)
        self.port = self._udp.getsockname()[1]
        self._http.daemon_threads = True
        self.http_port = self._http.server_address[1]
        self._threads = [
            threading.Thread(target=self._serve_udp, name="SimulatedNetFT-udp", daemon=True),
            threading.Thread(target=self._http.serve_forever, kwargs={"poll_interval": 0.05},
                             name="SimulatedNetFT-http", daemon=True),
        ]
        for th in self._threads:
            th.start()

    # ------------------------------------------------------------------ fault injection
    def inject(self, fault: str, n: int = 1, *, seconds: float = 0.0, factor: float = 1.0) -> None:
        """Inject a fault into the stream (SIMULATED; for tests and demos).

        ``"stall"``: send nothing for ``seconds`` s (the records are delayed, not lost);
        ``"drop"``: the next ``n`` packets are not sent; ``"reorder"``: the next ``n`` packets
        are each sent after the one that follows; ``"saturate"``: the next ``n`` records carry
        the saturation status; ``"garbage"``: ``n`` packets of a wrong size are sent;
        ``"rate"``: send at ``factor`` × the configured rate from now on (the configuration page
        still says the configured rate: a rate mismatch).
        """
        self.log["injected"].append((fault, n, seconds, factor))
        if fault == "stall":
            self._hold_until = time.monotonic() + float(seconds)
        elif fault == "rate":
            if not factor > 0:
                raise ValueError(f"factor: expected > 0, got {factor!r}")
            self._rate_factor = float(factor)
        elif fault in self._faults:
            self._faults[fault] += int(n)
        else:
            raise ValueError(f"fault: expected one of stall, drop, reorder, saturate, garbage, rate; got {fault!r}")

    def _take_fault(self, name: str, k: int = 1) -> int:
        with self._lock:
            got = min(k, self._faults[name])
            self._faults[name] -= got
            return got

    def _bind(self, same_port: bool):
        """``(udp socket, http server)`` on ephemeral ports of 127.0.0.1; one number for both if ``same_port``."""
        for _ in range(50):
            udp = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            udp.bind((self.host, 0))
            try:
                http = ThreadingHTTPServer((self.host, udp.getsockname()[1] if same_port else 0), self._handler())
            except OSError:  # that TCP port is taken: try another UDP port
                udp.close()
                continue
            return udp, http
        raise OSError("SimulatedNetFT: found no free port number for both UDP and TCP on 127.0.0.1")

    def config_xml(self) -> bytes:
        rate = f"<comrdtrate>{self.rate_hz * self.speed:g}</comrdtrate>" if np.isfinite(self.speed) else ""
        return (
            '<?xml version="1.0" encoding="UTF-8"?>\n<netft>'
            f"<cfgcpf>{self.cpf:g}</cfgcpf><cfgcpt>{self.cpt:g}</cfgcpt>"
            f"<scfgfu>{self.force_unit}</scfgfu><scfgtu>{self.torque_unit}</scfgtu>"
            f"<comrdte>Enabled</comrdte>{rate}<setserial>SIM-0001</setserial></netft>"
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
        clock = _Clock(self.speed, self.epoch)
        k_sim = 0 if self.epoch is None else int(np.ceil(clock.now() * self.rate_hz))  # sample of record 0
        clock.t0 += k_sim / (self.rate_hz * clock.speed) if not np.isinf(clock.speed) else 0.0
        dt = 1.0 / self.rate_hz
        scale = np.array([self.cpf] * 3 + [self.cpt] * 3)  # counts per force or torque unit
        si = np.array([FORCE_UNITS[self.force_unit]] * 3 + [TORQUE_UNITS[self.torque_unit]] * 3)  # N or N·m per unit
        rate_shift = 0.0  # keeps the schedule continuous when the injected rate factor changes
        factor = self._rate_factor
        k = 0  # records sent in this stream; rdt_sequence restarts at 1 per stream
        if self.n_records is not None:
            count = self.n_records if not count else min(count, self.n_records)
        block = max(per_packet, int(self.rate_hz * 0.1))  # the source is asked 0.1 s at a time
        while not stop.is_set() and not self._stop.is_set():
            nb = block if not count else min(block, count - k)
            if nb <= 0:
                break
            t_block = np.arange(k, k + nb) * dt
            wrench_block = np.asarray(self.source.reference_at(t_block + k_sim * dt), dtype=float)
            for i in range(0, nb, per_packet):
                idx = np.arange(k, k + min(per_packet, nb - i))
                n = idx.size
                if self._rate_factor != factor:  # injected rate change: continuous schedule
                    t_now = t_block[i]
                    rate_shift += t_now / factor - t_now / self._rate_factor
                    factor = self._rate_factor
                if not clock.wait_until(t_block[i + n - 1] / factor + rate_shift, stop):
                    return
                while time.monotonic() < self._hold_until and not stop.is_set():  # injected stall
                    time.sleep(0.002)
                rec, sat = self._records(idx, wrench_block[i : i + n], si, scale)
                if not self._send(rec, sat, addr):
                    return
                k += n
        self.finished.set()

    def _records(self, idx, wrench, si, scale):
        """RDT records ``idx`` (0-based) carrying ``wrench (n, 6)`` (N, N·m, less the bias) in counts,
        and which of them are flagged saturated (drawn, injected, or over the rated load); ``si`` (6,) N or
        N·m per unit, ``scale`` (6,) counts per unit."""
        n = idx.size
        with self._lock:
            self._last_wrench = wrench[-1]
            w = wrench - self._bias
        rec = np.zeros(n, dtype=RDT_RECORD_DTYPE)
        rec["rdt_seq"] = (idx + 1) % 2**32
        rec["ft_seq"] = (idx * 7 + 1) % 2**32  # the box samples faster than it sends
        rec["counts"] = np.clip(np.rint(w / si * scale), -(2**31), 2**31 - 1).astype(np.int64)
        sat = self._rng.random(n) < self.saturation_rate
        forced = self._take_fault("saturate", n)
        if forced:
            sat[:forced] = True
        if self.rated_load is not None:
            sat |= (np.abs(wrench) > self.rated_load).any(axis=1)
        rec["status"] = np.where(sat, STATUS_SATURATION | STATUS_ERROR, 0)
        return rec, sat

    def _send(self, rec, sat, addr) -> bool:
        """Send one packet of records ``rec`` to ``addr`` with the injected faults (garbage, loss, reordering),
        logging what was sent or lost; False if the socket is closed."""
        seqs = rec["rdt_seq"].astype(np.int64).tolist()
        if self._take_fault("garbage"):
            try:
                self._udp.sendto(b"\x00" * (RDT_RECORD_DTYPE.itemsize - 5), addr)
            except OSError:
                return False
        if self._rng.random() < self.loss_rate or self._take_fault("drop"):
            self.log["lost"].extend(seqs)
            return True
        try:
            if self._held_packet is not None:  # reorder: this one first, the held one after
                self._udp.sendto(rec.tobytes(), addr)
                self._udp.sendto(self._held_packet, addr)
                self._held_packet = None
            elif self._take_fault("reorder"):
                self._held_packet = rec.tobytes()
            else:
                self._udp.sendto(rec.tobytes(), addr)
        except OSError:
            return False
        self.log["sent"].extend(seqs)
        self.log["saturated"].extend(np.asarray(seqs)[sat].tolist())
        return True

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

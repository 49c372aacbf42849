"""ATI Net F/T over its Raw Data Transfer (RDT) UDP protocol.

Request (8 bytes, big-endian): ``u16 header = 0x1234``, ``u16 command``, ``u32 sample count``
(0 = stream until stopped). Commands: 0x0000 stop, 0x0002 start real-time streaming
(one record per packet), 0x0003 start buffered streaming (several records per packet),
0x0042 set software bias.

Record (36 bytes, big-endian): ``u32 rdt_sequence``, ``u32 ft_sequence``, ``u32 status``,
``6 × i32`` Fx, Fy, Fz, Tx, Ty, Tz in counts. Force = counts / counts-per-force in the box's
force unit, torque = counts / counts-per-torque in its torque unit; both factors and units
are read from the box's configuration page ``/netftapi2.xml`` (``cfgcpf``, ``cfgcpt``,
``scfgfu``, ``scfgtu``) unless given.
"""

from __future__ import annotations

import socket
import struct
import threading
import time
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from urllib.request import urlopen

import numpy as np

from ._serial import STALL_AFTER, DeviceError, SequenceTracker, StallMonitor
from ._queue import BatchQueue

__all__ = [
    "NetFT",
    "NetFTBatch",
    "NetFTConfig",
    "read_netft_config",
    "decode_status",
    "RDT_PORT",
    "RDT_HEADER",
    "CMD_BIAS",
    "CMD_START_BUFFERED",
    "CMD_START_REALTIME",
    "CMD_STOP",
    "RDT_RECORD_DTYPE",
    "STATUS_ERROR",
    "STATUS_SATURATION",
    "FORCE_UNITS",
    "TORQUE_UNITS",
]

RDT_PORT = 49152
RDT_HEADER = 0x1234
CMD_STOP, CMD_START_REALTIME, CMD_START_BUFFERED, CMD_BIAS = 0x0000, 0x0002, 0x0003, 0x0042
_REQUEST = struct.Struct(">HHI")

#: One RDT record (36 bytes, big-endian).
RDT_RECORD_DTYPE = np.dtype([("rdt_seq", ">u4"), ("ft_seq", ">u4"), ("status", ">u4"), ("counts", ">i4", (6,))])

#: Status bit the box sets whenever it reports any fault (summary bit).
STATUS_ERROR = 0x8000_0000
#: Status bit taken as "transducer saturated" by default. The Net F/T manual's
#: "system status code" table is the authority: check it for your box's firmware and pass
#: ``saturation_mask=`` to :class:`NetFT` if it differs (see docs/devices.md).
STATUS_SATURATION = 0x0002_0000

#: SI value of one unit of force, for the units a Net F/T or a .cal file can report.
FORCE_UNITS = {"N": 1.0, "kN": 1e3, "lbf": 4.4482216152605, "lb": 4.4482216152605, "klbf": 4448.2216152605,
               "klb": 4448.2216152605, "kgf": 9.80665, "kg": 9.80665, "gf": 9.80665e-3, "g": 9.80665e-3}
#: SI value (N·m) of one unit of torque.
TORQUE_UNITS = {"N-m": 1.0, "Nm": 1.0, "N-mm": 1e-3, "Nmm": 1e-3, "kN-m": 1e3, "kNm": 1e3,
                "lbf-in": 0.1129848290276167, "lb-in": 0.1129848290276167, "in-lb": 0.1129848290276167,
                "in-lbf": 0.1129848290276167, "lbf-ft": 1.3558179483314, "lb-ft": 1.3558179483314,
                "ft-lb": 1.3558179483314, "ft-lbf": 1.3558179483314, "kgf-cm": 0.0980665, "kg-cm": 0.0980665}


def decode_status(status, saturation_mask: int = STATUS_SATURATION) -> dict:
    """Decode RDT status words.

    Parameters
    ----------
    status : int or array-like of int, shape (n,)

    Returns
    -------
    dict
        ``ok`` (status == 0), ``error`` (summary bit 31), ``saturated`` (any bit of
        ``saturation_mask``), ``bits`` (list of set bit numbers, for a scalar input).
    """
    s = np.asarray(status, dtype=np.uint64)
    out = {
        "ok": s == 0,
        "error": (s & STATUS_ERROR) != 0,
        "saturated": (s & np.uint64(saturation_mask)) != 0,
    }
    if s.ndim == 0:
        out = {k: bool(v) for k, v in out.items()}
        out["bits"] = [b for b in range(32) if int(s) >> b & 1]
    return out


@dataclass(frozen=True)
class NetFTConfig:
    """Scaling of a Net F/T: counts per force and torque unit, and those units.

    Attributes
    ----------
    counts_per_force, counts_per_torque : float
        As configured on the box (counts per ``force_unit`` / ``torque_unit``).
    force_unit, torque_unit : str
        e.g. ``"N"``, ``"N-m"`` (keys of :data:`FORCE_UNITS` / :data:`TORQUE_UNITS`).
    rdt_rate_hz : float or None
        The RDT output rate the box is configured for (``comrdtrate``, Hz), if it says.
    """

    counts_per_force: float
    counts_per_torque: float
    force_unit: str = "N"
    torque_unit: str = "N-m"
    rdt_rate_hz: float | None = field(default=None, compare=False)

    def scale(self) -> np.ndarray:
        """``(6,)`` factors from counts to N and N·m."""
        if self.force_unit not in FORCE_UNITS:
            raise ValueError(f"force_unit: unknown unit {self.force_unit!r} (known: {sorted(FORCE_UNITS)})")
        if self.torque_unit not in TORQUE_UNITS:
            raise ValueError(f"torque_unit: unknown unit {self.torque_unit!r} (known: {sorted(TORQUE_UNITS)})")
        f = FORCE_UNITS[self.force_unit] / self.counts_per_force
        t = TORQUE_UNITS[self.torque_unit] / self.counts_per_torque
        return np.array([f, f, f, t, t, t])


def read_netft_config(host: str, http_port: int = 80, timeout: float = 2.0) -> NetFTConfig:
    """Read counts per force/torque and units from ``http://host:http_port/netftapi2.xml``.

    Raises
    ------
    DeviceError
        If the page cannot be fetched or lacks ``cfgcpf``, ``cfgcpt``, ``scfgfu`` or ``scfgtu``.
    """
    url = f"http://{host}:{int(http_port)}/netftapi2.xml"
    try:
        with urlopen(url, timeout=timeout) as resp:
            text = resp.read()
        root = ET.fromstring(text)
    except Exception as exc:
        raise DeviceError(f"host: cannot read the Net F/T configuration at {url}: {exc}") from None
    values = {el.tag.rsplit("}", 1)[-1].lower(): (el.text or "").strip() for el in root.iter()}
    missing = [k for k in ("cfgcpf", "cfgcpt", "scfgfu", "scfgtu") if not values.get(k)]
    if missing:
        raise DeviceError(f"host: {url} lacks {missing}; pass counts_per_force and counts_per_torque explicitly")
    try:
        rate = float(values["comrdtrate"]) if values.get("comrdtrate") else None
        cfg = NetFTConfig(float(values["cfgcpf"]), float(values["cfgcpt"]), values["scfgfu"], values["scfgtu"], rate)
        if not (np.isfinite(cfg.counts_per_force) and np.isfinite(cfg.counts_per_torque)
                and cfg.counts_per_force > 0 and cfg.counts_per_torque > 0):
            raise ValueError(f"counts per unit must be finite and positive (cfgcpf={values['cfgcpf']}, cfgcpt={values['cfgcpt']})")
        if rate is not None and not (np.isfinite(rate) and rate > 0):
            raise ValueError(f"comrdtrate: RDT output rate must be a positive number of Hz, got {values['comrdtrate']!r}")
        cfg.scale()
    except ValueError as exc:
        raise DeviceError(f"host: unusable Net F/T configuration at {url}: {exc}") from None
    return cfg


@dataclass(frozen=True)
class NetFTBatch:
    """Consecutive RDT records.

    Attributes
    ----------
    rdt_seq : ndarray of uint32, shape (n,)
        RDT sequence number (one per record sent).
    ft_seq : ndarray of uint32, shape (n,)
        The box's internal sample counter.
    status : ndarray of uint32, shape (n,)
        Status word (0 = healthy), see :func:`decode_status`.
    wrench : ndarray of float64, shape (n, 6)
        ``[fx, fy, fz, tx, ty, tz]`` in N and N·m, sensor frame, as the box reports it
        (including the box's own bias if one was set).
    host_time : ndarray of float64, shape (n,)
        Host clock (``time.monotonic()``, s) when the packet arrived.
    saturated : ndarray of bool, shape (n,)
        Status flags transducer saturation.
    """

    rdt_seq: np.ndarray
    ft_seq: np.ndarray
    status: np.ndarray
    wrench: np.ndarray
    host_time: np.ndarray
    saturated: np.ndarray

    def __len__(self) -> int:
        return int(self.rdt_seq.shape[0])

    @staticmethod
    def concatenate(batches) -> "NetFTBatch":
        batches = list(batches)
        if not batches:
            z = np.zeros(0, np.uint32)
            return NetFTBatch(z, z, z, np.zeros((0, 6)), np.zeros(0), np.zeros(0, bool))
        fields = ("rdt_seq", "ft_seq", "status", "wrench", "host_time", "saturated")
        return NetFTBatch(*(np.concatenate([getattr(b, f) for b in batches]) for f in fields))


class NetFT:
    """ATI Net F/T client (RDT over UDP) with a receiver thread.

    Parameters
    ----------
    host : str
        The box's address.
    port : int, optional
        RDT UDP port, default 49152.
    counts_per_force, counts_per_torque : float, optional
        Counts per N and per N·m. Give both or neither; when omitted they are read,
        with their units, from the box's configuration page (never assumed).
    http_port : int, optional
        Port of the configuration page, default 80.
    buffered : bool, optional
        Use buffered streaming (several records per packet, fewer packets); default False.
    saturation_mask : int, optional
        Status bits meaning "saturated", default :data:`STATUS_SATURATION`.
    restart_after : float, optional
        Re-send the start request when no packet came for this many seconds (the box
        was power-cycled or the request was lost), default 1.0.
    max_pending : int, optional
        Records kept for :meth:`read` if nobody reads; older ones are counted as ``overflow``.
    stall_after : float, optional
        Seconds without a record after which :meth:`stats` says ``stalled`` (default 0.1 s;
        flagged within 0.12 s).
    rate_tolerance : float, optional
        Relative difference between the received record rate and the box's configured RDT
        rate (``comrdtrate``) above which ``rate_mismatch`` is set, default 0.05. The host
        lag (``lag_ms``: how far arrivals trail the box's clock, from the sequence numbers
        and the configured rate) growing above ``max_lag`` s also sets it — the reader
        cannot keep up (the well-known lag at a 7 kHz output rate).
    max_lag : float, optional
        Default 0.25 s.
    """

    def __init__(
        self,
        host: str,
        port: int = RDT_PORT,
        counts_per_force: float | None = None,
        counts_per_torque: float | None = None,
        *,
        http_port: int = 80,
        buffered: bool = False,
        saturation_mask: int = STATUS_SATURATION,
        restart_after: float = 1.0,
        max_pending: int = 600_000,
        stall_after: float = STALL_AFTER,
        rate_tolerance: float = 0.05,
        max_lag: float = 0.25,
    ):
        if not isinstance(host, str) or not host:
            raise ValueError(f"host: expected a host name or address, got {host!r}")
        if not 0 < int(port) < 65536:
            raise ValueError(f"port: expected 1..65535, got {port!r}")
        if (counts_per_force is None) != (counts_per_torque is None):
            raise ValueError("counts_per_force, counts_per_torque: give both or neither")
        self.config: NetFTConfig | None = None
        if counts_per_force is not None:
            if not (counts_per_force > 0 and counts_per_torque > 0):
                raise ValueError("counts_per_force, counts_per_torque: expected positive numbers")
            self.config = NetFTConfig(float(counts_per_force), float(counts_per_torque), "N", "N-m")
        self.host = host
        self.port = int(port)
        self.http_port = int(http_port)
        self.buffered = bool(buffered)
        self.saturation_mask = int(saturation_mask)
        self.restart_after = float(restart_after)
        self.max_pending = int(max_pending)
        self._sock: socket.socket | None = None
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._queue = BatchQueue(self.max_pending, NetFTBatch.concatenate)
        self._seq = SequenceTracker()
        self._counts = dict(records=0, packets=0, saturated=0, status_errors=0, bad_packets=0, restarts=0, overflow=0)
        self._last_status = 0
        self._scale = None
        self._stall = StallMonitor(stall_after)
        self.rate_tolerance = float(rate_tolerance)
        self.max_lag = float(max_lag)
        self._rate = {"t0": None, "seq0": 0, "n": 0, "t_last": None, "lag": 0.0, "lag_min": None}
        self._undo = np.zeros(6)  # N, N·m added back after an undone box bias
        #: Every bias: ``{"event": "bias"|"undo_bias", "host_time" (s, monotonic), "unix_time",
        #: "wrench" [6] N, N·m (the output just before), "status"}``; a bias also has "box_output"
        #: [6] (the box's output it zeroed, the step :meth:`undo_bias` adds back) and "settled": both values
        #: are set in place once its step is in (no key is added later: the history can be serialised at any time).
        self.bias_history: list[dict] = []
        self._last_wrench = np.zeros(6)
        self._bias_lock = threading.Lock()
        self._pending_bias: dict | None = None
        self._prev_counts: np.ndarray | None = None

    #: s of the box's records after a bias command is sent that are searched for its step.
    BIAS_WINDOW_S = 0.25

    # ------------------------------------------------------------------ lifecycle
    def start(self) -> "NetFT":
        """Read the configuration (if needed), send the start request, start receiving."""
        if self._thread is not None:
            return self
        if self.config is None:
            self.config = read_netft_config(self.host, self.http_port)
        self._scale = self.config.scale()
        self._stall = StallMonitor(self._stall.after)
        try:
            addr = socket.getaddrinfo(self.host, self.port, socket.AF_INET, socket.SOCK_DGRAM)[0][4]
        except OSError as exc:
            raise DeviceError(f"host: cannot resolve {self.host!r}: {exc}") from None
        self._addr = addr
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 8 * 1024 * 1024)
        except OSError:
            pass
        sock.bind(("", 0))
        sock.settimeout(min(0.1, self._stall.after / 5))
        self._sock = sock
        self._send(CMD_START_BUFFERED if self.buffered else CMD_START_REALTIME)
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, name=f"NetFT({self.host})", daemon=True)
        self._thread.start()
        return self

    def _send(self, command: int, count: int = 0) -> None:
        try:
            self._sock.sendto(_REQUEST.pack(RDT_HEADER, command, count), self._addr)
        except OSError as exc:
            raise DeviceError(f"host: cannot send to {self._addr}: {exc}") from None

    def bias(self) -> dict:
        """Ask the box to bias (zero) its output at the current load (RDT command 0x42).

        Recorded in :attr:`bias_history` with the time and the output just before (N, N·m);
        :meth:`undo_bias` adds that output back. The box biases at the record it sends when the
        command arrives, which a client lagging behind the stream has not received yet: the entry's
        ``wrench`` is first the last record received, then, once the records up to the command's
        arrival plus :attr:`BIAS_WINDOW_S` are in, the record just before the output's step (the
        largest jump in counts among them); ``box_output`` is that record less the undone biases
        (what the box had zeroed). Returns the history entry.
        """
        if self._sock is None:
            raise DeviceError("NetFT: not started")
        ev = {"event": "bias", "host_time": time.monotonic(), "unix_time": time.time(),
              "wrench": [float(v) for v in self._last_wrench], "status": self._last_status,
              "box_output": [float(v) for v in self._last_wrench - self._undo], "settled": False}  # keys fixed
        # without a configured rate, the rate received (from the sequence numbers), else 1 kHz
        rate = (self.config.rdt_rate_hz if self.config is not None else None) or self._received_rate()[0] or 1000.0
        with self._bias_lock:
            if self._pending_bias is not None:
                self._settle_bias()
            self._pending_bias = {"ev": ev, "jump": 0.0, "box": self._last_wrench - self._undo,
                                  "left": int(np.ceil((self._rate["lag"] + self.BIAS_WINDOW_S) * rate))}
            self.bias_history.append(ev)
        try:  # sent once its step is searched for: the box may answer before this thread runs again
            self._send(CMD_BIAS)
        except DeviceError:
            with self._bias_lock:
                if self._pending_bias is not None and self._pending_bias["ev"] is ev:
                    self._pending_bias = None
                self.bias_history.remove(ev)
            raise
        return ev

    def undo_bias(self) -> dict:
        """Undo the last :meth:`bias` not yet undone: the box's output just before it is added back to
        every later record (waits up to 2 s for the records that hold the bias's step)."""
        done = [e for e in self.bias_history if e["event"] == "bias" and not e.get("undone")]
        if not done:
            raise DeviceError("NetFT: no bias to undo")
        last = done[-1]
        deadline = time.monotonic() + 2.0
        while time.monotonic() < deadline:
            p = self._pending_bias  # read once: the receiver thread may settle it at any time
            if p is None or p["ev"] is not last:
                break
            time.sleep(0.005)
        with self._bias_lock:
            if self._pending_bias is not None and self._pending_bias["ev"] is last:
                self._settle_bias()
            last["undone"] = True
            self._undo = self._undo + np.asarray(last["box_output"])
            ev = {"event": "undo_bias", "host_time": time.monotonic(), "unix_time": time.time(),
                  "wrench": list(last["wrench"]), "of": last["host_time"]}
            self.bias_history.append(ev)
        return ev

    def _settle_bias(self) -> None:
        """Fix the pending bias's entry at the step found so far (under ``_bias_lock``)."""
        p, self._pending_bias = self._pending_bias, None
        p["ev"]["wrench"] = [float(v) for v in p["box"] + self._undo]
        p["ev"]["box_output"] = [float(v) for v in p["box"]]
        p["ev"]["settled"] = True

    def _find_bias_step(self, counts: np.ndarray) -> None:
        """Track the largest jump in a packet's ``counts (n, 6)`` while a bias is pending (receiver thread)."""
        with self._bias_lock:
            p = self._pending_bias
            if p is None:
                return
            prev = self._prev_counts if self._prev_counts is not None else counts[:1]
            jumps = np.linalg.norm(np.diff(np.vstack([prev, counts]), axis=0), axis=1)
            i = int(np.argmax(jumps))
            if jumps[i] > p["jump"]:  # the box's own output just before the step
                p["jump"], p["box"] = float(jumps[i]), (counts[i - 1] if i > 0 else prev[0]) * self._scale
            p["left"] -= len(counts)  # records received since the bias (a restart starts the sequence anew)
            r, rate = self._rate, (self.config.rdt_rate_hz if self.config is not None else None)
            if rate and r["lag_min"] is not None:  # the last record's send time at the box, on the host clock
                done = r["t0"] + r["n"] / rate + r["lag_min"] >= p["ev"]["host_time"] + self.BIAS_WINDOW_S
            else:
                done = p["left"] <= 0
            if done:
                self._settle_bias()

    def close(self) -> None:
        """Send the stop request, stop the thread, close the socket (idempotent)."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
            self._thread = None
        with self._bias_lock:  # no more records: a pending bias keeps the step found so far
            if self._pending_bias is not None:
                self._settle_bias()
        if self._sock is not None:
            try:
                self._send(CMD_STOP)
            except DeviceError:
                pass
            self._sock.close()
            self._sock = None
        self._queue.wake()

    def __enter__(self) -> "NetFT":
        return self.start()

    def __exit__(self, *exc) -> None:
        self.close()

    # ------------------------------------------------------------------ receiver
    def _run(self) -> None:
        sock = self._sock
        last_rx = time.monotonic()
        size = RDT_RECORD_DTYPE.itemsize
        while not self._stop.is_set():
            try:
                data = sock.recv(65536)
            except socket.timeout:
                self._stall.poll(time.monotonic())
                if time.monotonic() - last_rx > self.restart_after:
                    try:
                        self._send(CMD_START_BUFFERED if self.buffered else CMD_START_REALTIME)
                        self._counts["restarts"] += 1
                    except DeviceError:
                        pass
                    last_rx = time.monotonic()
                continue
            except OSError:
                break
            now = time.monotonic()
            last_rx = now
            if not data or len(data) % size:
                self._counts["bad_packets"] += 1
                self._stall.poll(now)
                continue
            self._stall.data(now)
            rec = np.frombuffer(data, dtype=RDT_RECORD_DTYPE)
            batch = self._batch(rec, now)
            dropped = self._queue.put(batch)
            if dropped:
                self._counts["overflow"] += dropped

    def _batch(self, rec: np.ndarray, now: float) -> NetFTBatch:
        status = rec["status"].astype(np.uint32)
        saturated = (status & np.uint32(self.saturation_mask)) != 0
        c = self._counts
        c["packets"] += 1
        c["records"] += rec.size
        c["saturated"] += int(saturated.sum())
        c["status_errors"] += int((status != 0).sum())
        self._last_status = int(status[-1])
        rdt_seq = rec["rdt_seq"].astype(np.uint32)
        restarts = self._seq.restarts
        self._seq.update(rdt_seq)
        self._track_rate(int(self._seq.last), now, self._seq.restarts != restarts)
        counts = rec["counts"].astype(np.float64)
        wrench = counts * self._scale + self._undo
        self._find_bias_step(counts)
        self._prev_counts = counts[-1:]
        self._last_wrench = wrench[-1]
        return NetFTBatch(rdt_seq, rec["ft_seq"].astype(np.uint32), status, wrench, np.full(rec.size, now), saturated)

    def _received_rate(self) -> tuple[float | None, float]:
        """``(records/s received, from the sequence numbers, or None before 0.5 s of them; that span in s)``."""
        r = self._rate
        span = (r["t_last"] - r["t0"]) if r["t0"] is not None else 0.0
        return (r["n"] / span if span >= 0.5 else None), span

    def _track_rate(self, seq: int, now: float, restarted: bool) -> None:
        """Received rate (records/s) and host lag behind the box's clock (s), from the sequence numbers."""
        r = self._rate
        if r["t0"] is None or restarted:
            r.update(t0=now, seq0=seq, n=0, lag=0.0, lag_min=None)
        r["n"] = (seq - r["seq0"]) % 2**32
        r["t_last"] = now
        rate = self.config.rdt_rate_hz if self.config is not None else None
        if rate and r["n"]:
            lag = (now - r["t0"]) - r["n"] / rate  # arrival time minus the box's own time for that record
            r["lag_min"] = lag if r["lag_min"] is None else min(r["lag_min"], lag)
            r["lag"] = lag - r["lag_min"]

    # ------------------------------------------------------------------ consumer API
    def read(self, timeout: float | None = None) -> NetFTBatch | None:
        """All records received since the last call, or None if none came within ``timeout`` s."""
        return self._queue.get(timeout, self._stop)

    def stats(self) -> dict:
        """Counters since :meth:`start`.

        Keys: ``records``, ``packets``, ``lost`` (records missing from the RDT sequence),
        ``saturated`` (records whose status flags saturation), ``status_errors`` (records
        with a non-zero status), ``bad_packets`` (wrong size), ``restarts`` (start request
        re-sent after silence), ``seq_restarts``, ``overflow``, ``last_status``,
        ``out_of_order`` (late records), ``stalled`` / ``stalls`` / ``stalled_s`` /
        ``since_data_s`` (no record for more than ``stall_after`` s), ``configured_rate_hz``
        (the box's ``comrdtrate``, None if it does not say), ``rate_hz`` (records/s received,
        from the sequence numbers), ``lag_ms`` (how much later than the box's clock records
        now arrive than they did at best), ``rate_mismatch`` (bool), ``counts_per_force``,
        ``counts_per_torque``, ``force_unit``, ``torque_unit``, ``biases`` (len of :attr:`bias_history`).
        """
        out = dict(self._counts)
        out["lost"] = self._seq.dropped
        out["seq_restarts"] = self._seq.restarts
        out["out_of_order"] = self._seq.out_of_order
        out["last_status"] = self._last_status
        out.update(self._stall.stats())
        r = self._rate
        cfg = self.config
        configured = cfg.rdt_rate_hz if cfg is not None else None
        out["rate_hz"], span = self._received_rate()
        out["configured_rate_hz"] = configured
        out["lag_ms"] = 1e3 * r["lag"] if configured else None
        mismatch = False
        if configured and out["rate_hz"] is not None and span >= 1.0:
            mismatch = abs(out["rate_hz"] - configured) > self.rate_tolerance * configured
        if out["lag_ms"] is not None and r["lag"] > self.max_lag:
            mismatch = True
        out["rate_mismatch"] = mismatch
        if cfg is not None:
            out.update(counts_per_force=cfg.counts_per_force, counts_per_torque=cfg.counts_per_torque,
                       force_unit=cfg.force_unit, torque_unit=cfg.torque_unit)
        out["biases"] = len(self.bias_history)
        return out

    def __repr__(self) -> str:
        return f"NetFT({self.host!r}, port={self.port})"

"""Recordings: an append-only, crash-safe chunk file of both device streams.

Format ``pito-recording``, version 1 (docs/devices.md). All integers little-endian::

    file   = header chunk*
    header = b"PITOREC\\0" | u16 version | u16 flags (0) | u32 n | n bytes JSON meta | u32 crc32(JSON)
    chunk  = b"CHNK" | u8 kind | u8 0 | u16 0 | u32 rows | u32 n | u32 crc32(bytes 0..15 + payload) | n bytes payload

Chunk kinds: 1 cube rows (:data:`PITO_ROW`, 160 bytes each), 2 Net F/T rows
(:data:`NETFT_ROW`, 68 bytes each), 3 an event (JSON object), 255 the end marker (JSON
summary) that a cleanly closed file ends with.

The writer buffers rows and appends them as one chunk at least every ``flush_interval``
seconds (default 0.5 s), flushed to the operating system (and fsync'ed) each time: a
killed recorder loses at most the rows of the last interval, and every chunk before is
intact and checked by its CRC. A file without the end marker is *incomplete*; reading it
raises :class:`FileFormatError` unless ``recover=True``, which returns every intact chunk.
"""

from __future__ import annotations

import json
import os
import struct
import threading
import time
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .._version import __version__
from ..frames import N_GAUGES
from ._hdf5 import ChecksumError, FileFormatError, json_attr

__all__ = [
    "RECORDING_FORMAT",
    "RECORDING_VERSION",
    "PITO_ROW",
    "NETFT_ROW",
    "RecordingWriter",
    "Recording",
    "ReplayBatch",
    "read_recording",
    "RecordingChunks",
]

RECORDING_FORMAT = "pito-recording"
RECORDING_VERSION = 1
_MAGIC = b"PITOREC\x00"
_CHUNK_MAGIC = b"CHNK"
_HEAD = struct.Struct("<8sHHI")
_CHUNK = struct.Struct("<4sBBHIII")  # magic, kind, 0, 0, rows, payload length, crc
KIND_PITO, KIND_NETFT, KIND_EVENT, KIND_END = 1, 2, 3, 255

#: One cube sample: sequence, device time (µs), host time (s, monotonic clock), 36 counts.
PITO_ROW = np.dtype([("seq", "<u4"), ("time_us", "<u4"), ("host_time", "<f8"), ("counts", "<i4", (N_GAUGES,))])
#: One Net F/T record: RDT sequence, F/T sequence, status, host time (s), wrench (N, N·m).
NETFT_ROW = np.dtype(
    [("rdt_seq", "<u4"), ("ft_seq", "<u4"), ("status", "<u4"), ("host_time", "<f8"), ("wrench", "<f8", (6,))]
)
_ROWS = {KIND_PITO: PITO_ROW, KIND_NETFT: NETFT_ROW}


def _json_bytes(obj) -> bytes:
    return json_attr(obj).encode("utf-8")


class RecordingWriter:
    """Append both streams to a recording file, crash-safely.

    Parameters
    ----------
    path : str or Path
        Exactly the file written (overwritten if present).
    meta : dict, optional
        JSON-serialisable metadata stored in the header (devices, units, ``simulated``, ...).
    flush_interval : float, optional
        Maximum seconds between chunk writes, default 0.5 (a crash loses at most this).
    fsync : bool, optional
        fsync after each chunk (survives power loss, not only a killed process). Default True.
    """

    def __init__(self, path, meta: dict | None = None, *, flush_interval: float = 0.5, fsync: bool = True):
        if not 0 < flush_interval <= 1.0:
            raise ValueError(f"flush_interval: expected 0 < s <= 1, got {flush_interval!r}")
        self.path = Path(os.fspath(path))
        self.flush_interval = float(flush_interval)
        self.fsync = bool(fsync)
        meta = dict(meta or {})
        meta.setdefault("created_unix", time.time())
        meta.setdefault("writer", f"pito {__version__}")
        self.meta = meta
        head = _json_bytes(meta)
        self._fh = open(self.path, "wb")
        self._fh.write(_HEAD.pack(_MAGIC, RECORDING_VERSION, 0, len(head)) + head + struct.pack("<I", zlib.crc32(head)))
        self._sync()
        self._lock = threading.Lock()
        self._buf = {KIND_PITO: [], KIND_NETFT: []}
        self._events: list[bytes] = []
        self._rows = {KIND_PITO: 0, KIND_NETFT: 0}
        self._last_flush = time.monotonic()
        self.closed = False

    def _sync(self) -> None:
        self._fh.flush()
        if self.fsync:
            os.fsync(self._fh.fileno())

    @staticmethod
    def _chunk(kind: int, rows: int, payload: bytes) -> bytes:
        head = _CHUNK.pack(_CHUNK_MAGIC, kind, 0, 0, rows, len(payload), 0)[:16]
        crc = zlib.crc32(payload, zlib.crc32(head))
        return head + struct.pack("<I", crc) + payload

    # ------------------------------------------------------------------ appending
    def append_pito(self, seq, time_us, host_time, counts) -> None:
        """Append cube samples: ``seq (n,)``, ``time_us (n,)``, ``host_time (n,)`` s, ``counts (n, 36)``."""
        counts = np.asarray(counts)
        n = counts.shape[0] if counts.ndim == 2 else -1
        if counts.ndim != 2 or counts.shape[1] != N_GAUGES:
            raise ValueError(f"counts: expected shape (n, {N_GAUGES}), got {counts.shape}")
        rows = np.zeros(n, dtype=PITO_ROW)
        rows["seq"], rows["time_us"], rows["host_time"], rows["counts"] = seq, time_us, host_time, counts
        self._append(KIND_PITO, rows)

    def append_netft(self, rdt_seq, ft_seq, status, host_time, wrench) -> None:
        """Append Net F/T records: sequences and status ``(n,)``, ``host_time (n,)`` s, ``wrench (n, 6)`` N, N·m."""
        wrench = np.asarray(wrench, dtype=float)
        if wrench.ndim != 2 or wrench.shape[1] != 6:
            raise ValueError(f"wrench: expected shape (n, 6), got {wrench.shape}")
        rows = np.zeros(wrench.shape[0], dtype=NETFT_ROW)
        rows["rdt_seq"], rows["ft_seq"], rows["status"] = rdt_seq, ft_seq, status
        rows["host_time"], rows["wrench"] = host_time, wrench
        self._append(KIND_NETFT, rows)

    def append_event(self, event: dict) -> None:
        """Append an event (JSON object, e.g. a tare or a marker); a ``host_time`` key is added if absent."""
        event = dict(event)
        event.setdefault("host_time", time.monotonic())
        with self._lock:
            self._events.append(_json_bytes(event))
        self.maybe_flush()

    def _append(self, kind: int, rows: np.ndarray) -> None:
        if rows.size:
            with self._lock:
                if self.closed:
                    raise ValueError(f"{self.path}: recording is closed")
                self._buf[kind].append(rows)
        self.maybe_flush()

    def maybe_flush(self) -> None:
        """Write the buffered rows if ``flush_interval`` has passed since the last write."""
        if time.monotonic() - self._last_flush >= self.flush_interval:
            self.flush()

    def flush(self) -> None:
        """Write every buffered row and event as chunks and flush them to disk."""
        with self._lock:
            if self.closed:
                return
            out = bytearray()
            for kind in (KIND_PITO, KIND_NETFT):
                if self._buf[kind]:
                    rows = np.concatenate(self._buf[kind])
                    self._buf[kind] = []
                    out += self._chunk(kind, rows.size, rows.tobytes())
                    self._rows[kind] += rows.size
            for ev in self._events:
                out += self._chunk(KIND_EVENT, 1, ev)
            self._events = []
            if out:
                self._fh.write(out)
                self._sync()
            self._last_flush = time.monotonic()

    def close(self) -> None:
        """Flush, write the end marker and close (idempotent)."""
        if self.closed:
            return
        self.flush()
        with self._lock:
            summary = {"pito_rows": self._rows[KIND_PITO], "netft_rows": self._rows[KIND_NETFT], "closed_unix": time.time()}
            self._fh.write(self._chunk(KIND_END, 0, _json_bytes(summary)))
            self._sync()
            self._fh.close()
            self.closed = True

    def __enter__(self) -> "RecordingWriter":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    @property
    def rows_written(self) -> dict:
        """Rows written to disk so far: ``{"pito": n, "netft": m}``."""
        return {"pito": self._rows[KIND_PITO], "netft": self._rows[KIND_NETFT]}


@dataclass(frozen=True)
class ReplayBatch:
    """A slice of a recording during :meth:`Recording.replay`.

    Attributes
    ----------
    t : float
        Recording time at the end of the slice, s since the first sample.
    pito : ndarray of :data:`PITO_ROW`, shape (n,)
    netft : ndarray of :data:`NETFT_ROW`, shape (m,)
    """

    t: float
    pito: np.ndarray
    netft: np.ndarray


def _read_header(p, data: bytes) -> tuple[dict, int, int]:
    """The header of recording ``data`` (file ``p``): its metadata, version and the byte where the chunks start."""
    if len(data) < _HEAD.size or data[:8] != _MAGIC:
        raise FileFormatError(f"{p}: not a '{RECORDING_FORMAT}' file (bad magic bytes)")
    _, version, flags, n = _HEAD.unpack_from(data, 0)
    if flags != 0:
        raise ChecksumError(p, "header", f"flags field is {flags}, written as 0")
    if version != RECORDING_VERSION:
        raise FileFormatError(f"{p}: '{RECORDING_FORMAT}' version {version} is not supported (this pito reads [1])")
    end = _HEAD.size + n
    if len(data) < end + 4:
        raise FileFormatError(f"{p}: truncated header")
    head = data[_HEAD.size:end]
    if struct.unpack_from("<I", data, end)[0] != zlib.crc32(head):
        raise ChecksumError(p, "header", "CRC-32 of the header metadata does not match")
    return json.loads(head.decode("utf-8")), version, end + 4


@dataclass
class _Chunks:
    """What :func:`_read_chunks` found: row arrays per kind, events, the end marker's summary (or None),
    the first problem (or None), the damaged chunk ``(byte, kind)`` if its CRC failed, and the byte where
    reading stopped."""

    parts: dict
    events: list
    summary: dict | None
    problem: str | None
    crc_bad: tuple | None
    end: int


def _read_chunks(data: bytes, pos: int) -> _Chunks:
    """The chunks of recording ``data`` from byte ``pos``, up to the end marker or the first damage."""
    parts = {KIND_PITO: [], KIND_NETFT: []}
    events, summary, problem, crc_bad = [], None, None, None
    while pos < len(data):
        if len(data) - pos < _CHUNK.size:
            problem = f"truncated chunk header at byte {pos}"
            break
        magic, kind, _, _, rows, size, crc = _CHUNK.unpack_from(data, pos)
        body = pos + _CHUNK.size
        if magic != _CHUNK_MAGIC:
            problem = f"bad chunk magic at byte {pos}"
            break
        if body + size > len(data):
            problem = f"truncated chunk at byte {pos}"
            break
        payload = data[body : body + size]
        if zlib.crc32(payload, zlib.crc32(data[pos : pos + 16])) != crc:
            problem = f"chunk CRC mismatch at byte {pos}"
            crc_bad = (pos, kind)
            break
        if kind in _ROWS:
            if size != rows * _ROWS[kind].itemsize:
                problem = f"chunk size does not match its row count at byte {pos}"
                break
            parts[kind].append(np.frombuffer(payload, dtype=_ROWS[kind]))
        elif kind == KIND_EVENT:
            events.append(json.loads(payload.decode("utf-8")))
        elif kind == KIND_END:
            summary = json.loads(payload.decode("utf-8"))
            pos = body + size
            if pos != len(data):
                problem = f"{len(data) - pos} bytes after the end marker"
            break
        pos = body + size
    return _Chunks(parts, events, summary, problem, crc_bad, pos)


def _refuse_damaged(p, chunks: _Chunks, complete: bool) -> None:
    """Raise for a damaged or incomplete recording (read without ``recover``), naming what is wrong."""
    if chunks.crc_bad is not None:
        name = {KIND_PITO: "cube rows", KIND_NETFT: "Net F/T rows", KIND_EVENT: "event", KIND_END: "end marker"}
        at, kind = chunks.crc_bad
        raise ChecksumError(
            p, f"chunk at byte {at} ({name.get(kind, f'kind {kind}')})",
            "CRC mismatch (CRC-32); the intact part before it can be read with Recording(path, recover=True)",
        )
    if not complete:
        why = chunks.problem or "no end marker: the recorder did not close it (crash or kill)"
        raise FileFormatError(
            f"{p}: incomplete or damaged recording ({why}); the intact part can be read with "
            "Recording(path, recover=True) or `pito replay --recover`"
        )


class Recording:
    """A recording read back from disk.

    Parameters
    ----------
    path : str or Path
    recover : bool, optional
        Accept an incomplete file (recorder killed or crashed) or one with a damaged tail,
        returning every intact chunk before the damage. Default False: such files raise
        :class:`FileFormatError`.

    Attributes
    ----------
    meta : dict
        The header metadata.
    pito : ndarray of :data:`PITO_ROW`, shape (N,)
        Fields ``seq``, ``time_us``, ``host_time`` (s), ``counts (N, 36)``.
    netft : ndarray of :data:`NETFT_ROW`, shape (M,)
        Fields ``rdt_seq``, ``ft_seq``, ``status``, ``host_time`` (s), ``wrench (M, 6)`` N, N·m.
    events : list of dict
    complete : bool
        The file ends with the end marker (the recorder closed it).
    damaged_bytes : int
        Bytes after the last intact chunk (0 for a complete file).
    """

    def __init__(self, path, *, recover: bool = False):
        self.path = Path(os.fspath(path))
        if not self.path.exists():
            raise FileNotFoundError(f"{self.path}: no such file")
        data = self.path.read_bytes()
        p = self.path
        self.meta, self.version, start = _read_header(p, data)
        chunks = _read_chunks(data, start)
        parts, self.events, self.summary, problem = chunks.parts, chunks.events, chunks.summary, chunks.problem
        self.complete = self.summary is not None and problem is None
        self.damaged_bytes = len(data) - chunks.end if problem else 0
        if not recover:
            _refuse_damaged(p, chunks, self.complete)
        self.pito = np.concatenate(parts[KIND_PITO]) if parts[KIND_PITO] else np.zeros(0, PITO_ROW)
        self.netft = np.concatenate(parts[KIND_NETFT]) if parts[KIND_NETFT] else np.zeros(0, NETFT_ROW)
        if self.summary is not None and self.complete:
            if (self.summary.get("pito_rows"), self.summary.get("netft_rows")) != (self.pito.size, self.netft.size):
                raise FileFormatError(f"{p}: row counts do not match the end marker (corrupt file)")

    # ------------------------------------------------------------------ views
    @property
    def simulated(self) -> bool:
        return bool(self.meta.get("simulated", False))

    @property
    def t0(self) -> float:
        """Host time of the first sample of either stream (s)."""
        firsts = [a["host_time"][0] for a in (self.pito, self.netft) if a.size]
        return float(min(firsts)) if firsts else 0.0

    @property
    def duration(self) -> float:
        """Seconds from the first to the last sample (host clock)."""
        lasts = [a["host_time"][-1] for a in (self.pito, self.netft) if a.size]
        return float(max(lasts) - self.t0) if lasts else 0.0

    def __repr__(self) -> str:
        return (
            f"Recording({str(self.path)!r}, pito={self.pito.size}, netft={self.netft.size}, "
            f"duration={self.duration:.3f} s, complete={self.complete})"
        )

    def replay(self, speed: float = 1.0, step: float = 0.05):
        """Yield :class:`ReplayBatch` slices of ``step`` s of recording time, paced at ``speed``.

        ``speed=1`` is real time, ``2`` twice as fast, ``float('inf')`` as fast as possible.
        Every row is yielded exactly once, in host-time order within each stream.
        """
        if not speed > 0:
            raise ValueError(f"speed: expected > 0 (inf for as fast as possible), got {speed!r}")
        if not step > 0:
            raise ValueError(f"step: expected > 0 s, got {step!r}")
        t0 = self.t0
        tp = self.pito["host_time"] - t0
        tn = self.netft["host_time"] - t0
        ip = inn = 0
        wall0 = time.monotonic()
        k = 1
        while ip < tp.size or inn < tn.size:
            t = k * step
            jp = int(np.searchsorted(tp, t, side="right")) if ip < tp.size else ip
            jn = int(np.searchsorted(tn, t, side="right")) if inn < tn.size else inn
            jp, jn = max(jp, ip), max(jn, inn)
            if not np.isinf(speed):
                delay = wall0 + t / speed - time.monotonic()
                if delay > 0:
                    time.sleep(delay)
            if jp > ip or jn > inn:
                yield ReplayBatch(t, self.pito[ip:jp], self.netft[inn:jn])
            ip, inn = jp, jn
            k += 1


class RecordingChunks:
    """A recording read chunk by chunk, in bounded memory: its index, small columns whole, rows by range.

    One pass over the file checks every chunk (CRC, as :class:`Recording`) and keeps where each
    row chunk lies and the fields named in ``keep`` (e.g. the clocks); :meth:`rows` then reads
    any range of rows back from the file. For recordings too long to hold (an hour of both
    streams is ~0.8 GB on disk, ~1.7 GB as float arrays).

    Parameters
    ----------
    path : str or Path
    recover : bool, optional
        As :class:`Recording`: accept an incomplete or damaged file, up to its last intact chunk.
    keep : dict, optional
        ``{"pito": fields, "netft": fields}`` read whole in the pass (default: the clock and
        sequence fields of each stream, not the counts and wrenches).

    Attributes
    ----------
    meta, events, summary, complete, damaged_bytes, simulated
        As :class:`Recording`.
    pito, netft : dict of ndarray
        The kept fields, whole (``pito["time_us"]`` ...), in file order.
    n_pito, n_netft : int
        Rows of each stream.
    """

    KEEP = {"pito": ("seq", "time_us", "host_time"), "netft": ("rdt_seq", "host_time")}

    def __init__(self, path, *, recover: bool = False, keep: dict | None = None):
        self.path = Path(os.fspath(path))
        if not self.path.exists():
            raise FileNotFoundError(f"{self.path}: no such file")
        keep = dict(self.KEEP if keep is None else keep)
        size = self.path.stat().st_size
        with open(self.path, "rb") as fh:
            head = fh.read(min(size, _HEAD.size))
            n = _HEAD.unpack(head)[3] if len(head) == _HEAD.size and head[:8] == _MAGIC else 0
            head += fh.read(n + 4)
            self.meta, self.version, pos = _read_header(self.path, head)
            chunks, where, kept = self._scan(fh, pos, size, keep)
        self.events, self.summary = chunks.events, chunks.summary
        self.complete = self.summary is not None and chunks.problem is None
        self.damaged_bytes = size - chunks.end if chunks.problem else 0
        if not recover:
            _refuse_damaged(self.path, chunks, self.complete)
        self._where = {k: (np.array([w[0] for w in v], np.int64), np.array([w[1] for w in v], np.int64))
                       for k, v in where.items()}
        self._starts = {k: np.concatenate([[0], np.cumsum(rows)]) for k, (_, rows) in self._where.items()}
        self.pito, self.netft = kept[KIND_PITO], kept[KIND_NETFT]
        self.n_pito, self.n_netft = int(self._starts[KIND_PITO][-1]), int(self._starts[KIND_NETFT][-1])
        if self.summary is not None and self.complete:
            if (self.summary.get("pito_rows"), self.summary.get("netft_rows")) != (self.n_pito, self.n_netft):
                raise FileFormatError(f"{self.path}: row counts do not match the end marker (corrupt file)")

    @staticmethod
    def _scan(fh, pos: int, size: int, keep: dict):
        """Every chunk from byte ``pos``: ``(_Chunks, {kind: [(payload byte, rows)]}, {kind: {field: [array]}})``.

        A first pass reads the chunk heads only (their row counts size the kept columns), the
        second every payload (CRC) into those columns: no column is held twice.
        """
        heads, events, summary, problem, crc_bad = [], [], None, None, None
        at = pos
        while at < size:
            fh.seek(at)
            head = fh.read(_CHUNK.size)
            if len(head) < _CHUNK.size:
                problem = f"truncated chunk header at byte {at}"
                break
            magic, kind, _, _, rows, n, crc = _CHUNK.unpack(head)
            if magic != _CHUNK_MAGIC:
                problem = f"bad chunk magic at byte {at}"
                break
            if at + _CHUNK.size + n > size:
                problem = f"truncated chunk at byte {at}"
                break
            if kind in _ROWS and n != rows * _ROWS[kind].itemsize:
                problem = f"chunk size does not match its row count at byte {at}"
                break
            heads.append((at, head, kind, rows, n, crc))
            at += _CHUNK.size + n
            if kind == KIND_END:
                break
        total = {k: sum(h[3] for h in heads if h[2] == k) for k in _ROWS}
        cols = {k: {f: np.empty(total[k], _ROWS[k][f]) for f in keep.get(name, ())}
                for k, name in ((KIND_PITO, "pito"), (KIND_NETFT, "netft"))}
        where = {KIND_PITO: [], KIND_NETFT: []}
        filled = {KIND_PITO: 0, KIND_NETFT: 0}
        end = pos
        for at, head, kind, rows, n, crc in heads:
            fh.seek(at + _CHUNK.size)
            payload = fh.read(n)
            if zlib.crc32(payload, zlib.crc32(head[:16])) != crc:
                problem, crc_bad = f"chunk CRC mismatch at byte {at}", (at, kind)
                break
            end = at + _CHUNK.size + n
            if kind in _ROWS:
                where[kind].append((at + _CHUNK.size, rows))
                arr = np.frombuffer(payload, dtype=_ROWS[kind])
                for f, col in cols[kind].items():
                    col[filled[kind]:filled[kind] + rows] = arr[f]
                filled[kind] += rows
            elif kind == KIND_EVENT:
                events.append(json.loads(payload.decode("utf-8")))
            elif kind == KIND_END:
                summary = json.loads(payload.decode("utf-8"))
                if end != size:
                    problem = f"{size - end} bytes after the end marker"
        cols = {k: {f: c[:filled[k]] for f, c in v.items()} for k, v in cols.items()}
        return _Chunks({}, events, summary, problem, crc_bad, end), where, cols

    @property
    def simulated(self) -> bool:
        return bool(self.meta.get("simulated", False))

    def column(self, stream: str, name: str) -> "_Column":
        """Field ``name`` of ``stream`` (``"pito"``, ``"netft"``) read by slice: ``column[i:j]`` float64 rows."""
        return _Column(self, stream, name)

    def rows(self, stream: str, start: int, stop: int) -> np.ndarray:
        """Rows ``start:stop`` of ``stream`` (``"pito"`` or ``"netft"``): :data:`PITO_ROW` / :data:`NETFT_ROW` array."""
        kind = {"pito": KIND_PITO, "netft": KIND_NETFT}.get(stream)
        if kind is None:
            raise ValueError(f"stream: expected 'pito' or 'netft', got {stream!r}")
        starts = self._starts[kind]
        start, stop = max(0, int(start)), min(int(stop), int(starts[-1]))
        out = np.empty(max(0, stop - start), _ROWS[kind])
        if stop <= start:
            return out
        offsets, _ = self._where[kind]
        size = _ROWS[kind].itemsize
        c0 = int(np.searchsorted(starts, start, side="right")) - 1
        c1 = int(np.searchsorted(starts, stop, side="left"))
        buf = memoryview(out.view(np.uint8))
        with open(self.path, "rb") as fh:
            at = 0
            for c in range(c0, c1):
                a, b = max(start, int(starts[c])), min(stop, int(starts[c + 1]))
                fh.seek(int(offsets[c]) + (a - int(starts[c])) * size)
                if fh.readinto(buf[at * size:(at + b - a) * size]) != (b - a) * size:
                    raise FileFormatError(f"{self.path}: the file changed while it was read")
                at += b - a
        return out


class _Column:
    """One field of a :class:`RecordingChunks` stream, read from the file by slice (``column[i:j]``, float64)."""

    def __init__(self, rec: RecordingChunks, stream: str, name: str):
        self.rec, self.stream, self.name = rec, stream, name

    def __getitem__(self, sl: slice) -> np.ndarray:
        return np.asarray(self.rec.rows(self.stream, sl.start or 0, sl.stop)[self.name], np.float64)


def read_recording(path, *, recover: bool = False) -> Recording:
    """Read a recording file (see :class:`Recording`)."""
    return Recording(path, recover=recover)

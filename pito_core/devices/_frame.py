"""The cube's serial frame: packing, CRC and a resynchronising stream decoder.

Frame layout (156 bytes, every field little-endian; docs/devices.md has the byte table)::

    offset  size  field
    0       2     sync bytes 0xAA 0x55
    2       4     u32 sequence number (wraps at 2**32)
    6       4     u32 device time, µs (wraps at 2**32, ~71.6 min)
    10      144   36 × i32 gauge counts, face i owns channels 6(i-1) .. 6i-1
    154     2     u16 CRC-16/CCITT-FALSE over bytes 2 .. 153 (sequence through counts)

CRC-16/CCITT-FALSE: polynomial 0x1021, initial value 0xFFFF, no reflection, no final XOR
(check value ``crc16_ccitt_false(b"123456789") == 0x29B1``).

:class:`FrameDecoder` turns an arbitrary byte stream (chunks of any size, with garbage,
truncated or corrupted frames) into arrays of intact frames, in order, each exactly once.
The CRC is computed for all candidate frames of a chunk at once with numpy, so decoding
runs several hundred times faster than the 1 kHz real-time rate.
"""

from __future__ import annotations

import binascii
from dataclasses import dataclass

import numpy as np

from ..frames import N_GAUGES

__all__ = [
    "FRAME_SIZE",
    "FRAME_SYNC",
    "FRAME_DTYPE",
    "crc16_ccitt_false",
    "crc16_ccitt_false_rows",
    "pack_frames",
    "unpack_frames",
    "FrameDecoder",
    "DecodedFrames",
]

#: Frame size in bytes.
FRAME_SIZE = 156
#: The two sync bytes that start every frame.
FRAME_SYNC = b"\xaa\x55"
_CRC_START, _CRC_STOP = 2, 154  # the CRC covers sequence .. counts

#: numpy record layout of one frame.
FRAME_DTYPE = np.dtype(
    [("sync", "u1", (2,)), ("seq", "<u4"), ("time_us", "<u4"), ("counts", "<i4", (N_GAUGES,)), ("crc", "<u2")]
)
assert FRAME_DTYPE.itemsize == FRAME_SIZE


def _crc_table() -> np.ndarray:
    table = np.zeros(256, dtype=np.uint16)
    for byte in range(256):
        crc = byte << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1021) if crc & 0x8000 else (crc << 1)
            crc &= 0xFFFF
        table[byte] = crc
    return table


_TABLE = _crc_table()
_TABLE_LIST = _TABLE.tolist()


def crc16_ccitt_false(data: bytes) -> int:
    """CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF) of ``data``, as an int 0..65535."""
    crc = 0xFFFF
    for b in bytes(data):
        crc = ((crc << 8) & 0xFFFF) ^ _TABLE_LIST[(crc >> 8) ^ b]
    return crc


_POS_TABLES: dict[int, tuple[np.ndarray, int]] = {}


def _position_tables(m: int) -> tuple[np.ndarray, int]:
    """Per-position tables for messages of ``m`` bytes: the CRC is affine in the data,

    ``crc(d) = c0 ^ T[0, d0] ^ T[1, d1] ^ ... ^ T[m-1, d(m-1)]`` where ``T[k, v]`` is the
    zero-init CRC of a message that is zero except byte k = v, and ``c0`` the CRC of m
    zero bytes. One gather and one XOR-reduce then give the CRC of many rows at once.
    """
    if m not in _POS_TABLES:
        tables = np.zeros((m, 256), dtype=np.uint16)
        t = _TABLE.copy()  # a byte in the last position
        for k in range(m - 1, -1, -1):
            tables[k] = t
            t = (t << np.uint16(8)) ^ _TABLE[t >> np.uint16(8)]  # one more zero byte after it
        _POS_TABLES[m] = (tables, crc16_ccitt_false(bytes(m)))
    return _POS_TABLES[m]


def crc16_ccitt_false_rows(rows: np.ndarray) -> np.ndarray:
    """CRC-16/CCITT-FALSE of each row of a ``(n, m)`` uint8 array → ``(n,)`` uint16.

    Vectorised over rows and columns (see :func:`_position_tables`).
    """
    rows = np.asarray(rows, dtype=np.uint8)
    if rows.ndim != 2:
        raise ValueError(f"rows: expected shape (n, m), got {rows.shape}")
    n, m = rows.shape
    if m == 0:
        return np.full(n, 0xFFFF, dtype=np.uint16)
    tables, c0 = _position_tables(m)
    parts = tables[np.arange(m)[None, :], rows]
    return np.bitwise_xor.reduce(parts, axis=1) ^ np.uint16(c0)


def pack_frames(seq, time_us, counts) -> bytes:
    """Pack frames into bytes (what the cube's firmware sends).

    Parameters
    ----------
    seq : array-like of int, shape (n,)
        Sequence numbers (taken modulo 2**32).
    time_us : array-like of int, shape (n,)
        Device time in µs (taken modulo 2**32).
    counts : array-like of int, shape (n, 36)
        Gauge counts, int32 range.

    Returns
    -------
    bytes
        ``n * 156`` bytes.
    """
    counts = np.asarray(counts)
    if counts.ndim != 2 or counts.shape[1] != N_GAUGES:
        raise ValueError(f"counts: expected shape (n, {N_GAUGES}), got {counts.shape}")
    n = counts.shape[0]
    seq = np.asarray(seq, dtype=np.int64).reshape(-1)
    time_us = np.asarray(time_us, dtype=np.int64).reshape(-1)
    if seq.shape != (n,):
        raise ValueError(f"seq: expected shape ({n},), got {seq.shape}")
    if time_us.shape != (n,):
        raise ValueError(f"time_us: expected shape ({n},), got {time_us.shape}")
    if counts.size and (counts.min() < -(2**31) or counts.max() > 2**31 - 1):
        raise ValueError("counts: expected values in the int32 range")
    rec = np.zeros(n, dtype=FRAME_DTYPE)
    rec["sync"] = (0xAA, 0x55)
    rec["seq"] = (seq % 2**32).astype(np.uint32)
    rec["time_us"] = (time_us % 2**32).astype(np.uint32)
    rec["counts"] = counts.astype(np.int32)
    raw = rec.view(np.uint8).reshape(n, FRAME_SIZE)
    rec["crc"] = crc16_ccitt_false_rows(raw[:, _CRC_START:_CRC_STOP])
    return rec.tobytes()


@dataclass(frozen=True)
class DecodedFrames:
    """Intact frames decoded from a stream.

    Attributes
    ----------
    seq : ndarray of uint32, shape (n,)
    time_us : ndarray of uint32, shape (n,)
        Device time, µs (wrapping).
    counts : ndarray of int32, shape (n, 36)
    """

    seq: np.ndarray
    time_us: np.ndarray
    counts: np.ndarray

    def __len__(self) -> int:
        return int(self.seq.shape[0])


def unpack_frames(data: bytes) -> DecodedFrames:
    """Unpack back-to-back frames (``len(data)`` a multiple of 156), checking sync and CRC.

    Raises
    ------
    ValueError
        If the length is wrong, or a frame has bad sync bytes or a bad CRC (its index named).
    """
    if len(data) % FRAME_SIZE:
        raise ValueError(f"data: expected a multiple of {FRAME_SIZE} bytes, got {len(data)}")
    rec = np.frombuffer(data, dtype=FRAME_DTYPE)
    raw = np.frombuffer(data, dtype=np.uint8).reshape(-1, FRAME_SIZE)
    bad = np.flatnonzero((raw[:, 0] != 0xAA) | (raw[:, 1] != 0x55))
    if bad.size:
        raise ValueError(f"data: frame {int(bad[0])} has bad sync bytes")
    bad = np.flatnonzero(crc16_ccitt_false_rows(raw[:, _CRC_START:_CRC_STOP]) != rec["crc"])
    if bad.size:
        raise ValueError(f"data: frame {int(bad[0])} has a bad CRC")
    return DecodedFrames(rec["seq"].copy(), rec["time_us"].copy(), rec["counts"].copy())


_EMPTY = DecodedFrames(np.zeros(0, np.uint32), np.zeros(0, np.uint32), np.zeros((0, N_GAUGES), np.int32))


class FrameDecoder:
    """Stream decoder: bytes in (any chunking), intact frames out, in order, once each.

    A frame is accepted only if it starts with the sync bytes and its CRC matches; the
    decoder never accepts a corrupt frame. After garbage, a truncated or a corrupted frame
    it finds the next intact frame (resynchronisation).

    Counters (cumulative, see :meth:`stats`):

    - ``frames``: intact frames delivered.
    - ``crc_errors``: frames that started where a frame was expected (right after an intact
      or a rejected frame) and failed the CRC.
    - ``resyncs``: times the decoder lost the frame boundary (something other than an
      intact frame where one was expected) and then found an intact frame elsewhere. The
      first alignment after start (or after :meth:`reset_alignment`) is not counted.
    - ``bytes_skipped``: bytes not part of any intact frame.
    """

    def __init__(self):
        self._buf = bytearray()
        self._base = 0  # absolute stream offset of _buf[0]
        self._expect: int | None = None  # absolute offset where the next frame should start
        self._aligned = False
        self.frames = 0
        self.crc_errors = 0
        self.resyncs = 0
        self.bytes_in = 0

    def stats(self) -> dict:
        """Counters as a dict: frames, crc_errors, resyncs, bytes_skipped, bytes_in."""
        return {
            "frames": self.frames,
            "crc_errors": self.crc_errors,
            "resyncs": self.resyncs,
            "bytes_skipped": self.bytes_in - self.frames * FRAME_SIZE - len(self._buf),
            "bytes_in": self.bytes_in,
        }

    def reset_alignment(self) -> None:
        """Drop buffered bytes and the expected boundary (e.g. after a reconnect)."""
        self.bytes_in -= len(self._buf)
        self._base += len(self._buf)
        self._buf = bytearray()
        self._expect = None
        self._aligned = False

    def feed(self, data: bytes) -> DecodedFrames:
        """Add ``data`` to the stream; return the intact frames completed by it."""
        self.bytes_in += len(data)
        self._buf += data
        if len(self._buf) < FRAME_SIZE:
            return _EMPTY
        fast = self._fast_path()
        if len(self._buf) < FRAME_SIZE:
            return fast if fast is not None else _EMPTY
        arr = np.frombuffer(self._buf, dtype=np.uint8)
        try:
            out, keep = self._scan(arr)
        finally:
            del arr  # release the buffer export before resizing
        self._base += keep
        del self._buf[:keep]
        if fast is None:
            return out
        if not len(out):
            return fast
        return DecodedFrames(
            np.concatenate([fast.seq, out.seq]),
            np.concatenate([fast.time_us, out.time_us]),
            np.concatenate([fast.counts, out.counts]),
        )

    def _fast_path(self) -> DecodedFrames | None:
        """Take the intact frames that follow each other from the expected boundary.

        The steady state of a healthy link (a few frames per read, each where the last one
        ended) costs one C-level CRC (``binascii.crc_hqx`` computes CRC-16/CCITT-FALSE with
        init 0xFFFF) per frame instead of the vectorised scan's fixed numpy overhead.
        Anything unexpected stops it; :meth:`_scan` then handles the rest, counters and all.
        """
        if not self._aligned or self._expect != self._base:
            return None
        buf = self._buf
        at = 0
        n = len(buf)
        while at + FRAME_SIZE <= n and buf[at] == 0xAA and buf[at + 1] == 0x55:
            stored = buf[at + FRAME_SIZE - 2] | (buf[at + FRAME_SIZE - 1] << 8)
            if binascii.crc_hqx(buf[at + _CRC_START : at + _CRC_STOP], 0xFFFF) != stored:
                break
            at += FRAME_SIZE
        if at == 0:
            return None
        rec = np.frombuffer(bytes(buf[:at]), dtype=FRAME_DTYPE)
        del buf[:at]
        self._base += at
        self._expect = self._base
        self.frames += rec.size
        return DecodedFrames(rec["seq"].copy(), rec["time_us"].copy(), rec["counts"].copy())

    def _scan(self, arr: np.ndarray):
        n = arr.size
        cand = np.flatnonzero((arr[:-1] == 0xAA) & (arr[1:] == 0x55))
        complete = cand[cand + FRAME_SIZE <= n]
        if complete.size:
            body = arr[complete[:, None] + np.arange(_CRC_START, FRAME_SIZE)[None, :]]
            crc = crc16_ccitt_false_rows(body[:, : _CRC_STOP - _CRC_START])
            stored = body[:, -2].astype(np.uint16) | (body[:, -1].astype(np.uint16) << np.uint16(8))
            ok = crc == stored
        else:
            ok = np.zeros(0, dtype=bool)
        valid, bad = complete[ok], complete[~ok]
        breaks = np.flatnonzero(np.diff(valid) != FRAME_SIZE)  # a run of valid frames ends at each
        base = self._base
        expect = None if self._expect is None else self._expect - base
        pos = 0  # scan floor: nothing before it can still start a frame
        starts = []
        while True:
            j = int(np.searchsorted(valid, pos))
            c = int(valid[j]) if j < valid.size else None
            if expect is not None and expect >= pos and (c is None or expect < c):
                # the expected boundary comes before the next intact frame
                if expect + 2 > n:
                    break
                if expect + FRAME_SIZE <= n:
                    jb = int(np.searchsorted(bad, expect))
                    if jb < bad.size and bad[jb] == expect:  # corrupt frame where one was due
                        self.crc_errors += 1
                        pos = expect + 1
                        expect += FRAME_SIZE
                        continue
                    expect = None  # garbage where a frame was due: alignment lost
                elif arr[expect] == 0xAA and arr[expect + 1] == 0x55:
                    break  # the expected frame has not fully arrived
                else:
                    expect = None
            if c is None:
                break
            if c != expect and self._aligned:
                self.resyncs += 1
            k = int(np.searchsorted(breaks, j))
            end = int(breaks[k]) if k < breaks.size else valid.size - 1
            starts.append(valid[j : end + 1])
            self._aligned = True
            pos = int(valid[end]) + FRAME_SIZE
            expect = pos
        keep = n
        tail = cand[(cand >= pos) & (cand + FRAME_SIZE > n)]
        if tail.size:
            keep = int(tail[0])
        elif arr[n - 1] == 0xAA and n - 1 >= pos:
            keep = n - 1
        if expect is not None and pos <= expect < keep:
            keep = expect
        self._expect = None if expect is None else base + expect
        if not starts:
            return _EMPTY, keep
        st = np.concatenate(starts)
        self.frames += st.size
        rows = arr[st[:, None] + np.arange(FRAME_SIZE)[None, :]]
        rec = rows.reshape(-1).view(FRAME_DTYPE)
        return DecodedFrames(rec["seq"].copy(), rec["time_us"].copy(), rec["counts"].copy()), keep

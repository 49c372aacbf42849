"""ROS 2 MCAP export (``mcap`` + ``mcap-ros2-support``; no ROS install): docs/interop.md, "MCAP".

Topics (profile ``ros2``, encoding ``cdr``; log time = header stamp = recording start (UNIX) +
sample time on the cube's device clock, ``ExportData.time``: strictly increasing, gaps kept):

- ``/pito/face_{i}/wrench`` — ``geometry_msgs/msg/WrenchStamped``, ``frame_id`` ``pito_face_{i}``:
  the wrench on face i in its own frame (N, N·m), every cube sample with a finite value (with a calibration).
- ``/pito/face_{i}/contact/point`` — ``geometry_msgs/msg/PointStamped``, frame ``pito_core``:
  the contact point (m), only at samples where face i carries a contact;
  ``/pito/face_{i}/contact/wrench`` — ``WrenchStamped``, frame ``pito_core``: the finger force
  (N) and the torsion as a torque along the normal (N·m), acting at that point;
  ``/pito/face_{i}/contact/single_contact`` — ``std_msgs/msg/Float64MultiArray``, at the same
  samples: ``[single (1/0), p (0..1), reason code]`` of the single-contact test
  (``ContactEstimate.single_contact``; reason codes ``pito_core.contact.SingleContactReason``).
- ``/pito/reference/wrench`` — ``WrenchStamped``, frame ``pito_reference`` (S_A), tared: every
  reference record of the recording, at its own time (``ExportData.reference_time``).
- ``/tf_static`` — ``tf2_msgs/msg/TFMessage``: ``pito_core`` → ``pito_face_{i}`` (i = 1..6).
- ``/pito/raw_counts`` — ``std_msgs/msg/Int32MultiArray`` (36 counts) every sample.
- metadata record ``pito_provenance`` (calibration method/date/hash, assembly, note), the
  attachment ``calibration.json`` (the full record of :func:`~pito_core.interop.calibration_record`)
  and the attachment ``calibration.pitocal``: the calibration file's exact bytes (the whole
  model, correction and covariance), whose content hash is the record's ``hash``.

The fixed-layout messages are CDR-encoded and framed as MCAP message records in bulk with numpy,
each channel's records a numpy record type (:class:`_Layout`) filled in place in the chunk's
buffer (the generic encoder of ``mcap_ros2`` costs ~30 µs a message,
tests/interop/test_export_stream.py checks the bytes against it; the ``mcap`` writer ~15 µs a
message), then chunks (zstd, :data:`ZSTD_PARAMETERS`) and message indexes in bulk too:
:class:`McapWriter` writes a recording block by block; the
summary (schemas, channels, statistics, chunk, attachment and metadata indexes) is ``mcap``'s
own records.
"""

from __future__ import annotations

import json
import struct
import zlib

import numpy as np
from scipy.spatial.transform import Rotation

from .._version import __version__
from ..frames import CubeCore
from ._conventions import ROS_CORE_FRAME, ROS_FACE_FRAME
from ._provenance import BULKY_RECORD_KEYS, record_file_bytes

__all__ = ["write_mcap", "McapWriter", "MSGDEFS"]

_TIME = "int32 sec\nuint32 nanosec\n"
_HEADER = "builtin_interfaces/Time stamp\nstring frame_id\n"
_VEC = "float64 x\nfloat64 y\nfloat64 z\n"
_SEP = "=" * 80 + "\n"


def _defs(main: str, *deps: tuple[str, str]) -> str:
    return main + "".join(f"{_SEP}MSG: {name}\n{text}" for name, text in deps)


MSGDEFS = {
    "geometry_msgs/msg/WrenchStamped": _defs(
        "std_msgs/Header header\ngeometry_msgs/Wrench wrench\n",
        ("std_msgs/Header", _HEADER), ("builtin_interfaces/Time", _TIME),
        ("geometry_msgs/Wrench", "geometry_msgs/Vector3 force\ngeometry_msgs/Vector3 torque\n"),
        ("geometry_msgs/Vector3", _VEC)),
    "geometry_msgs/msg/PointStamped": _defs(
        "std_msgs/Header header\ngeometry_msgs/Point point\n",
        ("std_msgs/Header", _HEADER), ("builtin_interfaces/Time", _TIME), ("geometry_msgs/Point", _VEC)),
    "tf2_msgs/msg/TFMessage": _defs(
        "geometry_msgs/TransformStamped[] transforms\n",
        ("geometry_msgs/TransformStamped", "std_msgs/Header header\nstring child_frame_id\ngeometry_msgs/Transform transform\n"),
        ("std_msgs/Header", _HEADER), ("builtin_interfaces/Time", _TIME),
        ("geometry_msgs/Transform", "geometry_msgs/Vector3 translation\ngeometry_msgs/Quaternion rotation\n"),
        ("geometry_msgs/Vector3", _VEC), ("geometry_msgs/Quaternion", "float64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1\n")),
    "std_msgs/msg/Int32MultiArray": _defs(
        "std_msgs/MultiArrayLayout layout\nint32[] data\n",
        ("std_msgs/MultiArrayLayout", "std_msgs/MultiArrayDimension[] dim\nuint32 data_offset\n"),
        ("std_msgs/MultiArrayDimension", "string label\nuint32 size\nuint32 stride\n")),
    "std_msgs/msg/Float64MultiArray": _defs(
        "std_msgs/MultiArrayLayout layout\nfloat64[] data\n",
        ("std_msgs/MultiArrayLayout", "std_msgs/MultiArrayDimension[] dim\nuint32 data_offset\n"),
        ("std_msgs/MultiArrayDimension", "string label\nuint32 size\nuint32 stride\n")),
}


class _Layout:
    """The MCAP message records of one channel's fixed-size messages, as a numpy record type.

    A record is the 31-byte message head (opcode 0x05, record length, channel, sequence, log
    and publish time) and the CDR message: ``prefix`` (its constant bytes; with ``stamped``,
    bytes 4..12 are the header stamp's ``sec``, ``nanosec``, filled per message) and ``k``
    values of dtype ``values``. :meth:`fill` writes every byte of records in place (a chunk's
    buffer): no message is encoded apart and copied.
    """

    def __init__(self, channel: int, prefix: bytes, values: str, k: int, stamped: bool = False):
        self.size = 31 + len(prefix) + np.dtype(values).itemsize * k
        self.stamped = stamped
        fields = [("head", "V11", 0), ("sequence", "<u4", 11), ("log_time", "<u8", 15), ("publish_time", "<u8", 23)]
        consts = {"head": struct.pack("<BQH", 0x05, self.size - 9, channel)}
        if stamped:  # encapsulation, stamp, then frame_id (its length, text, NUL) and the padding
            fields += [("encap", "V4", 31), ("sec", "<i4", 35), ("nsec", "<u4", 39),
                       ("frame", f"V{len(prefix) - 12}", 43)]
            consts.update(encap=prefix[:4], frame=prefix[12:])
        elif prefix:
            fields.append(("prefix", f"V{len(prefix)}", 31))
            consts["prefix"] = prefix
        fields.append(("values", (values, (k,)), 31 + len(prefix)))
        self.dtype = np.dtype({"names": [f[0] for f in fields], "formats": [f[1] for f in fields],
                               "offsets": [f[2] for f in fields], "itemsize": self.size})
        template = np.zeros(1, self.dtype)  # one record: the constant bytes, zeros elsewhere
        for name, b in consts.items():
            template[name] = np.frombuffer(b, f"V{len(b)}")[0]
        self._template = template.view(np.uint8)
        self._tiled = self._template  # the template repeated: records' constant bytes in one copy

    @classmethod
    def stamped(cls, channel: int, frame_id: str, k: int) -> _Layout:
        """``{header{stamp, frame_id}, float64 × k}`` (WrenchStamped, PointStamped), CDR little endian."""
        fid = frame_id.encode() + b"\0"
        start = (12 + len(fid) + 7) // 8 * 8  # the float64 values aligned on 8 (from the encapsulation's end)
        prefix = bytes([0, 1, 0, 0]) + bytes(8) + struct.pack("<I", len(fid)) + fid
        return cls(channel, prefix + bytes(4 + start - len(prefix)), "<f8", k, stamped=True)

    @classmethod
    def int32_array(cls, channel: int, k: int) -> _Layout:
        """``std_msgs/Int32MultiArray``, empty layout, ``k`` int32: dim[] = 0, data_offset = 0, length k."""
        return cls(channel, bytes([0, 1, 0, 0]) + struct.pack("<3I", 0, 0, k), "<i4", k)

    @classmethod
    def float64_array(cls, channel: int, k: int) -> _Layout:
        """``std_msgs/Float64MultiArray``, empty layout, ``k`` float64 (4 bytes to align the data on 8)."""
        return cls(channel, bytes([0, 1, 0, 0]) + struct.pack("<4I", 0, 0, k, 0), "<f8", k)

    def fill(self, rec: np.ndarray, seq0: int, stamps: np.ndarray, values) -> None:
        """Every byte of the records ``rec`` (``(n,)`` of :attr:`dtype`): sequences from ``seq0``, log and
        publish times (and header stamps) ``stamps`` (``(n,)`` of :data:`_STAMP`), values ``(n, k)``."""
        raw = rec.view(np.uint8)
        if self._tiled.size < raw.size:
            self._tiled = np.tile(self._template, len(rec))
        np.copyto(raw, self._tiled[:raw.size])
        rec["sequence"] = np.arange(seq0, seq0 + len(rec), dtype=np.uint32)
        rec["log_time"] = stamps["ns"]
        rec["publish_time"] = stamps["ns"]
        if self.stamped:
            rec["sec"] = stamps["sec"]
            rec["nsec"] = stamps["nsec"]
        rec["values"] = values


#: Message times: ns since the UNIX epoch, and as ``builtin_interfaces/Time`` (int32 sec, uint32 nanosec).
_STAMP = np.dtype([("ns", "<i8"), ("sec", "<i4"), ("nsec", "<u4")])


def _stamps(ns) -> np.ndarray:
    """:data:`_STAMP` rows of times ``ns (n,)`` ns (computed once a block, shared by the topics)."""
    ns = np.asarray(ns, np.int64)
    out = np.empty(len(ns), _STAMP)
    out["ns"] = ns
    out["sec"] = ns // 1_000_000_000
    out["nsec"] = ns % 1_000_000_000
    return out


def _cdr(layout: _Layout, stamp_ns, values) -> np.ndarray:
    """The CDR messages alone, ``(n, size)`` uint8, of ``layout`` (channel 0, sequence 0...)."""
    values = np.asarray(values)
    rec = np.empty(len(values), layout.dtype)
    layout.fill(rec, 0, _stamps(np.zeros(len(values)) if stamp_ns is None else stamp_ns), values)
    return rec.view(np.uint8).reshape(len(values), layout.size)[:, 31:]


def _stamped(stamp_ns: np.ndarray, frame_id: str, values: np.ndarray) -> np.ndarray:
    """CDR (little endian) of ``n`` messages ``{header{stamp, frame_id}, float64 × k}``: ``(n, size)`` uint8."""
    return _cdr(_Layout.stamped(0, frame_id, np.shape(values)[1]), stamp_ns, values)


def _int32_array(values: np.ndarray) -> np.ndarray:
    """CDR of ``n`` ``std_msgs/Int32MultiArray`` with empty layout and ``k`` int32: ``(n, size)`` uint8."""
    return _cdr(_Layout.int32_array(0, np.shape(values)[1]), None, values)


def _float64_array(values: np.ndarray) -> np.ndarray:
    """CDR of ``n`` ``std_msgs/Float64MultiArray`` with empty layout and ``k`` float64: ``(n, size)`` uint8."""
    return _cdr(_Layout.float64_array(0, np.shape(values)[1]), None, values)


def _quat_xyzw(R: np.ndarray) -> list[float]:
    return [float(v) for v in Rotation.from_matrix(R).as_quat()]


_MAGIC = bytes([137, 77, 67, 65, 80, 48, 13, 10])
#: Uncompressed bytes of message records per chunk (as the ``mcap`` writer's default ``chunk_size``).
CHUNK_BYTES = 1 << 20
#: zstd's parameters for the chunks (``compression_level=None``): its fast strategy (as its negative levels)
#: with a window of one chunk, a 2¹⁴-entry hash table, matches of at least 7 bytes and a step of 3 over
#: unmatched bytes (the float64 values, which hardly compress). On the export's chunks (60 s, 1 MiB
#: each; CPU time, median of 5 rounds) against level −1: 0.76× the time, 1.03× the size (level −3:
#: 0.75×, 1.06×; −2: 0.81×, 1.03×; lz4 frames: 0.76×, 1.28×); docs/interop.md.
ZSTD_PARAMETERS = dict(strategy=1, window_log=20, hash_log=14, chain_log=14, search_log=1, min_match=7,
                       target_length=3)


def write_mcap(data, path, *, raw_counts: bool = True, progress=None) -> dict:
    """Write :class:`~pito_core.interop.ExportData` (or an :class:`~pito_core.interop.ExportStream`) ``data`` to the MCAP file ``path``.

    Returns ``{topic: message count}``.
    """
    w = McapWriter(data, path, raw_counts=raw_counts)
    for block in data.blocks():
        w.append(block)
    counts = w.close()
    if progress is not None:
        progress(1.0, "mcap: done")
    return counts


def _ns(start_unix: float, t) -> np.ndarray:
    """Log times, ns since the UNIX epoch, of times ``t`` s from ``start_unix``."""
    return np.round((start_unix + np.asarray(t, float)) * 1e9).astype(np.int64)


class McapWriter:
    """An MCAP file (profile ``ros2``) written block by block, every message encoded and framed in bulk.

    Parameters
    ----------
    head : ExportData or ExportStream
        Its metadata (calibration, assembly, note) and ``start_unix``, ``time`` (the first stamp).
    path : str or Path
    raw_counts : bool
        Write ``/pito/raw_counts``.
    compression_level : int, optional
        zstd's level for the chunks; None: :data:`ZSTD_PARAMETERS`.
    background : bool
        Compress and write the chunks in a second thread (zstd, CRC and file writes release the
        GIL) while the caller fills the next one: less wall time on two cores, the same CPU time
        and the same file. False: all in the calling thread.

    :meth:`append` takes the :class:`~pito_core.interop.ExportData` blocks in order; :meth:`close`
    writes the summary and returns ``{topic: message count}``.
    """

    def __init__(self, head, path, *, raw_counts: bool = True, compression_level: int | None = None,
                 background: bool = False):
        import zstandard  # deferred: optional dependency (extra "interop", with mcap)
        from mcap.records import Header

        self.head, self.raw_counts = head, bool(raw_counts)
        self._zstd = zstandard.ZstdCompressor(level=compression_level) if compression_level is not None else \
            zstandard.ZstdCompressor(compression_params=zstandard.ZstdCompressionParameters(**ZSTD_PARAMETERS))
        self._fh = open(path, "wb")
        self._fh.write(_MAGIC)
        self._put(Header(profile="ros2", library=f"pito {__version__} (pito_core.interop)"))
        self._schemas = {name: i + 1 for i, name in enumerate(MSGDEFS)}
        self._records = {"schemas": [], "channels": [], "chunks": [], "attachments": [], "metadata": []}
        for name, text in MSGDEFS.items():
            self._schema(name, text)
        self._channels: dict[str, int] = {}
        self._layouts: dict[str, _Layout] = {}
        self._bufs = [np.empty(0, np.uint8), np.empty(0, np.uint8)]  # two in background: one filled, one written
        self._busy = [None, None]  # the background write of each buffer
        self._next = 0
        self._pool = None
        if background:
            from concurrent.futures import ThreadPoolExecutor

            self._pool = ThreadPoolExecutor(1, thread_name_prefix="pito-mcap")  # one thread: chunks in order
        self.counts: dict[str, int] = {}
        self._times = [None, None]
        self._started = False

    # ------------------------------------------------------------------ records
    def _put(self, record) -> tuple[int, int]:
        """Write one ``mcap.records`` record; returns its ``(offset, length)``."""
        from mcap.data_stream import RecordBuilder

        b = RecordBuilder()
        record.write(b)
        data = b.end()
        at = self._fh.tell()
        self._fh.write(data)
        return at, len(data)

    def _schema(self, name: str, text: str) -> None:
        from mcap.records import Schema

        rec = Schema(id=self._schemas[name], name=name, encoding="ros2msg", data=text.encode())
        self._put(rec)
        self._records["schemas"].append(rec)

    def _channel(self, topic: str, datatype: str, layout) -> None:
        """Channel ``topic``; ``layout(id)``: its messages' :class:`_Layout`."""
        from mcap.records import Channel

        rec = Channel(id=len(self._channels) + 1, topic=topic, message_encoding="cdr",
                      schema_id=self._schemas[datatype], metadata={})
        self._put(rec)
        self._records["channels"].append(rec)
        self._channels[topic] = rec.id
        self._layouts[topic] = layout(rec.id)
        self.counts[topic] = 0

    # ------------------------------------------------------------------ data
    def _start(self, first) -> None:
        """Provenance, ``/tf_static`` and every channel, in the order of ``counts``."""
        head = self.head
        t0 = int(_ns(head.start_unix, head.time[:1])[0]) if np.size(head.time) else int(head.start_unix * 1e9)
        self._write_provenance(t0)
        tf = _tf_static(head, t0)
        self._channel("/tf_static", "tf2_msgs/msg/TFMessage", lambda c: _Layout(c, b"", "u1", tf.shape[1]))
        if self.raw_counts:
            self._channel("/pito/raw_counts", "std_msgs/msg/Int32MultiArray", lambda c: _Layout.int32_array(c, 36))
        wrench = "geometry_msgs/msg/WrenchStamped"
        if np.size(head.reference_time):
            self._channel("/pito/reference/wrench", wrench, lambda c: _Layout.stamped(c, "pito_reference", 6))
        if first.face_wrenches is not None:
            for i in range(1, 7):
                self._channel(f"/pito/face_{i}/wrench", wrench,
                              lambda c, i=i: _Layout.stamped(c, ROS_FACE_FRAME.format(i=i), 6))
        if first.contacts is not None:
            for i in range(1, 7):
                self._channel(f"/pito/face_{i}/contact/point", "geometry_msgs/msg/PointStamped",
                              lambda c: _Layout.stamped(c, ROS_CORE_FRAME, 3))
                self._channel(f"/pito/face_{i}/contact/wrench", wrench, lambda c: _Layout.stamped(c, ROS_CORE_FRAME, 6))
                if getattr(first.contacts, "single_contact", None) is not None:
                    self._channel(f"/pito/face_{i}/contact/single_contact", "std_msgs/msg/Float64MultiArray",
                                  lambda c: _Layout.float64_array(c, 3))
        self._write_chunk([("/tf_static", _stamps([t0]), tf)])

    def append(self, block) -> None:
        """The messages of ``block`` (an :class:`~pito_core.interop.ExportData` of consecutive samples)."""
        if not self._started:
            self._start(block)
            self._started = True
        stamp = _stamps(_ns(block.start_unix, block.time))
        parts = []  # (topic, stamps, values): the values are written straight into the chunks' records
        if self.raw_counts:
            parts.append(("/pito/raw_counts", stamp, block.counts))
        if np.size(block.reference_time):  # every reference record, at its own time (the cube's clock), tared
            parts.append(("/pito/reference/wrench", _stamps(_ns(block.start_unix, block.reference_time)),
                          block.reference_wrench))
        if block.face_wrenches is not None:
            fw = block.face_wrenches
            ok = np.isfinite(fw).all(axis=2)  # no message where there is no value
            for i in range(1, 7):
                v = ok[:, i - 1]
                parts.append((f"/pito/face_{i}/wrench", stamp, fw[:, i - 1]) if v.all() else
                             (f"/pito/face_{i}/wrench", stamp[v], fw[v, i - 1]))
        if block.contacts is not None:
            parts += _contact_parts(block.contacts, stamp)
        self._write_block(parts, stamp)

    def _write_block(self, parts: list, stamp: np.ndarray) -> None:
        """``parts`` ``[(topic, stamps (_STAMP rows), values)]`` as chunks of about :data:`CHUNK_BYTES`, cut at
        cube sample times."""
        total = sum(len(st) * self._layouts[topic].size for topic, st, _ in parts)
        k = max(1, -(-total // CHUNK_BYTES))
        if k == 1 or stamp.size < 2:
            self._write_chunk(parts)
            return
        cuts = stamp["ns"][np.linspace(0, stamp.size, k + 1).astype(int)[1:-1]]
        sl = [np.concatenate([[0], np.searchsorted(st["ns"], cuts, side="left"), [st.size]]) for _, st, _ in parts]
        for c in range(k):
            self._write_chunk([(topic, st[s[c]:s[c + 1]], v[s[c]:s[c + 1]]) for (topic, st, v), s in zip(parts, sl)])

    def _write_chunk(self, parts: list) -> None:
        """One chunk (zstd) of the messages ``[(topic, stamps (n,) of _STAMP, values (n, k))]`` and its indexes.

        The message records are written in place in a buffer kept from chunk to chunk (two, taken
        in turn, with ``background``: a buffer is filled again once its chunk is written)."""
        parts = [(topic, st, v) for topic, st, v in parts if len(st)]
        if not parts:
            return
        i = self._next
        if self._pool is not None:
            self._next = 1 - i
            if self._busy[i] is not None:
                self._busy[i].result()  # (a failure of the writing thread is raised here)
                self._busy[i] = None
        size = sum(len(st) * self._layouts[topic].size for topic, st, _ in parts)
        if self._bufs[i].size < size:
            self._bufs[i] = np.empty(size, np.uint8)
        data = self._bufs[i][:size]
        index, at = [], 0
        for topic, st, values in parts:
            lay = self._layouts[topic]
            n = len(st)
            cid, seq0 = self._channels[topic], self.counts[topic]
            lay.fill(data[at:at + n * lay.size].view(lay.dtype), seq0, st, values)
            index.append((cid, st["ns"], at + lay.size * np.arange(n, dtype=np.uint64)))
            at += n * lay.size
            self.counts[topic] = seq0 + n
        lo = min(int(st["ns"][0]) for _, st, _ in parts)  # every topic's stamps increase
        hi = max(int(st["ns"][-1]) for _, st, _ in parts)
        self._times = [lo if self._times[0] is None else min(self._times[0], lo), max(self._times[1] or hi, hi)]
        if self._pool is None:
            self._put_chunk(data, index, lo, hi)
        else:
            self._busy[i] = self._pool.submit(self._put_chunk, data, index, lo, hi)

    def _put_chunk(self, data: np.ndarray, index: list, lo: int, hi: int) -> None:
        """The Chunk record of the message records ``data`` (zstd), then its message indexes ``index``
        (``[(channel, log times, offsets)]``), at the end of the file."""
        from mcap.records import ChunkIndex

        size = len(data)
        packed = self._zstd.compress(data)
        # the Chunk record (opcode 0x06) by hand: its compressed records written as they are, not copied
        head = struct.pack("<QQQI", lo, hi, size, zlib.crc32(data)) + struct.pack("<I", 4) + b"zstd" + \
            struct.pack("<Q", len(packed))
        start = self._fh.tell()
        self._fh.write(struct.pack("<BQ", 0x06, len(head) + len(packed)) + head)
        self._fh.write(packed)
        length = self._fh.tell() - start
        offsets, idx = {}, bytearray()
        base = self._fh.tell()
        for cid, st, off in index:
            if cid in offsets:  # one index per channel and chunk: a topic comes once per chunk
                raise RuntimeError(f"mcap: channel {cid} twice in one chunk")
            offsets[cid] = base + len(idx)
            pairs = np.column_stack([st.astype("<u8"), off.astype("<u8")]).tobytes()
            idx += struct.pack("<BQHI", 0x07, 6 + len(pairs), cid, len(pairs)) + pairs
        self._fh.write(idx)
        self._records["chunks"].append(ChunkIndex(
            message_start_time=lo, message_end_time=hi, chunk_start_offset=start, chunk_length=length,
            message_index_offsets=offsets, message_index_length=len(idx), compression="zstd",
            compressed_size=len(packed), uncompressed_size=size))

    def _write_provenance(self, t0: int) -> None:
        """The ``pito_provenance`` metadata record and the ``calibration.json`` (and ``.pitocal``) attachments."""
        from mcap.records import Attachment, AttachmentIndex, Metadata, MetadataIndex

        head = self.head
        meta = {"note": head.note, "simulated": json.dumps(head.simulated),
                "assembly": json.dumps(head.assembly), "calibration": json.dumps(
                    None if head.calibration is None else
                    {k: v for k, v in head.calibration.items() if k not in BULKY_RECORD_KEYS}, default=str)}
        at, length = self._put(Metadata(name="pito_provenance", metadata=meta))
        self._records["metadata"].append(MetadataIndex(offset=at, length=length, name="pito_provenance"))
        if head.calibration is None:
            return
        files = [("calibration.json", "application/json", json.dumps(head.calibration, default=str).encode())]
        if "file" in head.calibration:
            files.append(("calibration.pitocal", "application/x-hdf5", record_file_bytes(head.calibration)))
        for name, media, data in files:
            at, length = self._put(Attachment(create_time=0, log_time=t0, name=name, media_type=media, data=data))
            self._records["attachments"].append(AttachmentIndex(
                offset=at, length=length, log_time=t0, create_time=0, data_size=len(data), name=name, media_type=media))

    def _wait(self) -> None:
        """Every chunk handed to the writing thread written (its failure raised), the thread ended."""
        if self._pool is None:
            return
        try:
            for f in self._busy:
                if f is not None:
                    f.result()
        finally:
            self._busy = [None, None]
            self._pool.shutdown(wait=True)
            self._pool = None

    # ------------------------------------------------------------------ summary
    def close(self) -> dict:
        """The summary section (schemas, channels, statistics, indexes), the footer; returns ``{topic: messages}``."""
        from mcap.data_stream import RecordBuilder
        from mcap.opcode import Opcode
        from mcap.records import DataEnd, Footer, Statistics, SummaryOffset

        if not self._started:
            raise ValueError("mcap: no block was written")
        self._wait()
        self._put(DataEnd(data_section_crc=0))
        start = self._fh.tell()
        b = RecordBuilder()
        ids = self._channels
        stats = Statistics(
            message_count=sum(self.counts.values()), schema_count=len(self._records["schemas"]),
            channel_count=len(ids), attachment_count=len(self._records["attachments"]),
            metadata_count=len(self._records["metadata"]), chunk_count=len(self._records["chunks"]),
            message_start_time=self._times[0] or 0, message_end_time=self._times[1] or 0,
            channel_message_counts={ids[t]: n for t, n in self.counts.items() if n})
        groups = [(Opcode.SCHEMA, self._records["schemas"]), (Opcode.CHANNEL, self._records["channels"]),
                  (Opcode.STATISTICS, [stats]), (Opcode.CHUNK_INDEX, self._records["chunks"]),
                  (Opcode.ATTACHMENT_INDEX, self._records["attachments"]),
                  (Opcode.METADATA_INDEX, self._records["metadata"])]
        offsets = []
        for opcode, recs in groups:
            g = b.count
            for r in recs:
                r.write(b)
            offsets.append(SummaryOffset(group_opcode=opcode, group_start=start + g, group_length=b.count - g))
        offset_start = start + b.count
        for o in offsets:
            o.write(b)
        summary = b.end()
        crc = zlib.crc32(struct.pack("<BQQQ", Opcode.FOOTER, 20, start, offset_start), zlib.crc32(summary))
        self._fh.write(summary)
        self._put(Footer(summary_start=start, summary_offset_start=offset_start, summary_crc=crc))
        self._fh.write(_MAGIC)
        self._fh.close()
        return dict(self.counts)


def _tf_static(head, t0: int) -> np.ndarray:
    """``/tf_static``: one ``TFMessage`` with ``pito_core`` → ``pito_face_{i}`` (i = 1..6), CDR by ``mcap_ros2``."""
    from mcap_ros2._dynamic import serialize_dynamic  # deferred: optional dependency (extra "interop")

    edge = (head.assembly or {}).get("core_edge_m") or (head.calibration or {}).get("core_edge_m")
    core = CubeCore(edge) if edge else CubeCore()
    tfs = []
    for i in range(1, 7):
        T = core.face_pose(i)
        tfs.append({"header": {"stamp": {"sec": t0 // 10**9, "nanosec": t0 % 10**9}, "frame_id": ROS_CORE_FRAME},
                    "child_frame_id": ROS_FACE_FRAME.format(i=i),
                    "transform": {"translation": dict(zip("xyz", map(float, T[:3, 3]))),
                                  "rotation": dict(zip("xyzw", _quat_xyzw(T[:3, :3])))}})
    name = "tf2_msgs/msg/TFMessage"
    data = serialize_dynamic(name, MSGDEFS[name])[name]({"transforms": tfs})
    return np.frombuffer(data, np.uint8).reshape(1, -1)


def _contact_parts(c, stamp: np.ndarray) -> list:
    """Each face's contact point, finger wrench and single-contact test, at the samples with a contact."""
    parts = []
    for i in range(1, 7):
        k = i - 1
        v = np.flatnonzero(c.valid[:, k])
        st = stamp[v]
        parts.append((f"/pito/face_{i}/contact/point", st, c.point[v, k]))
        wr = np.empty((len(v), 6))
        wr[:, :3] = c.force[v, k]
        np.multiply(c.torsion[v, k, None], c.normal[v, k], out=wr[:, 3:])
        parts.append((f"/pito/face_{i}/contact/wrench", st, wr))
        if getattr(c, "single_contact", None) is not None:
            flag = np.empty((len(v), 3))
            flag[:, 0] = c.single_contact[v, k]
            flag[:, 1] = c.single_contact_p[v, k]
            flag[:, 2] = c.single_contact_reason[v, k]
            parts.append((f"/pito/face_{i}/contact/single_contact", st, flag))
    return parts

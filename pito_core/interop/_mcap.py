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

The fixed-layout messages are CDR-encoded in bulk with numpy (the generic encoder of
``mcap_ros2`` costs ~30 µs a message; tests/interop/test_mcap.py checks the bytes against it),
and framed as MCAP message records, chunks (zstd) and message indexes in bulk too (the ``mcap``
writer costs ~15 µs a message): :class:`McapWriter` writes a recording block by block; the
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


def _stamped(stamp_ns: np.ndarray, frame_id: str, values: np.ndarray) -> np.ndarray:
    """CDR (little endian) of ``n`` messages ``{header{stamp, frame_id}, float64 × k}``: ``(n, size)`` uint8."""
    values = np.ascontiguousarray(values, dtype="<f8")
    n, k = values.shape
    fid = frame_id.encode() + b"\0"
    body = 12 + len(fid)
    start = (body + 7) // 8 * 8
    size = 4 + start + 8 * k
    out = np.zeros((n, size), np.uint8)
    out[:, 1] = 1  # encapsulation CDR_LE
    sec = (stamp_ns // 1_000_000_000).astype("<i4")
    nsec = (stamp_ns % 1_000_000_000).astype("<u4")
    out[:, 4:8] = sec.view(np.uint8).reshape(n, 4)
    out[:, 8:12] = nsec.view(np.uint8).reshape(n, 4)
    out[:, 12:16] = np.frombuffer(np.uint32(len(fid)).astype("<u4").tobytes(), np.uint8)
    out[:, 16:16 + len(fid)] = np.frombuffer(fid, np.uint8)
    out[:, 4 + start:] = values.view(np.uint8).reshape(n, 8 * k)
    return out


def _int32_array(values: np.ndarray) -> np.ndarray:
    """CDR of ``n`` ``std_msgs/Int32MultiArray`` with empty layout and ``k`` int32: ``(n, size)`` uint8."""
    values = np.ascontiguousarray(values, dtype="<i4")
    n, k = values.shape
    head = np.array([0, 1, 0, 0], np.uint8).tobytes() + np.array([0, 0, k], "<u4").tobytes()  # dim[]=0, offset=0, len
    out = np.empty((n, len(head) + 4 * k), np.uint8)
    out[:, :len(head)] = np.frombuffer(head, np.uint8)
    out[:, len(head):] = values.view(np.uint8).reshape(n, 4 * k)
    return out


def _float64_array(values: np.ndarray) -> np.ndarray:
    """CDR of ``n`` ``std_msgs/Float64MultiArray`` with empty layout and ``k`` float64: ``(n, size)`` uint8."""
    values = np.ascontiguousarray(values, dtype="<f8")
    n, k = values.shape
    # dim[] = 0, data_offset = 0, data length k, 4 bytes to align the float64 data on 8
    head = np.array([0, 1, 0, 0], np.uint8).tobytes() + np.array([0, 0, k, 0], "<u4").tobytes()
    out = np.empty((n, len(head) + 8 * k), np.uint8)
    out[:, :len(head)] = np.frombuffer(head, np.uint8)
    out[:, len(head):] = values.view(np.uint8).reshape(n, 8 * k)
    return out


def _quat_xyzw(R: np.ndarray) -> list[float]:
    return [float(v) for v in Rotation.from_matrix(R).as_quat()]


#: MCAP message record head: opcode 0x05, record length, channel, sequence, log and publish time (31 bytes).
_MSG_HEAD = np.dtype([("op", "u1"), ("length", "<u8"), ("channel", "<u2"), ("sequence", "<u4"), ("log_time", "<u8"),
                      ("publish_time", "<u8")])
_MAGIC = bytes([137, 77, 67, 65, 80, 48, 13, 10])
#: Uncompressed bytes of message records per chunk (as the ``mcap`` writer's default ``chunk_size``).
CHUNK_BYTES = 1 << 20


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

    :meth:`append` takes the :class:`~pito_core.interop.ExportData` blocks in order; :meth:`close`
    writes the summary and returns ``{topic: message count}``.
    """

    def __init__(self, head, path, *, raw_counts: bool = True, compression_level: int = -1):
        import zstandard  # deferred: optional dependency (extra "interop", with mcap)
        from mcap.records import Header

        self.head, self.raw_counts = head, bool(raw_counts)
        self._zstd = zstandard.ZstdCompressor(level=compression_level)
        self._fh = open(path, "wb")
        self._fh.write(_MAGIC)
        self._put(Header(profile="ros2", library=f"pito {__version__} (pito_core.interop)"))
        self._schemas = {name: i + 1 for i, name in enumerate(MSGDEFS)}
        self._records = {"schemas": [], "channels": [], "chunks": [], "attachments": [], "metadata": []}
        for name, text in MSGDEFS.items():
            self._schema(name, text)
        self._channels: dict[str, int] = {}
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

    def _channel(self, topic: str, datatype: str) -> None:
        from mcap.records import Channel

        rec = Channel(id=len(self._channels) + 1, topic=topic, message_encoding="cdr",
                      schema_id=self._schemas[datatype], metadata={})
        self._put(rec)
        self._records["channels"].append(rec)
        self._channels[topic] = rec.id
        self.counts[topic] = 0

    # ------------------------------------------------------------------ data
    def _start(self, first) -> None:
        """Provenance, ``/tf_static`` and every channel, in the order of ``counts``."""
        head = self.head
        t0 = int(_ns(head.start_unix, head.time[:1])[0]) if np.size(head.time) else int(head.start_unix * 1e9)
        self._write_provenance(t0)
        self._channel("/tf_static", "tf2_msgs/msg/TFMessage")
        if self.raw_counts:
            self._channel("/pito/raw_counts", "std_msgs/msg/Int32MultiArray")
        if np.size(head.reference_time):
            self._channel("/pito/reference/wrench", "geometry_msgs/msg/WrenchStamped")
        if first.face_wrenches is not None:
            for i in range(1, 7):
                self._channel(f"/pito/face_{i}/wrench", "geometry_msgs/msg/WrenchStamped")
        if first.contacts is not None:
            for i in range(1, 7):
                self._channel(f"/pito/face_{i}/contact/point", "geometry_msgs/msg/PointStamped")
                self._channel(f"/pito/face_{i}/contact/wrench", "geometry_msgs/msg/WrenchStamped")
                if getattr(first.contacts, "single_contact", None) is not None:
                    self._channel(f"/pito/face_{i}/contact/single_contact", "std_msgs/msg/Float64MultiArray")
        self._write_chunk([("/tf_static", np.array([t0]), _tf_static(head, t0))])

    def append(self, block) -> None:
        """The messages of ``block`` (an :class:`~pito_core.interop.ExportData` of consecutive samples)."""
        if not self._started:
            self._start(block)
            self._started = True
        stamp = _ns(block.start_unix, block.time)
        parts = []
        if self.raw_counts:
            parts.append(("/pito/raw_counts", stamp, _int32_array(block.counts)))
        if np.size(block.reference_time):  # every reference record, at its own time (the cube's clock), tared
            rstamp = _ns(block.start_unix, block.reference_time)
            parts.append(("/pito/reference/wrench", rstamp,
                          _stamped(rstamp, "pito_reference", np.asarray(block.reference_wrench, float))))
        if block.face_wrenches is not None:
            for i in range(1, 7):
                fw = np.asarray(block.face_wrenches[:, i - 1], float)
                ok = np.isfinite(fw).all(axis=1)  # no message where there is no value
                parts.append((f"/pito/face_{i}/wrench", stamp[ok], _stamped(stamp[ok], ROS_FACE_FRAME.format(i=i), fw[ok])))
        if block.contacts is not None:
            parts += _contact_parts(block.contacts, stamp)
        self._write_block(parts, stamp)

    def _write_block(self, parts: list, stamp: np.ndarray) -> None:
        """``parts`` ``[(topic, stamps, encoded)]`` as chunks of about :data:`CHUNK_BYTES`, cut at cube sample times."""
        total = sum(e.size + 31 * len(e) for _, _, e in parts)
        k = max(1, -(-total // CHUNK_BYTES))
        if k == 1 or stamp.size < 2:
            self._write_chunk(parts)
            return
        cuts = stamp[np.linspace(0, stamp.size, k + 1).astype(int)[1:-1]]
        sl = [np.concatenate([[0], np.searchsorted(st, cuts, side="left"), [st.size]]) for _, st, _ in parts]
        for c in range(k):
            self._write_chunk([(topic, st[s[c]:s[c + 1]], enc[s[c]:s[c + 1]])
                               for (topic, st, enc), s in zip(parts, sl)])

    def _write_chunk(self, parts: list) -> None:
        """One chunk (zstd) of the messages ``[(topic, stamps (n,) ns, encoded (n, size) uint8)]`` and its indexes."""
        from mcap.records import Chunk, ChunkIndex

        parts = [(topic, st, enc) for topic, st, enc in parts if len(enc)]
        if not parts:
            return
        data = np.empty(sum(len(enc) * (31 + enc.shape[1]) for _, _, enc in parts), np.uint8)
        index, at = [], 0
        for topic, st, enc in parts:  # message records: 31-byte head, then the CDR message
            n, size = len(enc), 31 + enc.shape[1]
            cid, seq0 = self._channels[topic], self.counts[topic]
            rec = data[at:at + n * size].reshape(n, size)
            head = np.empty(n, _MSG_HEAD)
            head["op"], head["length"], head["channel"] = 0x05, size - 9, cid
            head["sequence"] = np.arange(seq0, seq0 + n)
            head["log_time"] = head["publish_time"] = st
            rec[:, :31] = head.view(np.uint8).reshape(n, 31)
            rec[:, 31:] = enc
            index.append((cid, st, at + size * np.arange(n, dtype=np.uint64)))
            at += n * size
            self.counts[topic] = seq0 + n
        lo = min(int(st.min()) for _, st, _ in parts)
        hi = max(int(st.max()) for _, st, _ in parts)
        self._times = [lo if self._times[0] is None else min(self._times[0], lo), max(self._times[1] or hi, hi)]
        chunk = Chunk(compression="zstd", data=self._zstd.compress(data), message_start_time=lo, message_end_time=hi,
                      uncompressed_crc=zlib.crc32(data), uncompressed_size=len(data))
        start, length = self._put(chunk)
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
            compressed_size=len(chunk.data), uncompressed_size=len(data)))

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

    # ------------------------------------------------------------------ summary
    def close(self) -> dict:
        """The summary section (schemas, channels, statistics, indexes), the footer; returns ``{topic: messages}``."""
        from mcap.data_stream import RecordBuilder
        from mcap.opcode import Opcode
        from mcap.records import DataEnd, Footer, Statistics, SummaryOffset

        if not self._started:
            raise ValueError("mcap: no block was written")
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
        v = np.asarray(c.valid[:, k], bool)
        st = stamp[v]
        parts.append((f"/pito/face_{i}/contact/point", st, _stamped(st, ROS_CORE_FRAME, c.point[v, k])))
        wr = np.concatenate([c.force[v, k], c.torsion[v, k, None] * c.normal[v, k]], axis=1)
        parts.append((f"/pito/face_{i}/contact/wrench", st, _stamped(st, ROS_CORE_FRAME, wr)))
        if getattr(c, "single_contact", None) is not None:
            flag = np.c_[c.single_contact[v, k], c.single_contact_p[v, k], c.single_contact_reason[v, k]]
            parts.append((f"/pito/face_{i}/contact/single_contact", st, _float64_array(flag)))
    return parts

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
``mcap_ros2`` costs ~30 µs a message); the tests decode them with ``mcap_ros2``'s decoder.
"""

from __future__ import annotations

import json

import numpy as np
from scipy.spatial.transform import Rotation

from ..frames import CubeCore
from ._conventions import ROS_CORE_FRAME, ROS_FACE_FRAME
from ._provenance import BULKY_RECORD_KEYS, record_file_bytes

__all__ = ["write_mcap", "MSGDEFS"]

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


def write_mcap(data, path, *, raw_counts: bool = True, progress=None) -> dict:
    """Write :class:`~pito_core.interop.ExportData` ``data`` to the MCAP file ``path``.

    Returns ``{topic: message count}``.
    """
    from mcap_ros2.writer import Writer  # deferred: optional dependency (extra "interop"), as mcap itself

    stamp = (np.round((data.start_unix + np.asarray(data.time, float)) * 1e9)).astype(np.int64)
    n_steps = 2 + 6 * (data.face_wrenches is not None) + 6 * (data.contacts is not None)
    step = 0

    def advance(text):
        nonlocal step
        step += 1
        if progress is not None:
            progress(float(0.7 + 0.3 * step / n_steps), text)

    with open(path, "wb") as fh:
        w = Writer(fh)
        topics = _Topics(w)
        _write_provenance(w, data, stamp)
        _write_tf_static(topics, data, stamp)
        _write_series(topics, data, stamp, raw_counts, advance)
        if data.contacts is not None:
            _write_contacts(topics, data.contacts, stamp, advance)
        w.finish()
    if progress is not None:
        progress(1.0, "mcap: done")
    return topics.counts


class _Topics:
    """The writer's schemas and channels; ``counts`` = ``{topic: messages written}``, in writing order."""

    def __init__(self, writer):
        self.writer = writer
        self.schemas = {k: writer.register_msgdef(k, v) for k, v in MSGDEFS.items()}
        self.raw = writer._writer  # the plain mcap writer: messages encoded here in bulk
        self.counts: dict[str, int] = {}

    def put(self, topic: str, datatype: str, stamps: np.ndarray, encoded: np.ndarray) -> None:
        """Messages ``encoded`` ``(n, size)`` uint8 (CDR) on a new channel ``topic``, at ``stamps`` (ns)."""
        cid = self.raw.register_channel(topic=topic, message_encoding="cdr", schema_id=self.schemas[datatype].id)
        add = self.raw.add_message
        for s, (t, row) in enumerate(zip(stamps.tolist(), encoded)):
            add(channel_id=cid, log_time=t, publish_time=t, sequence=s, data=row.tobytes())
        self.counts[topic] = len(encoded)


def _write_provenance(w, data, stamp: np.ndarray) -> None:
    """The ``pito_provenance`` metadata record and the ``calibration.json`` attachment."""
    meta = {"note": data.note, "simulated": json.dumps(data.simulated),
            "assembly": json.dumps(data.assembly), "calibration": json.dumps(
                None if data.calibration is None else
                {k: v for k, v in data.calibration.items() if k not in BULKY_RECORD_KEYS}, default=str)}
    w.add_metadata("pito_provenance", meta)
    if data.calibration is not None:
        t = int(stamp[0]) if stamp.size else 0
        w.add_attachment(0, t, "calibration.json", "application/json", json.dumps(data.calibration, default=str).encode())
        if "file" in data.calibration:
            w.add_attachment(0, t, "calibration.pitocal", "application/x-hdf5", record_file_bytes(data.calibration))


def _write_tf_static(topics: _Topics, data, stamp: np.ndarray) -> None:
    """``/tf_static``: one message with ``pito_core`` → ``pito_face_{i}`` (i = 1..6) of the recording's core."""
    edge = (data.assembly or {}).get("core_edge_m") or (data.calibration or {}).get("core_edge_m")
    core = CubeCore(edge) if edge else CubeCore()
    t0 = int(stamp[0]) if stamp.size else int(data.start_unix * 1e9)
    tfs = []
    for i in range(1, 7):
        T = core.face_pose(i)
        tfs.append({"header": {"stamp": {"sec": t0 // 10**9, "nanosec": t0 % 10**9}, "frame_id": ROS_CORE_FRAME},
                    "child_frame_id": ROS_FACE_FRAME.format(i=i),
                    "transform": {"translation": dict(zip("xyz", map(float, T[:3, 3]))),
                                  "rotation": dict(zip("xyzw", _quat_xyzw(T[:3, :3])))}})
    topics.writer.write_message("/tf_static", topics.schemas["tf2_msgs/msg/TFMessage"], {"transforms": tfs},
                                log_time=t0, publish_time=t0)
    topics.counts["/tf_static"] = 1


def _write_series(topics: _Topics, data, stamp: np.ndarray, raw_counts: bool, advance) -> None:
    """Raw counts, reference wrench and face wrenches, each sample with a finite value."""
    if raw_counts:
        topics.put("/pito/raw_counts", "std_msgs/msg/Int32MultiArray", stamp, _int32_array(data.counts))
    advance("mcap: counts")
    m = np.size(data.reference_time)
    if m:  # every reference record, at its own time (the cube's clock), tared
        rstamp = (np.round((data.start_unix + np.asarray(data.reference_time, float)) * 1e9)).astype(np.int64)
        topics.put("/pito/reference/wrench", "geometry_msgs/msg/WrenchStamped", rstamp,
                   _stamped(rstamp, "pito_reference", np.asarray(data.reference_wrench, float)))
    advance("mcap: reference")
    if data.face_wrenches is not None:
        for i in range(1, 7):
            fw = np.asarray(data.face_wrenches[:, i - 1], float)
            ok = np.isfinite(fw).all(axis=1)  # no message where there is no value
            topics.put(f"/pito/face_{i}/wrench", "geometry_msgs/msg/WrenchStamped", stamp[ok],
                       _stamped(stamp[ok], ROS_FACE_FRAME.format(i=i), fw[ok]))
            advance(f"mcap: face {i}")


def _write_contacts(topics: _Topics, c, stamp: np.ndarray, advance) -> None:
    """Each face's contact point, finger wrench and single-contact test, at the samples with a contact."""
    for i in range(1, 7):
        k = i - 1
        v = np.asarray(c.valid[:, k], bool)
        st = stamp[v]
        topics.put(f"/pito/face_{i}/contact/point", "geometry_msgs/msg/PointStamped", st,
                   _stamped(st, ROS_CORE_FRAME, c.point[v, k]))
        wr = np.concatenate([c.force[v, k], c.torsion[v, k, None] * c.normal[v, k]], axis=1)
        topics.put(f"/pito/face_{i}/contact/wrench", "geometry_msgs/msg/WrenchStamped", st,
                   _stamped(st, ROS_CORE_FRAME, wr))
        if getattr(c, "single_contact", None) is not None:
            flag = np.c_[c.single_contact[v, k], c.single_contact_p[v, k], c.single_contact_reason[v, k]]
            topics.put(f"/pito/face_{i}/contact/single_contact", "std_msgs/msg/Float64MultiArray", st,
                       _float64_array(flag))
        advance(f"mcap: contacts {i}")

"""ROS 2 MCAP export round trip: read back with the mcap reader and decoded with mcap_ros2 (no ROS install)."""

import json

import numpy as np
import pytest

pytest.importorskip("mcap_ros2", reason="the interop extra (pip install -e '.[interop]') is not installed")

from mcap.reader import make_reader  # noqa: E402
from mcap_ros2.decoder import DecoderFactory  # noqa: E402

from pito_core.frames import CubeCore  # noqa: E402
from pito_core.io import read_recording  # noqa: E402
from pito_core.interop import export_data  # noqa: E402

from .conftest import pito  # noqa: E402


@pytest.fixture(scope="module")
def mcap_file(interop_files):
    d, _, rec, _ = interop_files
    out = d / "grasp.mcap"
    pito("export", rec, "--mcap", out)
    return out, export_data(rec), rec


def read_all(path):
    msgs = {}
    with open(path, "rb") as fh:
        reader = make_reader(fh, decoder_factories=[DecoderFactory()])
        summary = reader.get_summary()
        for schema, channel, message, ros in reader.iter_decoded_messages():
            msgs.setdefault(channel.topic, []).append((schema.name, message.log_time, ros))
        meta = {m.name: m.metadata for m in reader.iter_metadata()}
        atts = {a.name: a.data for a in reader.iter_attachments()}
    return msgs, summary, meta, atts


def test_mcap_round_trip(mcap_file):
    path, data, rec = mcap_file
    msgs, summary, meta, atts = read_all(path)
    stamps = np.round((data.start_unix + data.time) * 1e9).astype(np.int64)
    for i in range(1, 7):
        topic = msgs[f"/pito/face_{i}/wrench"]
        assert len(topic) == data.n and topic[0][0] == "geometry_msgs/msg/WrenchStamped"
        got = np.array([[m.wrench.force.x, m.wrench.force.y, m.wrench.force.z,
                         m.wrench.torque.x, m.wrench.torque.y, m.wrench.torque.z] for _, _, m in topic])
        np.testing.assert_array_equal(got, data.face_wrenches[:, i - 1])
        assert {m.header.frame_id for _, _, m in topic} == {f"pito_face_{i}"}
        st = np.array([m.header.stamp.sec * 10**9 + m.header.stamp.nanosec for _, _, m in topic])
        np.testing.assert_array_equal(st, stamps)
        np.testing.assert_array_equal([t for _, t, _ in topic], stamps)
        pts = msgs.get(f"/pito/face_{i}/contact/point", [])
        v = data.contacts.valid[:, i - 1]
        assert len(pts) == int(v.sum())
        if pts:
            assert pts[0][0] == "geometry_msgs/msg/PointStamped" and pts[0][2].header.frame_id == "pito_core"
            got = np.array([[m.point.x, m.point.y, m.point.z] for _, _, m in pts])
            np.testing.assert_array_equal(got, data.contacts.point[v, i - 1])
            cw = msgs[f"/pito/face_{i}/contact/wrench"]
            np.testing.assert_array_equal([[m.wrench.force.x, m.wrench.force.y, m.wrench.force.z] for _, _, m in cw],
                                          data.contacts.force[v, i - 1])
            sc = msgs[f"/pito/face_{i}/contact/single_contact"]
            assert sc[0][0] == "std_msgs/msg/Float64MultiArray" and [t for _, t, _ in sc] == [t for _, t, _ in pts]
            got = np.array([list(m.data) for _, _, m in sc])
            np.testing.assert_array_equal(got, np.c_[data.contacts.single_contact[v, i - 1],
                                                     data.contacts.single_contact_p[v, i - 1],
                                                     data.contacts.single_contact_reason[v, i - 1]])
    assert sum(len(msgs.get(f"/pito/face_{i}/contact/point", [])) for i in range(1, 7)) > 0
    raw = msgs["/pito/raw_counts"]
    np.testing.assert_array_equal(np.array([list(m.data) for _, _, m in raw]), data.counts)
    ref = msgs["/pito/reference/wrench"]
    # every reference record of the recording, at its own time on the cube's clock
    assert len(ref) == data.reference_time.size == read_recording(rec).netft.size
    assert ref[0][2].header.frame_id == "pito_reference"
    got = np.array([[m.wrench.force.x, m.wrench.force.y, m.wrench.force.z,
                     m.wrench.torque.x, m.wrench.torque.y, m.wrench.torque.z] for _, _, m in ref])
    np.testing.assert_array_equal(got, data.reference_wrench)
    rstamps = np.round((data.start_unix + data.reference_time) * 1e9).astype(np.int64)
    np.testing.assert_array_equal([t for _, t, _ in ref], rstamps)
    assert (np.diff(stamps) > 0).all() and (np.diff(rstamps) > 0).all()  # one clock, never a repeated time
    (schema, _, tf), = msgs["/tf_static"]
    assert schema == "tf2_msgs/msg/TFMessage" and len(tf.transforms) == 6
    core = CubeCore(data.assembly["core_edge_m"])
    for i, t in enumerate(tf.transforms, start=1):
        assert t.header.frame_id == "pito_core" and t.child_frame_id == f"pito_face_{i}"
        T = core.face_pose(i)
        np.testing.assert_allclose([t.transform.translation.x, t.transform.translation.y, t.transform.translation.z],
                                   T[:3, 3], atol=1e-12)
        q = t.transform.rotation
        from scipy.spatial.transform import Rotation

        np.testing.assert_allclose(Rotation.from_quat([q.x, q.y, q.z, q.w]).as_matrix(), T[:3, :3], atol=1e-12)
    prov = meta["pito_provenance"]
    assert json.loads(prov["calibration"])["hash"] == data.calibration["hash"]
    assert json.loads(prov["assembly"])["name"] == "pito_mixed"
    full = json.loads(atts["calibration.json"])
    np.testing.assert_array_equal(full["matrix"], data.calibration["matrix"])
    # the calibration file itself, the same bytes as the recording embeds, the same content hash
    from pito_core.interop import calibration_from_bytes, calibration_hash, record_file_bytes

    assert atts["calibration.pitocal"] == record_file_bytes(read_recording(rec).meta["calibration"])
    assert calibration_hash(calibration_from_bytes(atts["calibration.pitocal"])) == data.calibration["hash"]
    assert summary.statistics.message_count == sum(len(v) for v in msgs.values())


def test_mcap_counts_only_without_calibration(interop_files, tmp_path):
    _, _, _, raw = interop_files
    out = tmp_path / "raw.mcap"
    r = pito("export", raw, "--mcap", out)
    assert "counts and reference only" in r.stdout
    msgs, _, meta, atts = read_all(out)
    assert set(msgs) == {"/pito/raw_counts", "/pito/reference/wrench", "/tf_static"}
    assert "calibration.json" not in atts and json.loads(meta["pito_provenance"]["calibration"]) is None


def test_no_mcap_message_carries_nan(mcap_file):
    """A cube sample before the first reference packet has no reference: no message for it (not a NaN one)."""
    path, data, _ = mcap_file
    msgs, *_ = read_all(path)
    for topic, rows in msgs.items():
        for _, _, m in rows:
            w = getattr(m, "wrench", None)
            if w is not None:
                v = [w.force.x, w.force.y, w.force.z, w.torque.x, w.torque.y, w.torque.z]
                assert np.isfinite(v).all(), f"{topic}: a message carries NaN"



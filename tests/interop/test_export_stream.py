"""The streamed export: chunked reading, blocks, bulk CDR and MCAP framing against the libraries' own."""

import numpy as np
import pytest

from pito_core.interop import ExportStream, export_data, export_files
from pito_core.io import RecordingChunks, read_recording
from pito_core.io._hdf5 import FileFormatError


def test_recording_chunks_match_the_whole_read(interop_files, tmp_path):
    _, _, rec, _ = interop_files
    whole, chunks = read_recording(rec), RecordingChunks(rec)
    assert (chunks.n_pito, chunks.n_netft) == (whole.pito.size, whole.netft.size)
    for name in ("seq", "time_us", "host_time"):
        np.testing.assert_array_equal(chunks.pito[name], whole.pito[name])
    np.testing.assert_array_equal(chunks.netft["rdt_seq"], whole.netft["rdt_seq"])
    assert chunks.events == whole.events and chunks.meta == whole.meta and chunks.complete
    rng = np.random.default_rng(3)
    for _ in range(20):
        a, b = np.sort(rng.integers(0, whole.pito.size + 1, 2))
        np.testing.assert_array_equal(chunks.rows("pito", a, b), whole.pito[a:b])
        a, b = np.sort(rng.integers(0, whole.netft.size + 1, 2))
        np.testing.assert_array_equal(chunks.rows("netft", a, b), whole.netft[a:b])
    with pytest.raises(ValueError, match="stream: expected 'pito' or 'netft'"):
        chunks.rows("cube", 0, 1)


@pytest.mark.parametrize("damage", ["truncate", "flip"])
def test_recording_chunks_refuse_and_recover_as_the_whole_read(interop_files, tmp_path, damage):
    _, _, rec, _ = interop_files
    data = bytearray(rec.read_bytes())
    if damage == "truncate":
        data = data[: len(data) // 2]
    else:
        data[len(data) // 3] ^= 0xFF
    bad = tmp_path / "bad.pitorec"
    bad.write_bytes(bytes(data))
    with pytest.raises(FileFormatError) as whole_error:
        read_recording(bad)
    with pytest.raises(FileFormatError) as chunk_error:
        RecordingChunks(bad)
    assert str(chunk_error.value) == str(whole_error.value)
    whole, chunks = read_recording(bad, recover=True), RecordingChunks(bad, recover=True)
    assert (chunks.n_pito, chunks.n_netft, chunks.damaged_bytes) == (whole.pito.size, whole.netft.size,
                                                                      whole.damaged_bytes)
    np.testing.assert_array_equal(chunks.rows("pito", 0, chunks.n_pito), whole.pito)


def test_blocks_cover_every_sample_once_and_match_the_whole_export(interop_files):
    _, _, rec, _ = interop_files
    whole = export_data(rec)
    stream = ExportStream(rec, block=700)
    blocks = list(stream.blocks())
    assert len(blocks) > 1
    r = read_recording(rec)
    assert sum(b.n for b in blocks) == r.pito.size == whole.n
    assert sum(b.reference_time.size for b in blocks) == r.netft.size == whole.reference_time.size
    for name in ("time", "tick", "counts", "reference", "face_wrenches", "reference_time", "reference_wrench",
                 "host_time", "reference_host_time"):
        np.testing.assert_array_equal(np.concatenate([getattr(b, name) for b in blocks]), getattr(whole, name),
                                      err_msg=name)
    for name in ("point", "valid", "single_contact_p"):
        np.testing.assert_array_equal(np.concatenate([getattr(b.contacts, name) for b in blocks]),
                                      getattr(whole.contacts, name), err_msg=name)
    assert (np.diff(stream.time) > 0).all() and (np.diff(stream.reference_time) > 0).all()


def test_bulk_cdr_is_byte_identical_to_mcap_ros2s_encoder():
    pytest.importorskip("mcap_ros2", reason="the interop extra is not installed")
    from mcap_ros2._dynamic import serialize_dynamic

    from pito_core.interop._mcap import MSGDEFS, _float64_array, _int32_array, _stamped

    def encoder(name):
        return serialize_dynamic(name, MSGDEFS[name])[name]

    rng = np.random.default_rng(7)
    n = 40
    stamps = rng.integers(0, 2**31 * 10**9, n)  # int32 seconds, as builtin_interfaces/Time
    wrench, point = encoder("geometry_msgs/msg/WrenchStamped"), encoder("geometry_msgs/msg/PointStamped")
    for frame in ("pito_core", "pito_face_3", "pito_reference", "f", "abcd", "abcdefg"):  # every alignment
        values = rng.normal(size=(n, 6))
        got = _stamped(stamps, frame, values)
        for k in range(n):
            head = {"stamp": {"sec": int(stamps[k] // 10**9), "nanosec": int(stamps[k] % 10**9)}, "frame_id": frame}
            v = values[k]
            want = wrench({"header": head, "wrench": {"force": dict(zip("xyz", v[:3])),
                                                       "torque": dict(zip("xyz", v[3:]))}})
            assert got[k].tobytes() == bytes(want)
        got = _stamped(stamps, frame, values[:, :3])
        want = point({"header": head, "point": dict(zip("xyz", values[-1, :3]))})
        assert got[-1].tobytes() == bytes(want)
    counts = rng.integers(-2**31, 2**31, (n, 36))
    got = _int32_array(counts)
    enc = encoder("std_msgs/msg/Int32MultiArray")
    for k in range(n):
        assert got[k].tobytes() == bytes(enc({"layout": {"dim": [], "data_offset": 0}, "data": counts[k].tolist()}))
    flags = rng.normal(size=(n, 3))
    got = _float64_array(flags)
    enc = encoder("std_msgs/msg/Float64MultiArray")
    for k in range(n):
        assert got[k].tobytes() == bytes(enc({"layout": {"dim": [], "data_offset": 0}, "data": flags[k].tolist()}))


def _messages(path):
    """``[(topic, log time, sequence, bytes)]`` of every message, a linear pass (CRCs checked), and the summary."""
    from mcap.records import Channel, Message, Statistics
    from mcap.stream_reader import StreamReader

    with open(path, "rb") as fh:
        records = list(StreamReader(fh, validate_crcs=True).records)
    topic = {r.id: r.topic for r in records if isinstance(r, Channel)}
    stats = [r for r in records if isinstance(r, Statistics)]
    return [(topic[r.channel_id], r.log_time, r.sequence, bytes(r.data)) for r in records if isinstance(r, Message)], \
        stats[0], topic


def test_streamed_mcap_and_nwb_hold_the_same_as_the_whole_export(interop_files, tmp_path):
    pytest.importorskip("mcap_ros2", reason="the interop extra is not installed")
    pytest.importorskip("pynwb", reason="the interop extra is not installed")
    import h5py

    from pito_core.interop import write_mcap

    _, _, rec, _ = interop_files
    whole = export_data(rec)
    counts = write_mcap(whole, tmp_path / "whole.mcap")
    out = export_files(rec, nwb=tmp_path / "s.nwb", mcap=tmp_path / "s.mcap", block=500)
    assert out["topics"] == counts and (out["n"], out["m"]) == (whole.n, whole.reference_time.size)
    assert counts["/pito/raw_counts"] == whole.n and counts["/pito/reference/wrench"] == whole.reference_time.size
    a, _, _ = _messages(tmp_path / "whole.mcap")
    b, stats, topic = _messages(tmp_path / "s.mcap")
    assert sorted(a) == sorted(b) and len(b) == sum(counts.values()) == stats.message_count
    assert stats.chunk_count > 1
    assert {topic[c]: k for c, k in stats.channel_message_counts.items()} == {t: k for t, k in counts.items() if k}
    with h5py.File(tmp_path / "s.nwb", "r") as f:  # pynwb reads it in test_nwb.py; here: every row written
        acq, beh = f["acquisition"], f["processing/behavior"]
        np.testing.assert_array_equal(acq["pito_raw_counts/data"][:], whole.counts)
        np.testing.assert_array_equal(acq["pito_host_time/data"][:], whole.host_time)
        np.testing.assert_array_equal(acq["reference_force/data"][:], whole.reference_wrench[:, :3])
        np.testing.assert_array_equal(acq["reference_torque/data"][:], whole.reference_wrench[:, 3:])
        for i in range(1, 7):
            np.testing.assert_array_equal(beh[f"face_{i}_force/data"][:], whole.face_wrenches[:, i - 1, :3])
            np.testing.assert_array_equal(beh[f"contact_face_{i}/point/data"][:], whole.contacts.point[:, i - 1])
            np.testing.assert_array_equal(beh[f"contact_face_{i}_valid/data"][:], whole.contacts.valid[:, i - 1])
            np.testing.assert_array_equal(beh[f"contact_face_{i}_single_contact_p/data"][:],
                                          whole.contacts.single_contact_p[:, i - 1])


def test_mcap_written_by_a_second_thread_is_the_same_file(interop_files, tmp_path):
    pytest.importorskip("mcap_ros2", reason="the interop extra is not installed")
    _, _, rec, _ = interop_files
    one = export_files(rec, mcap=tmp_path / "one.mcap", block=400)
    two = export_files(rec, mcap=tmp_path / "two.mcap", block=400, threads=2)
    assert one["topics"] == two["topics"]
    assert (tmp_path / "one.mcap").read_bytes() == (tmp_path / "two.mcap").read_bytes()
    with pytest.raises(ValueError, match="threads: expected 1 or 2"):
        export_files(rec, mcap=tmp_path / "three.mcap", threads=3)

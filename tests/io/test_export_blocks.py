"""CSV and .mat exports written block by block: the same files from a recording read whole or in chunks.

The recording is the one ``pito record`` wrote (tests/analysis/data, SIMULATED devices); the
blocks are made small so that every export crosses many block boundaries.
"""

import lzma
from pathlib import Path

import numpy as np
import pytest
from scipy.io import loadmat

import pito_core.io._export as export
from pito_core.io import RecordingChunks, export_recording_csv, export_recording_mat, read_recording, read_recording_csv
from pito_core.io._mat import Mat5Writer
from pito_core.pipeline import recording_times

RECORDED = Path(__file__).parents[1] / "analysis" / "data" / "recorded_seed7.pitorec.xz"


@pytest.fixture
def recorded(tmp_path, monkeypatch):
    monkeypatch.setattr(export, "BLOCK", 997)  # a prime: blocks end anywhere in the recorder's chunks
    path = tmp_path / "rec.pitorec"
    path.write_bytes(lzma.decompress(RECORDED.read_bytes()))
    return path


def test_chunked_csv_equals_the_whole_recordings_and_reads_back(recorded, tmp_path):
    whole, chunks = read_recording(recorded), RecordingChunks(recorded)
    times = recording_times(whole)
    for (a, b) in zip(times, recording_times(chunks)):
        np.testing.assert_array_equal(a, b)
    for stream, t in zip(("pito", "netft"), times):
        export_recording_csv(whole, tmp_path / "a.csv", stream, t)
        export_recording_csv(chunks, tmp_path / "b.csv", stream, t)
        assert (tmp_path / "a.csv").read_bytes() == (tmp_path / "b.csv").read_bytes()
        cols = read_recording_csv(tmp_path / "b.csv", stream)
        rows = whole.pito if stream == "pito" else whole.netft
        assert cols["time"].size == rows.size > 1000  # every sample, across many blocks
        np.testing.assert_array_equal(cols["time"], t)
        np.testing.assert_array_equal(cols["host_time"], rows["host_time"])
    np.testing.assert_array_equal(read_recording_csv(tmp_path / "b.csv", "netft")["fz"], whole.netft["wrench"][:, 2])


def test_chunked_mat_holds_every_sample_with_its_type(recorded, tmp_path):
    whole = read_recording(recorded)
    tc, tr = recording_times(whole)
    export_recording_mat(RecordingChunks(recorded), tmp_path / "r.mat", (tc, tr))
    m = loadmat(tmp_path / "r.mat")
    assert str(m["format"][0]) == "pito-recording" and int(m["version"][0, 0]) == 1
    assert m["pito_counts"].dtype == np.int32 and m["pito_counts"].shape == (whole.pito.size, 36)
    np.testing.assert_array_equal(m["pito_counts"], whole.pito["counts"])
    np.testing.assert_array_equal(m["pito_time_us"][:, 0], whole.pito["time_us"])
    np.testing.assert_array_equal(m["ati_wrench"], whole.netft["wrench"])
    np.testing.assert_array_equal(m["ati_rdt_seq"][:, 0], whole.netft["rdt_seq"])
    np.testing.assert_array_equal(m["pito_time"][:, 0], tc)
    np.testing.assert_array_equal(m["ati_time"][:, 0], tr)
    assert m["meta_json"][0].startswith("{")


def test_mat_writer_refuses_a_variable_beyond_4_GiB_and_rows_outside(tmp_path):
    with open(tmp_path / "x.mat", "w+b") as fh:
        w = Mat5Writer(fh, "test")
        with pytest.raises(ValueError, match="pito_counts: .* beyond a MATLAB v5 variable's 4 GiB"):
            w.matrix("pito_counts", (30_000_000, 36), np.int32)
        m = w.matrix("a", (3, 2), np.float64)
        with pytest.raises(ValueError, match="a: rows 2..4 outside 0..3"):
            w.fill(m, 2, np.zeros((2, 2)))
        w.fill(m, 0, [[1, 2], [3, 4], [5, 6]])
        w.value("s", "héllo")
        w.close()
    got = loadmat(tmp_path / "x.mat")
    np.testing.assert_array_equal(got["a"], [[1, 2], [3, 4], [5, 6]])
    assert str(got["s"][0]) == "héllo"


def test_a_recording_without_reference_exports_empty_reference_variables(tmp_path):
    from pito_core.io import RecordingWriter

    path = tmp_path / "cube_only.pitorec"
    with RecordingWriter(path, {"simulated": True}) as w:
        n = 50
        w.append_pito(np.arange(n), np.arange(n) * 1000, np.arange(n) * 1e-3, np.ones((n, 36), np.int32))
    rec = RecordingChunks(path)
    export_recording_mat(rec, tmp_path / "r.mat", recording_times(rec))
    m = loadmat(tmp_path / "r.mat")
    assert m["pito_counts"].shape == (50, 36) and m["ati_wrench"].size == 0 and m["ati_time"].size == 0


def test_progress_goes_forward_to_the_end_of_each_file(recorded, tmp_path):
    from pito_core.io import export_recording_files

    rec = RecordingChunks(recorded)
    seen = []
    export_recording_files(rec, str(tmp_path / "r"), str(tmp_path / "r.mat"), recording_times(rec),
                           progress=lambda f, text: seen.append((f, text.split(":")[0])))
    for name in ("r_pito.csv", "r_ati.csv", "r.mat"):
        fractions = [f for f, file in seen if file.endswith(name)]
        assert len(fractions) > 5 and fractions == sorted(fractions) and fractions[-1] == 1.0, name

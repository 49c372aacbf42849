"""Every pito file format: round trip, wrong kind, truncated, future version.

Sessions and calibrations (HDF5), session CSV, recordings (binary), recording CSV and .mat.
Data: a small simulated random sensor (labelled simulated by the simulator).
"""

from __future__ import annotations

import functools
import tempfile
import warnings
from pathlib import Path

import h5py
import numpy as np
import pytest

from pito_core.calibration import CalibrationSession, calibrate, load_calibration
from pito_core.io import (
    FileFormatError,
    Recording,
    RecordingWriter,
    export_recording_csv,
    export_recording_mat,
    read_recording_csv,
    write_session,
)
from pito_core.sim import random_sensor, random_sensor_session

_TMP = Path(tempfile.mkdtemp(prefix="pito-io-"))


@functools.lru_cache(maxsize=None)
def _files():
    s, _ = random_sensor_session(random_sensor(5), "frame_hole", 3, 40, n_tare=30, seed=1)
    sp = _TMP / "s.pitosession"
    write_session(sp, s)
    cal = calibrate(s, "face_to_face")
    cp = _TMP / "c.pitocal"
    cal.save(cp)
    rp = _TMP / "r.pitorec"
    rng = np.random.default_rng(2)
    with RecordingWriter(rp, {"simulated": True}, flush_interval=1.0, fsync=False) as w:
        n = 20
        w.append_pito(np.arange(n), np.arange(n) * 1000, np.arange(n) * 1e-3, rng.integers(-9, 9, (n, 36)))
        w.append_netft(np.arange(n), np.arange(n), np.zeros(n), np.arange(n) * 1e-3, rng.normal(size=(n, 6)))
        w.append_event({"kind": "tare"})
    return {"session": sp, "calibration": cp, "recording": rp}, s, cal


def _load(kind, path):
    return {"session": CalibrationSession.load, "calibration": load_calibration, "recording": Recording}[kind](path)


def test_session_round_trip():
    files, s, _ = _files()
    back = CalibrationSession.load(files["session"])
    np.testing.assert_array_equal(back.counts, s.counts)
    np.testing.assert_array_equal(back.reference, s.reference)
    np.testing.assert_array_equal(back.loaded, s.loaded)
    assert (back.flange, back.connected_face) == (s.flange, s.connected_face)
    lazy = CalibrationSession.load(files["session"], lazy=True)
    assert sum(len(b.counts) for b in lazy.iter_blocks(7)) == len(s.counts)


def test_calibration_round_trip():
    files, _, cal = _files()
    back = load_calibration(files["calibration"])
    np.testing.assert_array_equal(back.matrix, cal.matrix)
    np.testing.assert_array_equal(back.offset, cal.offset)
    assert back.method == cal.method and list(back.output_faces) == list(cal.output_faces)
    assert (back.covariance is None) == (cal.covariance is None)


def test_session_csv_round_trip():
    _, s, _ = _files()
    path = _TMP / "s.csv"
    s.to_csv(path)
    back = CalibrationSession.from_csv(path, flange=s.flange, connected_face=s.connected_face, T_core_ati=s.T_core_ati)
    np.testing.assert_array_equal(back.counts, s.counts)
    np.testing.assert_allclose(back.reference, s.reference, rtol=1e-12, atol=0)
    np.testing.assert_array_equal(back.loaded, s.loaded)


def test_session_csv_missing_column_names_it(tmp_path):
    bad = tmp_path / "bad.csv"
    bad.write_text("time,g1\n0,1\n")
    with pytest.raises(ValueError, match="missing columns"):
        CalibrationSession.from_csv(bad, flange="frame", connected_face=1)


def test_recording_round_trip_and_csv_mat_export(tmp_path):
    files, _, _ = _files()
    rec = Recording(files["recording"])
    assert rec.meta["simulated"] is True
    csv_path = tmp_path / "r.csv"
    export_recording_csv(rec, csv_path)
    table = read_recording_csv(csv_path)
    counts = np.column_stack([v for k, v in table.items() if k.startswith("g")]) if any(
        k.startswith("g") for k in table) else None
    assert counts is None or counts.shape == (20, 36)
    assert all(len(v) == 20 for v in table.values())
    mat_path = tmp_path / "r.mat"
    export_recording_mat(rec, mat_path)
    from scipy.io import loadmat  # scipy: only to read the .mat back

    assert any(not k.startswith("__") for k in loadmat(mat_path))


@pytest.mark.parametrize(("kind", "other"), [("session", "calibration"), ("calibration", "session"),
                                             ("calibration", "recording"), ("recording", "session")])
def test_wrong_kind_is_refused(kind, other):
    files, _, _ = _files()
    with pytest.raises(FileFormatError):
        _load(kind, files[other])


@pytest.mark.parametrize("kind", ["session", "calibration", "recording"])
def test_truncated_is_refused(kind, tmp_path):
    files, _, _ = _files()
    raw = files[kind].read_bytes()
    bad = tmp_path / f"bad-{kind}"
    bad.write_bytes(raw[: len(raw) * 2 // 3])
    with pytest.raises(FileFormatError):
        _load(kind, bad)


@pytest.mark.parametrize("kind", ["session", "calibration"])
def test_future_version_is_refused_naming_the_version(kind, tmp_path):
    files, _, _ = _files()
    bad = tmp_path / f"future-{kind}"
    bad.write_bytes(files[kind].read_bytes())
    with h5py.File(bad, "a") as f:
        f.attrs["version"] = 99
        del f.attrs["pito_checksums"]
    with warnings.catch_warnings(), pytest.raises(FileFormatError, match="version 99"):
        warnings.simplefilter("ignore")
        _load(kind, bad)

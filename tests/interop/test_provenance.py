"""Provenance: the calibration (matrix, offset, method, date, sha256) and assembly travel with every file."""

import numpy as np
import pytest

from pito_core.io import read_recording
from pito_core.interop import (
    calibration_from_record,
    calibration_hash,
    calibration_record,
    export_data,
    recording_calibration,
)
from pito_core.pipeline import replay_recording

from .conftest import ASSEMBLY, ideal_calibration


def test_hash_is_stable_and_sees_every_part():
    a, b = ideal_calibration(), ideal_calibration()
    assert calibration_hash(a) == calibration_hash(b)
    assert calibration_hash(a).startswith("sha256:") and len(calibration_hash(a)) == 7 + 64
    c = ideal_calibration()
    c.matrix = c.matrix.copy()
    c.matrix[3, 7] += 1e-12
    assert calibration_hash(c) != calibration_hash(a)
    d = ideal_calibration()
    d.offset = d.offset + 1.0
    assert calibration_hash(d) != calibration_hash(a)
    e = ideal_calibration()
    e.meta["date"] = "2026-11-24T00:00:00+00:00"
    assert calibration_hash(e) != calibration_hash(a)


def test_record_round_trip_and_tamper_check():
    cal = ideal_calibration(1.5)
    rec = calibration_record(cal, "x.h5")
    back = calibration_from_record(rec)
    np.testing.assert_array_equal(back.matrix, cal.matrix)
    np.testing.assert_array_equal(back.offset, cal.offset)
    assert calibration_hash(back) == rec["hash"] and back.method == "ideal"
    import copy

    bad = copy.deepcopy(rec)
    bad["matrix"][0][0] += 1.0
    with pytest.raises(ValueError, match="matrix"):
        calibration_from_record(bad)
    bad = dict(rec, hash="sha256:" + "0" * 64)
    with pytest.raises(ValueError, match="hash"):
        calibration_from_record(bad)
    bad = dict(rec, file=dict(rec["file"], content=rec["file"]["content"][:-8] + "AAAAAAAA"))
    with pytest.raises(ValueError, match="file: stored sha256"):
        calibration_from_record(bad)
    legacy = {k: v for k, v in rec.items() if k != "file"}  # provenance version 1: the linear part only
    legacy["matrix"][0][0] += 1.0
    with pytest.raises(ValueError, match="hash"):
        calibration_from_record(legacy)
    with pytest.raises(ValueError, match="missing field"):
        calibration_from_record({"method": "ideal"})


def test_recording_embeds_calibration_and_assembly(interop_files):
    _, cal_path, rec, raw = interop_files
    meta = read_recording(rec).meta
    assert meta["calibration"]["hash"] == calibration_hash(ideal_calibration())
    assert meta["calibration"]["method"] == "ideal" and meta["calibration"]["date"].startswith("2026-11-23")
    assert meta["assembly"]["name"] == ASSEMBLY and set(meta["assembly"]["faces"]) == {str(i) for i in range(1, 7)}
    assert "calibration" not in read_recording(raw).meta


def test_export_uses_the_embedded_calibration_or_says_it_recomputed(interop_files):
    _, _, rec, raw = interop_files
    own = export_data(rec)
    assert "recording's own calibration" in own.note and own.face_wrenches is not None
    bundle, _ = replay_recording(rec, ideal_calibration(), ASSEMBLY)
    np.testing.assert_allclose(own.face_wrenches, bundle.face_wrenches)
    other = ideal_calibration(2.0)
    re = export_data(rec, other, calibration_source="double.h5", contacts=False)
    assert "recomputed with double.h5" in re.note and "instead of the recording's own" in re.note
    assert re.calibration["hash"] == calibration_hash(other)
    # same tare events, a matrix twice as large: twice the wrenches
    np.testing.assert_allclose(re.face_wrenches, 2 * own.face_wrenches, rtol=1e-9, atol=1e-9)
    none = export_data(raw)
    assert none.face_wrenches is None and none.contacts is None and none.calibration is None
    assert "counts and reference only" in none.note and none.counts.shape[1] == 36
    _, note = recording_calibration({}, None)
    assert "no calibration" in note


def test_replay_and_export_say_which_calibration(interop_files, tmp_path):
    import subprocess
    import sys

    from .conftest import pito

    d, cal, rec, _ = interop_files
    assert "computed with the recording's own calibration (ideal" in pito("replay", rec, "--speed", "inf").stdout
    other = tmp_path / "double.h5"
    ideal_calibration(2.0).save(other)
    out = pito("replay", rec, "--speed", "inf", "--calibration", other).stdout
    assert f"recomputed with {other}" in out and "instead of the recording's own" in out
    r = subprocess.run([sys.executable, "-c", "import sys; from pito_core.cli import main; sys.exit(main())",
                        "export", str(rec)], capture_output=True, text=True)
    assert r.returncode == 1 and "--nwb" in r.stderr

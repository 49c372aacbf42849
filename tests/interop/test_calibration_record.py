"""One calibration record: the calibration file's exact bytes, for every model kind and method.

Property: for each method × model (the papers' linear fit, the polynomial correction), the
record made from a saved file carries that file's bytes; read back (also after a JSON round
trip, as a recording's header stores it) it is the same calibration — same content hash,
bitwise the same wrenches and covariance — through the calibration file's own reader.
"""

import json
import sys
from pathlib import Path

import numpy as np
import pytest

from pito_core.calibration import calibrate, load_calibration
from pito_core.interop import (
    calibration_from_bytes,
    calibration_from_record,
    calibration_hash,
    calibration_record,
    record_file_bytes,
)

sys.path.insert(0, str(Path(__file__).parents[1] / "calibration"))
from gen import CASES, make_session, true_sensitivity  # noqa: E402


@pytest.mark.parametrize("model", ["linear", "poly"])
@pytest.mark.parametrize("method", sorted(CASES))
def test_every_model_kind_round_trips_through_the_record(method, model, tmp_path):
    K = true_sensitivity(3)
    s = make_session(K, k=300, connected_face=3, noise=2.0, **CASES[method])
    cal = calibrate(s, method, model=model)
    assert (cal.correction is not None) == (model == "poly") and cal.covariance is not None
    path = tmp_path / "c.pitocal"
    cal.save(path)
    rec = json.loads(json.dumps(calibration_record(load_calibration(path), str(path))))  # as a header stores it
    assert record_file_bytes(rec) == path.read_bytes()  # the file itself
    assert rec["model"] == model and rec["hash"] == calibration_hash(cal)
    back = calibration_from_record(rec)
    assert calibration_hash(back) == calibration_hash(cal)
    counts = s.counts[:: max(1, len(s.counts) // 40)]
    W, C = cal.wrenches(counts, return_cov=True)
    Wb, Cb = back.wrenches(counts, return_cov=True)
    np.testing.assert_array_equal(Wb, W)  # the correction travelled
    np.testing.assert_array_equal(Cb, C)  # and the covariance
    assert calibration_hash(calibration_from_bytes(record_file_bytes(rec))) == rec["hash"]


def test_a_calibration_fitted_in_memory_is_embedded_as_save_writes_it(tmp_path):
    s = make_session(true_sensitivity(4), k=300, connected_face=3, noise=2.0, **CASES["total"])
    cal = calibrate(s, "total", model="poly")
    rec = calibration_record(cal)  # no file: serialised by Calibration.save
    back = calibration_from_record(rec)
    assert calibration_hash(back) == calibration_hash(cal) and rec["source"] is None
    np.testing.assert_array_equal(back.wrenches(s.counts[:20]), cal.wrenches(s.counts[:20]))
    other = tmp_path / "other.pitocal"  # a source holding another calibration is not embedded
    calibrate(s, "total", model="linear").save(other)
    assert record_file_bytes(calibration_record(cal, str(other))) != other.read_bytes()


def test_a_damaged_embedded_file_is_named():
    s = make_session(true_sensitivity(5), k=200, connected_face=3, noise=2.0, **CASES["total"])
    rec = calibration_record(calibrate(s, "total", model="linear"))
    import base64
    import hashlib

    junk = b"not an HDF5 file"
    bad = dict(rec, file=dict(rec["file"], content=base64.b64encode(junk).decode(),
                              sha256=hashlib.sha256(junk).hexdigest()))
    with pytest.raises(ValueError, match="calibration record: file"):
        calibration_from_record(bad)

"""The validation pass confirms a polynomial correction or gives the linear fit (confirm_model).

Random cubes of the tests' own (gen.py), not pito_core.sim: on a linear cube a forced
polynomial only fits noise, and a fresh session shows it; on a cube whose gauges bend, the
correction wins on fresh loads and is kept.
"""

import numpy as np
import pytest

from gen import CASES, make_session, true_sensitivity
from test_model_groups import _saturating

from pito_core.calibration import calibrate, confirm_model, validation_figures


@pytest.mark.parametrize("method", ["unloaded_frame", "total"])
def test_a_correction_that_only_fits_noise_gives_way_on_the_validation_pass(method):
    K = true_sensitivity(5, coupling=0.05)
    kw = dict(CASES[method], connected_face=6, noise=4.0, counts_dtype=float)
    train = make_session(K, k=150, seed=11, **kw)
    fresh = make_session(K, k=100, seed=12, **kw)
    forced = calibrate(train, method, model="poly")
    assert forced.correction is not None
    cal, figures = confirm_model(forced, fresh)
    assert cal.correction is None and cal.model.name == "linear"
    assert "lost on the validation pass" in cal.model.reason and "face " in cal.model.reason
    np.testing.assert_array_equal(cal.matrix, forced.linear_alternative().matrix)
    ref = validation_figures(cal, fresh)
    np.testing.assert_allclose(figures.rmse_force, ref.rmse_force, equal_nan=True)
    lin = validation_figures(forced.linear_alternative(), fresh)
    poly = validation_figures(forced, fresh)
    lost = (poly.rmse_force > lin.rmse_force) | (poly.rmse_torque > lin.rmse_torque)
    assert lost.any()  # the reason it gave way is on the figures


def test_a_correction_that_wins_on_fresh_loads_is_kept():
    method = "unloaded_frame"
    K = true_sensitivity(31, coupling=0.05)
    kw = dict(CASES[method], connected_face=6, noise=2.0, response=_saturating(31, K, 0.08), counts_dtype=float)
    train = make_session(K, k=800, seed=32, **kw)
    fresh = make_session(K, k=150, seed=33, **kw)
    auto = calibrate(train, method)
    assert auto.model.name == "poly", auto.model.reason
    cal, figures = confirm_model(auto, fresh)
    assert cal is auto
    lin = validation_figures(auto.linear_alternative(), fresh)
    assert np.nanmax(figures.rmse_force) < np.nanmax(lin.rmse_force)


def test_a_linear_calibration_passes_through():
    K = true_sensitivity(7)
    kw = dict(CASES["total"], connected_face=6, counts_dtype=float)
    train, fresh = make_session(K, k=100, seed=1, **kw), make_session(K, k=60, seed=2, **kw)
    cal = calibrate(train, "total", model="linear")
    out, figures = confirm_model(cal, fresh)
    assert out is cal and np.isfinite(figures.worst_force)


def test_given_the_training_sessions_the_linear_fit_keeps_its_own_error_model():
    """With ``sessions`` the linear fit that replaces a lost correction is fitted again: the same
    matrix, and the error model of the linear fit (not the correction's, whose residuals are smaller)."""
    method = "total"
    K = true_sensitivity(5, coupling=0.05)
    kw = dict(CASES[method], connected_face=6, noise=4.0, counts_dtype=float)
    train, fresh = make_session(K, k=150, seed=11, **kw), make_session(K, k=100, seed=12, **kw)
    forced = calibrate(train, method, model="poly")
    cal, _ = confirm_model(forced, fresh, sessions=train, fit_options={"block_size": 4096})
    assert cal.correction is None and "lost on the validation pass" in cal.model.reason
    own = calibrate(train, method, model="linear")
    np.testing.assert_allclose(cal.matrix, forced.linear_alternative().matrix, rtol=1e-9, atol=1e-12)
    np.testing.assert_array_equal(cal.covariance.variance_coef, own.covariance.variance_coef)


def test_pito_calibrate_validation_pass_gives_way_and_is_stored(tmp_path, capsys):
    """``pito calibrate --validation``: from session files, a correction the fresh session does not confirm (here
    the gauges' bend of the fitted session is gone in the fresh one) gives way to the linear fit; the pass's
    figures are printed and stored in the file, named by its session."""
    from pito_core.calibration import Calibration
    from pito_core.cli import main

    method = "unloaded_frame"
    K = true_sensitivity(31, coupling=0.05)
    kw = dict(CASES[method], connected_face=6, noise=2.0, counts_dtype=float)
    make_session(K, k=800, seed=32, response=_saturating(31, K, 0.08), **kw).save(tmp_path / "fit.h5")
    make_session(K, k=150, seed=33, **kw).save(tmp_path / "fresh.h5")
    out = tmp_path / "c.pitocal"
    assert main(["calibrate", str(tmp_path / "fit.h5"), "--validation", str(tmp_path / "fresh.h5"), "-m", method,
                 "-o", str(out)]) == 0
    text = capsys.readouterr().out
    assert "lost on the validation pass" in text and "validation pass (fresh.h5;" in text
    cal = Calibration.load(out)
    assert cal.model.name == "linear" and cal.correction is None
    stored = cal.meta["validation_pass"]
    assert stored["sessions"] == ["fresh.h5"] and stored["n_sessions"] == 1 and stored["n_single"] > 0
    assert cal.meta["validation"]["holdout"] == 0.2  # the held-out split's figures stay beside it


def test_pito_calibrate_refuses_a_validation_pass_it_fits(tmp_path, capsys):
    from pito_core.cli import main

    path = tmp_path / "s.h5"
    path.write_bytes(b"")  # refused before it is read
    assert main(["calibrate", str(path), "--validation", str(path), "-m", "total", "-o", str(tmp_path / "c")]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--validation" in err[0] and "s.h5" in err[0]

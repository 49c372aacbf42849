"""Loads beyond the box the correction was trained on: how it is tested, and its error bars there.

A short session (a few hundred samples a face) leaves a later session's loads beyond its range
often. The correction then continues along an extension (``_poly.PolyCorrection``), then fades to
the linear fit. Its held-out test (``_cv.extension_errors``) once shrank the box to hold 70 % of the
rows *at rest included*, so a session of long rests tested the extension from a box holding a
handful of loads; and the error model knew nothing of the extension, so its 95 % intervals covered
38-86 % of the samples beyond the box (BenchCube, k = 800 a face; 48 % for ``face_to_face`` at 400).
"""

import warnings

import numpy as np
import pytest

from pito_bench._cubes import BenchCube, cube_session
from pito_core.calibration import calibrate, load_calibration
from pito_core.calibration._cv import EXTRAPOLATION_QUANTILE, shrunk_box

FACES = list(range(1, 7))


def test_the_box_is_shrunk_to_hold_a_share_of_the_loads_not_of_the_rest():
    rng = np.random.default_rng(0)
    loads = rng.uniform(-1.0, 1.0, (300, 6))
    rest = rng.normal(0.0, 1e-3, (3000, 6))  # ten times as many samples at rest
    u = np.concatenate([rest, loads])
    loaded = np.r_[np.zeros(3000, bool), np.ones(300, bool)]
    lower, upper = u.min(axis=0), u.max(axis=0)
    shrink, t = shrunk_box(u, lower, upper, loaded)
    inside = t[loaded] >= 1.0
    assert inside.mean() == pytest.approx(EXTRAPOLATION_QUANTILE, abs=0.02)
    assert np.all(t[~loaded] == 1.0)  # the rest stays inside, in the refit
    shrink_all, _ = shrunk_box(u, lower, upper)  # every row counted: the box holds almost no load
    assert shrink_all < 0.1 < 0.8 < shrink


def _split_cover(cal, test, F):
    """Coverage of the 95 % intervals of the loaded samples inside and beyond the correction's box."""
    ld = test.loaded.any(axis=1)
    t = cal.tare(test.counts[~ld])
    W, cov = t.wrenches(test.counts[ld], return_cov=True)
    z = np.abs(W - F[ld]) / np.sqrt(np.diagonal(cov, axis1=-2, axis2=-1))
    z = z[:, cal.has_output]
    _, ray = cal.correction.ray(test.counts[ld] - t.offset)
    out = ray < 1.0
    return out.mean(), (z[~out] <= 1.959964).mean(), (z[out] <= 1.959964).mean()


@pytest.mark.parametrize("method", ["face_to_face", "loaded_frame"])
def test_intervals_widen_beyond_the_trained_loads(method, tmp_path):
    cube = BenchCube("saturation", 0.10, 0.1, seed=5)  # SIMULATED, independent of pito_core.sim
    train, _ = cube_session(cube, "frame_hole", 6, FACES, 400, seed=1)
    test, F = cube_session(cube, "frame_hole", 6, FACES, 400, seed=101, offset_shift=50.0, n_rest=1000)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cal = calibrate(train, method)
    assert cal.model.name == "poly"
    assert np.any(cal.covariance.beyond_cov)
    share, inside, beyond = _split_cover(cal, test, F)
    assert share > 0.15  # a quarter to a third of the later session's loads lie beyond the box
    assert inside > 0.92
    assert beyond > 0.92  # 48.5 % (face_to_face) and 82.3 % (loaded_frame) before
    cal.save(tmp_path / "cal.h5")
    back = load_calibration(tmp_path / "cal.h5")
    np.testing.assert_array_equal(back.covariance.beyond_cov, cal.covariance.beyond_cov)
    ld = test.loaded.any(axis=1)
    _, c1 = cal.wrenches(test.counts[ld][:50], return_cov=True)
    _, c2 = back.wrenches(test.counts[ld][:50], return_cov=True)
    np.testing.assert_allclose(c2, c1, rtol=1e-12)

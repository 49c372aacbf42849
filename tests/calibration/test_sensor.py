"""``fit_sensor`` on sensors unlike the cube: other channel counts, glitches, drift between segments."""

import numpy as np
import pytest

from pito_core.calibration import SensorFit, fit_sensor
from pito_core.calibration._sensor import FAMILIES

FS = np.array([15.0, 15.0, 15.0, 0.1, 0.1, 0.1])


def sensor_data(seed, m, n_seg, seg_len, sat=0.0, drift=0.0, glitches=0, ref_noise=0.0):
    """Random segments of held loads on an ``m``-channel sensor: counts, wrench, groups."""
    rng = np.random.default_rng(seed)
    S = rng.normal(size=(m, 6)) * 1000 / FS  # counts per N, N·m
    W = np.repeat(rng.uniform(-1, 1, size=(n_seg, 6)) * FS, seg_len, axis=0)
    W += rng.normal(scale=0.02, size=W.shape) * FS  # the load wanders within a segment
    lin = W @ S.T
    full = np.abs(S) @ FS
    counts = lin - sat * full * (lin / full) ** 3 + rng.normal(scale=2.0, size=lin.shape)
    groups = np.repeat(np.arange(n_seg), seg_len)
    counts += drift * rng.normal(size=(n_seg, m))[groups]  # offset drift between segments
    bad = rng.choice(len(W), size=glitches, replace=False)
    counts[bad] += rng.normal(scale=50.0, size=(glitches, m))
    return counts, W + rng.normal(scale=ref_noise, size=W.shape) * FS, groups, W


def _split(seg_len, *arrays, n_train):
    cut = n_train * seg_len
    return [a[:cut] for a in arrays], [a[cut:] for a in arrays]


def _rmse(fit, counts, truth):
    return np.sqrt(np.mean(((fit.predict(counts) - truth) / FS) ** 2))


@pytest.mark.parametrize("m", [6, 8, 24])
def test_saturating_sensor_gets_the_polynomial(m):
    c, w, g, truth = sensor_data(m, m, 60, 80, sat=0.1)
    (ct, wt, gt, _), (ch, _, _, th) = _split(80, c, w, g, truth, n_train=40)
    auto, lin = fit_sensor(ct, wt, gt), fit_sensor(ct, wt, gt, model="linear")
    assert isinstance(auto, SensorFit) and auto.model == "poly" and lin.model == "linear"
    # ≤ 0.65: the held-out segments reach beyond the training range, where the correction is
    # drawn back into it with the linear fit's slope beyond (_poly.py)
    assert _rmse(auto, ch, th) <= 0.65 * _rmse(lin, ch, th)
    assert auto.predict(ch).shape == (len(ch), 6) and auto.n_features_in_ == m


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_linear_sensor_with_drift_and_glitches_keeps_the_affine_fit(seed):
    """A richer model only overfits here (few segments, 24 channels, drift, glitches)."""
    c, w, g, truth = sensor_data(seed, 24, 30, 15, drift=20.0, glitches=5, ref_noise=0.005)
    (ct, wt, gt, _), (ch, _, _, th) = _split(15, c, w, g, truth, n_train=20)
    auto, lin = fit_sensor(ct, wt, gt), fit_sensor(ct, wt, gt, model="linear")
    assert auto.model == "linear", auto.choice.reason
    assert _rmse(auto, ch, th) <= 1.02 * _rmse(lin, ch, th)
    forced = fit_sensor(ct, wt, gt, model="poly")
    assert forced.model == "poly" and forced.choice.requested == "poly"


def test_linear_model_is_plain_affine_least_squares():
    c, w, g, _ = sensor_data(5, 7, 20, 30)
    fit = fit_sensor(c, w, g, model="linear")
    A = np.hstack([np.ones((len(c), 1)), c])
    X = np.linalg.lstsq(A, w, rcond=None)[0]
    np.testing.assert_allclose(fit.predict(c), A @ X, atol=1e-9 * np.abs(w).max())


def test_fit_sensor_refuses_bad_input():
    c, w, g, _ = sensor_data(5, 7, 10, 10)
    with pytest.raises(ValueError, match=r"wrench: expected shape"):
        fit_sensor(c, w[:-1])
    with pytest.raises(ValueError, match=r"groups: expected shape"):
        fit_sensor(c, w, g[:-1])
    with pytest.raises(ValueError, match=r"model: expected one of"):
        fit_sensor(c, w, model="spline")
    with pytest.raises(ValueError, match=r"counts: expected shape \(N, 7\)"):
        fit_sensor(c, w).predict(c[:, :3])


def _bending_sensor(seed, m, n_seg, seg_len, bend, per_group=10):
    """Counts that bend quadratically with the load (an even response, which no cube term models);
    ``per_group`` held loads per group."""
    rng = np.random.default_rng(seed)
    S = rng.normal(size=(m, 6)) * 1000 / FS
    W = np.repeat(rng.uniform(-1, 1, size=(n_seg, 6)) * FS, seg_len, axis=0)
    W += rng.normal(scale=0.02, size=W.shape) * FS
    lin = W @ S.T
    full = np.abs(S) @ FS
    counts = lin + bend * full * (lin / full) ** 2 + rng.normal(scale=2.0, size=lin.shape)
    return counts, W, np.repeat(np.arange(n_seg) // per_group, seg_len)


def test_few_groups_are_left_out_one_at_a_time():
    """10 groups: 10 folds (leave one group out); the correction (a family of ``FAMILIES``, per output
    group) beats the affine fit on groups never seen (measured 0.59×); 3 groups are too few for a
    standard error: the affine fit."""
    c, w, g = _bending_sensor(3, 6, 120, 5, bend=0.1)
    train = g < 10
    auto = fit_sensor(c[train], w[train], g[train])
    lin = fit_sensor(c[train], w[train], g[train], model="linear")
    assert auto.choice.n_folds == 10 and auto.model == "poly", auto.choice.reason
    assert [m == "linear" for m in auto.row_model_] == [a is None for a in auto.choice.row_alpha]
    assert set(auto.row_model_) <= {"linear", *FAMILIES}
    assert _rmse(auto, c[~train], w[~train]) <= 0.7 * _rmse(lin, c[~train], w[~train])
    few = g < 3
    assert fit_sensor(c[few], w[few], g[few]).model == "linear"
    c, w, g = _bending_sensor(3, 6, 30, 5, bend=0.1, per_group=1)
    assert fit_sensor(c, w, g).choice.n_folds == 5  # more than 12 groups: 5 dealt folds


def test_beyond_the_reach_it_tested_the_correction_fades_to_the_affine_fit():
    """Held-out groups beyond their folds' range choose how the correction continues (slope, tangent or
    fade) up to the farthest reach they tested; farther out, what it adds to the affine fit shrinks as
    1 / distance, so it never grows without bound."""
    c, w, g, _ = sensor_data(2, 6, 40, 30, sat=0.1)
    auto, lin = fit_sensor(c, w, g), fit_sensor(c, w, g, model="linear")
    assert auto.model == "poly", auto.choice.reason
    used = [a is not None for a in auto.choice.row_alpha]
    assert [e in ("slope", "tangent", "fade") for e in auto.extension_] == used
    assert [e == "" for e in auto.extension_] == [not u for u in used]
    assert auto.reach_ > 1.0
    x = c[np.argmax(np.abs(c - auto.center_).max(axis=1))] - auto.center_  # the sample farthest out
    far = [auto.center_ + s * 4 * auto.reach_ * x for s in (1.0, 2.0, 4.0)]
    d = np.array([(auto.predict(z[None]) - lin.predict(z[None]))[0] for z in far])
    np.testing.assert_allclose(d[1], d[0] / 2, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(d[2], d[0] / 4, rtol=1e-9, atol=1e-12)
    assert np.all(d[0][~np.array(used)] == 0) and np.abs(d[0][np.array(used)]).min() > 0

"""Beyond the trained range: the linear fit's slope, or the polynomial's tangent where held-out largest
loads say it extrapolates better (``_cv.extension_errors``)."""

import numpy as np
import pytest

from gen import CASES, make_session, true_sensitivity

from pito_core.calibration import Calibration, calibrate, fit_sensor
from pito_core.calibration._poly import PolyCorrection, poly_terms

FS = np.array([15.0, 15.0, 15.0, 0.1, 0.1, 0.1])


def test_tangent_rows_continue_along_the_polynomial_s_tangent():
    """A tangent row beyond the box: the polynomial at the edge plus its derivative along the ray times
    the way beyond (first order); the other rows as without the flag; inside, the plain polynomial."""
    rng = np.random.default_rng(7)
    pairs, cubes = poly_terms([range(3)])
    coef = rng.normal(size=(2, pairs.shape[0] + cubes.size))
    E = rng.normal(size=(2, 3))
    scale, lo, hi = np.array([2.0, 1.0, 4.0]), np.array([-1.0, -2.0, -0.5]), np.array([1.5, 1.0, 0.5])
    flag = np.array([True, False])
    tan = PolyCorrection(scale, pairs, cubes, coef, lo, hi, E, tangent=flag)
    slope, plain = PolyCorrection(scale, pairs, cubes, coef, lo, hi, E), PolyCorrection(scale, pairs, cubes, coef)
    inside = rng.uniform(lo, hi, size=(100, 3)) * scale
    np.testing.assert_allclose(tan(inside), plain(inside), rtol=1e-12, atol=1e-12)
    edge = np.array([hi[0], 0.3, -0.2]) * scale
    h = 1e-6
    d = (plain(((1 + h) * edge)[None])[0] - plain(((1 - h) * edge)[None])[0]) / (2 * h)  # d/ds at s = 1
    for s in (1.5, 4.0):
        far = (s * edge)[None]
        np.testing.assert_allclose(tan(far)[0, 0], plain(edge[None])[0, 0] + (s - 1) * d[0], rtol=1e-6)
        np.testing.assert_allclose(tan(far)[0, 1], slope(far)[0, 1], rtol=1e-12)
    with pytest.raises(ValueError, match="tangent"):
        PolyCorrection(scale, pairs, cubes, coef, lo, hi, E, tangent=[True])


def _sensor(seed, n_seg, seg, scale, kind):
    """Held loads on a 6-channel sensor: ``saturation`` (each channel ``tanh``-compressed, more the
    larger the load), or ``bend`` (a quadratic term that stops growing at 0.2 of full scale)."""
    S = np.random.default_rng(0).normal(size=(6, 6)) * 1000 / FS + 3000 * np.eye(6) / FS  # one sensor
    rng = np.random.default_rng(seed)
    W = np.repeat(rng.uniform(-1, 1, size=(n_seg, 6)) * FS * scale, seg, axis=0)
    lin = W @ S.T
    full = np.abs(S) @ FS
    if kind == "saturation":
        c = 1.2 * full * np.tanh(lin / (1.2 * full))
    else:
        c = lin + 0.15 * full * np.clip(lin / full, -0.2, 0.2) ** 2
    return c + rng.normal(scale=1.0, size=c.shape), W, np.repeat(np.arange(n_seg), seg)


@pytest.mark.parametrize("kind, tangent", [("saturation", True), ("bend", False)])
def test_fit_sensor_extrapolates_as_its_largest_loads_say(kind, tangent):
    """Trained on loads up to 0.6 of full scale, tested up to full scale: the tangent where the response
    keeps bending beyond the range (saturation), the linear fit's slope where it stops (bend); either
    way the default beats the affine fit."""
    c, w, g = _sensor(1, 60, 40, 0.6, kind)
    ct, wt, _ = _sensor(2, 40, 10, 1.0, kind)
    auto, lin = fit_sensor(c, w, g), fit_sensor(c, w, g, model="linear")
    assert auto.model == "poly", auto.choice.reason
    assert (auto.correction_.tangent is not None) == tangent
    beyond = np.abs(wt / FS).max(axis=1) > 0.6
    e = np.sqrt(np.mean(((auto.predict(ct) - wt) / FS)[beyond] ** 2))
    el = np.sqrt(np.mean(((lin.predict(ct) - wt) / FS)[beyond] ** 2))
    assert e < 0.8 * el


def test_cube_correction_keeps_its_tangent_rows_through_a_file(tmp_path):
    """A saturating cube trained on half its range: the joint method's correction takes the tangent
    for some groups; the file keeps them (same wrenches, and the hash covers them)."""
    from pito_core.io import calibration_hash

    K = true_sensitivity(41, coupling=0.05)
    full = np.abs(K) @ np.tile(FS, 6)

    def response(F):
        lin = F.reshape(-1, 36) @ K.T
        return 1.2 * full * np.tanh(lin / (1.2 * full))

    kw = dict(CASES["quasi_total"], connected_face=6, noise=2.0, response=response, counts_dtype=float)
    cal = calibrate(make_session(K, k=300, seed=42, load_scale=0.5, **kw), "quasi_total")
    assert cal.correction is not None and cal.correction.tangent is not None
    cal.save(tmp_path / "c.h5")
    back = Calibration.load(tmp_path / "c.h5")
    np.testing.assert_array_equal(back.correction.tangent, cal.correction.tangent)
    x = make_session(K, k=100, seed=43, **kw).counts
    np.testing.assert_allclose(back.wrenches(x), cal.wrenches(x), rtol=1e-12, atol=1e-12, equal_nan=True)
    assert calibration_hash(back) == calibration_hash(cal)
    back.correction.tangent = None
    assert calibration_hash(back) != calibration_hash(cal)


def test_choice_is_the_best_ridge_against_the_affine_fit_by_standard_errors():
    """The correction at its best ridge, kept only where it beats the affine fit by more than ``n_se``
    standard errors of its fold scores; never a weaker-scoring ridge that merely sits within the bound."""
    from pito_core.calibration._cv import _group_choice

    n = np.full(5, 100)
    affine = np.full(5, 100.0)
    best = np.array([80.0, 82.0, 78.0, 81.0, 79.0])  # mean 80, SE ≈ 0.71
    strong = best + 15.0  # a stronger ridge, worse than the best: never picked over it
    e = np.stack([affine, strong, best]) * n
    assert _group_choice(e, n, False, 1.0) == 2
    assert _group_choice(e, n, False, 3.0) == 2
    close = np.stack([affine, affine - 1.0 + np.array([-2, 2, -2, 2, 0.0])]) * n  # wins by 1, SE ≈ 0.9
    assert _group_choice(close, n, False, 1.0) == 1
    assert _group_choice(close, n, False, 3.0) == 0
    assert _group_choice(close, n, True, 3.0) == 1


def test_extension_choice_fade_and_trust_from_held_out_errors():
    """``choose_extension`` per output group of three: the tangent only below ``TANGENT_GAIN`` of the slope's
    error, then the fade where it does better; ``trust_polynomial`` the polynomial itself only where it
    beats the chosen extensions (summed over the corrected rows) by the same margin."""
    from pito_core.calibration._cv import TANGENT_GAIN, choose_extension, chosen_error, trust_polynomial

    e = {"slope": np.array([1.0, 1.0, 1.0, 4.0, 4.0, 4.0]), "tangent": np.array([0.96, 0.96, 0.96, 1.0, 1.0, 1.0]),
         "fade_slope": np.array([0.5, 0.5, 0.5, 9.0, 9.0, 9.0]), "fade_tangent": np.array([2.0, 2.0, 2.0, 0.5, 0.5, 0.5]),
         "poly": np.array([0.3, 0.3, 0.3, 0.1, 0.1, 0.1])}
    ra = np.array([1e-3] * 6)
    tangent, fade = choose_extension(e, ra)  # group 1: tangent 0.96 ≥ 0.95 · 1: slope, then its fade (0.5 < 1)
    np.testing.assert_array_equal(tangent, [False] * 3 + [True] * 3)  # group 2: tangent 1 < 0.95 · 4
    np.testing.assert_array_equal(fade, [True] * 3 + [True] * 3)  # group 2: its fade 0.5 < 1
    chosen, poly = chosen_error(e, ra, tangent, fade)
    assert chosen == pytest.approx(3 * 0.5 + 3 * 0.5) and poly == pytest.approx(1.2)
    assert trust_polynomial(chosen, poly) and not trust_polynomial(chosen, TANGENT_GAIN * chosen)
    ra[3:] = np.nan  # rows without a correction count for neither
    assert chosen_error(e, ra, tangent, fade) == pytest.approx((1.5, 0.9))
    assert chosen_error(None, ra, tangent, fade) == (0.0, 0.0) and not trust_polynomial(0.0, 0.0)

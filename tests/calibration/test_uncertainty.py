"""Issue 10, item 4: the calibration's covariance, stored, propagated per sample, and checked by Monte Carlo."""

import h5py
from pito_core.io import FileFormatError
import numpy as np
import pytest
from gen import CASES, make_session, true_sensitivity

from pito_core.calibration import calibrate, load_calibration
from pito_core.calibration._uncertainty import N_FEATURES, q_features
from pito_core.io._hdf5 import seal
from pito_core.sim import VirtualCube, random_sensor, random_sensor_session, simulate_calibration

#: Tests whose reference is noisier than the tare's limits on purpose (1–3 %): the fit warns so
#: (test_a_reference_noisier_than_the_tare_limits_is_named_in_the_calibration_and_its_evaluation).
NOISIER_THAN_THE_TARE_ALLOWS = pytest.mark.filterwarnings("ignore::pito_core.calibration.NoisyReferenceWarning")


def _coverage(cal, counts, truth):
    W, cov = cal.wrenches(counts, return_cov=True)
    out = cal.has_output
    e = (W - truth)[:, out]
    sd = np.sqrt(np.diagonal(cov, axis1=-2, axis2=-1))[:, out]
    return (np.abs(e) <= 1.959964 * sd).mean(axis=0)  # (faces with output, 6)


def test_shapes_units_and_faces_without_output():
    K = true_sensitivity(41)
    s = make_session(K, flange="frame", connected_face=2, k=400, noise=2.0)
    cal = calibrate(s, "quasi_total")
    W, cov = cal.wrenches(s.counts[:7], return_cov=True)
    assert W.shape == (7, 6, 6) and cov.shape == (7, 6, 6, 6)
    assert np.isnan(cov[:, 1]).all() and np.isfinite(cov[:, [0, 2, 3, 4, 5]]).all()
    np.testing.assert_allclose(cov, np.swapaxes(cov, -1, -2), rtol=1e-12, atol=0)
    assert (np.linalg.eigvalsh(cov[:, [0, 2, 3, 4, 5]]) > 0).all()
    w1, c1 = cal.wrenches(s.counts[3], return_cov=True)
    np.testing.assert_allclose(c1, cov[3]) and np.testing.assert_allclose(w1, W[3])
    # N² on forces and (N·m)² on torques: a 2-count gauge noise gives mN-level force σ here
    sd = np.sqrt(np.diagonal(cov[:, 0], axis1=-2, axis2=-1))
    assert 1e-4 < sd[:, :3].mean() < 0.1 and 1e-7 < sd[:, 3:].mean() < 1e-3


def test_retare_adds_the_tare_noise_and_explicit_offsets_only_the_slopes():
    K = true_sensitivity(42)
    s = make_session(K, flange="frame_hole", connected_face=6, k=500, noise=3.0)
    cal = calibrate(s, "loaded_frame")
    free = ~s.loaded.any(axis=1)
    few = cal.tare(s.counts[free][:5])
    many = cal.tare(s.counts[free])
    x = s.counts[-3:]
    _, c_few = few.wrenches(x, return_cov=True)
    _, c_many = many.wrenches(x, return_cov=True)
    _, c_expl = cal.wrenches(x, offset=few.offset, return_cov=True)
    d_few = np.diagonal(c_few, axis1=-2, axis2=-1)
    d_many = np.diagonal(c_many, axis1=-2, axis2=-1)
    d_expl = np.diagonal(c_expl, axis1=-2, axis2=-1)
    assert (d_few > d_many).all() and (d_many > d_expl).all()
    G = np.einsum("fia,ab,fjb->fij", cal._apply, cal.covariance.gauge_cov, cal._apply)
    np.testing.assert_allclose(d_few - d_expl, np.broadcast_to(np.diagonal(G, axis1=-2, axis2=-1) / 5, d_few.shape),
                               rtol=1e-6)


def test_covariance_round_trips_and_older_versions_are_refused(tmp_path):
    K = true_sensitivity(43)
    cal = calibrate(make_session(K, flange="frame_hole", connected_face=3, k=300, noise=2.0), "face_to_face")
    path = tmp_path / "c.pitocal"
    cal.save(path)
    with h5py.File(path) as f:
        assert int(f.attrs["version"]) == 6 and "covariance" in f
    back = load_calibration(path)
    x = np.random.default_rng(0).normal(size=(5, 36)) * 1e3 + cal.offset
    for a, b in zip(back.wrenches(x, return_cov=True), cal.wrenches(x, return_cov=True)):
        np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(back.covariance.own_q, cal.covariance.own_q)
    np.testing.assert_array_equal(back.covariance.own_variance_coef, cal.covariance.own_variance_coef)
    with h5py.File(path, "a") as f:  # 0.1.0 is unreleased: one version is read
        f.attrs["version"] = 5
        seal(f)
    with pytest.raises(FileFormatError, match="version"):
        load_calibration(path)


@pytest.mark.parametrize("method, flange", [("loaded_frame", "frame_hole"), ("unloaded_frame", "face"),
                                            ("face_to_face", "frame_hole")])
def test_monte_carlo_coverage_on_random_linear_cubes(method, flange):
    """Nominal 95 % intervals cover 93–97 % of the true face wrenches, per face and axis."""
    hits, n = 0, 0
    for seed in (1, 2):
        sensor = random_sensor(seed, condition=(1.0, 30.0))
        faces = [1, 2, 3, 4, 5] if method == "unloaded_frame" else None
        train, _ = random_sensor_session(sensor, flange, 6, 2000, n_tare=200, faces=faces, seed=10 + seed)
        test, truth = random_sensor_session(sensor, flange, 6, 1500, n_tare=0, faces=faces, seed=20 + seed)
        cal = calibrate(train, method)
        c = _coverage(cal, test.counts, truth)
        hits, n = hits + c * len(test), n + len(test)
    cover = hits / n
    assert 0.93 <= cover.min() and cover.max() <= 0.97, cover


def test_monte_carlo_coverage_on_the_structured_simulator():
    """pito_core.sim (hub nonlinearity, drift, reference noise; truth = the simulated face wrench).

    Its errors are not Gaussian and hold together over a loading gesture, so the per-axis
    coverage scatters more than on a linear cube (docs/calibration.md gives the figures);
    pooled over faces and axes it is close to nominal.
    """
    hits, n = 0, 0
    for r in range(3):
        cube = VirtualCube(seed=10 + r)
        train = simulate_calibration("face", 6, k=3000, seed=100 + r, model=cube)
        test, truth = simulate_calibration("face", 6, k=1500, seed=200 + r, model=cube, return_truth=True)
        loaded = test.loaded.any(axis=1)
        cal = calibrate(train, "total", model="linear").tare(test.counts[~loaded])  # the polynomial: issue 25 item 4
        c = _coverage(cal, test.counts[loaded], truth.face_wrenches[loaded])
        hits, n = hits + c * loaded.sum(), n + loaded.sum()
    cover = hits / n
    assert 0.90 <= cover.mean() <= 0.97, cover
    assert cover.min() >= 0.80 and cover.max() <= 0.995, cover


def test_the_contact_solver_takes_the_covariance_directly():
    from pito_core.contact import load_assembly, solve_object

    K = true_sensitivity(44)
    s = make_session(K, flange="frame_hole", connected_face=6, k=300, noise=2.0)
    cal = calibrate(s, "loaded_frame")
    W, cov = cal.wrenches(s.counts[-50:], return_cov=True)
    contacts = solve_object(load_assembly("pito_mixed"), W, wrench_cov=cov)
    ok = contacts.valid
    assert ok.any() and np.isfinite(contacts.point_cov[ok]).all()
    with pytest.raises(ValueError, match=r"wrench_cov: expected shape"):
        solve_object(load_assembly("pito_mixed"), W, wrench_cov=cov[:3])


@NOISIER_THAN_THE_TARE_ALLOWS
@pytest.mark.parametrize("method, flange", [("total", "face"), ("unloaded_frame", "face"), ("face_to_face", "frame_hole"),
                                           ("loaded_frame", "frame_hole")])
@pytest.mark.parametrize("reference_noise", [0.01])
def test_coverage_of_the_true_wrench_with_a_noisy_reference(method, flange, reference_noise):
    """The interval is of the true wrench: the reference's own noise (in every training target,
    here 0.3 % and 1 % of full scale, measured at rest in the tare) is not counted as calibration
    error. Before it was taken out: 79.5–100 % per face and axis (single torque axes 99.6–100 %).

    Random linear cubes (``pito_core.sim.random_sensor``), 2 × 1500 held-out samples per face
    and axis (binomial σ ≈ 0.2 %): the mean over faces and axes 94–96 %, every face and axis
    90.9–96.6 % (before the reference's noise was given to the faces that carried it: 91.8–98.6 %).
    At 1 % the coefficients' error from the reference's noise is most of the error, and it is one
    draw per calibration: a single axis scatters about 95 % more than the binomial σ (issue 25
    asks 93–97 %; docs/calibration.md gives the figures).
    """
    hits, n = 0, 0
    for seed in (1, 2):
        sensor = random_sensor(seed, condition=(1.0, 30.0))
        faces = [1, 2, 3, 4, 5] if method == "unloaded_frame" else None
        train, _ = random_sensor_session(sensor, flange, 6, 2000, n_tare=200, faces=faces, seed=10 + seed,
                                         reference_noise=reference_noise)
        test, truth = random_sensor_session(sensor, flange, 6, 1500, n_tare=0, faces=faces, seed=20 + seed)
        c = _coverage(calibrate(train, method, model="linear"), test.counts, truth)
        hits, n = hits + c * len(test), n + len(test)
    cover = hits / n
    assert 0.90 <= cover.min() and cover.max() <= 0.97, cover
    assert 0.94 <= cover.mean() <= 0.96, cover


def _held_out_coverage(method, face, reference_noise, model, seed=1, response=None):
    """Coverage of the true face wrench per face and axis on a LATER session (re-tared), cube of ``gen.py``."""

    K = true_sensitivity(seed, coupling=0.05)
    kw = dict(CASES[method], connected_face=face, noise=2.0, counts_dtype=float)
    if response is not None:
        kw["response"] = response(seed, K, face)
    train = make_session(K, k=2000, seed=seed + 1, reference_noise=reference_noise, **kw)
    test = make_session(K, k=1000, seed=seed + 1000, **kw)  # 6000 loaded samples: binomial σ ≈ 0.3 %
    loaded = test.loaded.any(axis=1)
    cal = calibrate(train, method, model=model).tare(test.counts[~loaded])
    return _coverage(cal, test.counts[loaded], test.true_face_wrenches[loaded])


@NOISIER_THAN_THE_TARE_ALLOWS
@pytest.mark.parametrize("model", ["linear", "auto"])
@pytest.mark.parametrize("reference_noise", [0.0, 0.01, 0.03])
def test_intervals_cover_the_true_wrench_whatever_the_reference_noise(reference_noise, model):
    """Issue 25 item 4: 93–97 % per face and axis of the TRUE wrench, the reference's noise (1 and
    3 % of full scale, measured in the tare) not counted as calibration error.

    ``face_to_face`` on a random linear cube of ``gen.py`` (not ``pito_core.sim``), held out on a
    later session. Before the error model weighed each row by its share of information and read
    the crosstalk of faces that carry nothing as load: 94.8–97.9 % at 1 %, 17.9–98.3 % at 3 %.
    """
    cover = _held_out_coverage("face_to_face", 3, reference_noise, model)
    assert 0.93 <= cover.min() and cover.max() <= 0.97, cover


@NOISIER_THAN_THE_TARE_ALLOWS
def test_the_reference_noise_in_the_coefficients_goes_to_the_faces_that_carried_it():
    """A joint fit (``loaded_frame``, 1 % reference noise): face k's coefficients hold the reference's
    noise of the samples where face k carried, so a sample loading face k has the larger interval.

    Checked as the ratio, over the held-out samples, of the mean predicted variance where the face
    is loaded to where it is not, against the same ratio of the squared errors (within a factor 2).
    Before, ``Σ_r`` spread it over every sample: there the ratio was 0.001–0.11.
    """
    from gen import CASES

    K = true_sensitivity(1, coupling=0.05)
    kw = dict(CASES["loaded_frame"], connected_face=5, noise=2.0, counts_dtype=float)
    ratios = []
    for d in range(3):
        train = make_session(K, k=2000, seed=2 + 31 * d, reference_noise=0.01, **kw)
        test = make_session(K, k=1000, seed=1001, **kw)
        loaded = test.loaded.any(axis=1)
        cal = calibrate(train, "loaded_frame", model="linear").tare(test.counts[~loaded])
        W, cov = cal.wrenches(test.counts[loaded], return_cov=True)
        e2 = (W - test.true_face_wrenches[loaded]) ** 2
        var = np.diagonal(cov, axis1=-2, axis2=-1)
        own = test.loaded[loaded]
        for f in range(6):
            emp = e2[own[:, f], f, :3].mean() / e2[~own[:, f], f, :3].mean()
            pred = var[own[:, f], f, :3].mean() / var[~own[:, f], f, :3].mean()
            ratios.append(pred / emp)
    ratios = np.array(ratios)
    assert 0.5 <= np.exp(np.log(ratios).mean()) <= 2.0 and ratios.min() > 0.25 and ratios.max() < 4.0, ratios


@NOISIER_THAN_THE_TARE_ALLOWS
def test_the_reference_noise_terms_round_trip(tmp_path):
    K = true_sensitivity(45)
    cal = calibrate(make_session(K, flange="face", connected_face=6, k=300, noise=2.0, reference_noise=0.01), "total")
    assert all(g.reference_leverage is not None for g in cal.covariance.groups)
    cal.save(tmp_path / "c.pitocal")
    back = load_calibration(tmp_path / "c.pitocal")
    x = np.random.default_rng(1).normal(size=(5, 36)) * 1e3 + cal.offset
    np.testing.assert_array_equal(back.wrenches(x, return_cov=True)[1], cal.wrenches(x, return_cov=True)[1])
    exact = calibrate(make_session(K, flange="face", connected_face=6, k=300, noise=2.0), "total")
    assert all(g.reference_leverage is None for g in exact.covariance.groups)


def test_the_significance_of_a_load_term_does_not_depend_on_the_features_units():
    """The standard errors behind the pruning of the error model's terms come from the
    pinv of the scaled normal matrix. With the unscaled one, a feature 10⁹ times smaller (q² of a
    small load) lost its direction below the pinv's cut-off and kept or dropped other terms."""
    from pito_core.calibration._residuals import _significant_nnls, _significant_rows

    S = np.array([1.0, 1.0, 1.0, 1e-9, 1.0])
    for seed in range(5):
        rng = np.random.default_rng(seed)
        q, qo = rng.uniform(0, 6, 4000), rng.uniform(0, 3, 4000)
        q[:1000] = qo[:1000] = 0.0  # at rest
        phi = q_features(np.stack([q, qo], axis=1))[:, 0]  # [1, L, q, q², q_other]
        e2 = phi @ np.array([1e-4, 0.01, 0.03, 0.004, 0.02]) + rng.normal(scale=0.2 * np.sqrt(2), size=q.size)  # E² − v
        P, e, V, rv = phi.T @ phi, phi.T @ e2, (phi.T @ np.full(q.size, 0.2))[None], [2.0 / 299]
        ref = _significant_rows(P[None], e[None], V[:, None], rv)[0]
        np.testing.assert_allclose(_significant_nnls(P, e, V, rv), ref, rtol=1e-9, atol=0)
        Ps, es, Vs = P * np.outer(S, S), e * S, V * S
        np.testing.assert_allclose(_significant_rows(Ps[None], es[None], Vs[:, None], rv)[0] * S, ref, rtol=1e-6, atol=0)
        np.testing.assert_allclose(_significant_nnls(Ps, es, Vs, rv) * S, ref, rtol=1e-6, atol=0)



def test_collinear_load_terms_are_pruned_one_at_a_time():
    """The excess over the reference's noise is jointly significant in ``q`` and ``q²`` (a mean of
    0.10 of ``v``, 3.2 standard errors of ``v`` from a 2000-sample tare) and neither alone is: the
    two share it. Dropping every weak term at once dropped both (the nonlinear cube's
    ``quasi_total`` face 1 at 0.33 %, interval 0.45× its error); the weakest alone, and the other
    is kept with the excess."""
    from pito_core.calibration._residuals import _significant_nnls, _significant_rows

    rng = np.random.default_rng(0)
    n = 4000
    carry = np.arange(n) % 2 == 0
    q = np.where(carry, rng.uniform(0.5, 1.5, n), 0.0)
    phi = q_features(np.stack([q, np.where(carry, 0.0, rng.uniform(0, 1, n))], axis=1))[:, 0]  # [1, L, q, q², q_other]
    e2 = phi @ np.array([0.0, 0.0, 0.06, 0.04, 0.0])  # E² − v, v = 1 where the face carries
    P, e, V, rv = phi.T @ phi, phi.T @ e2, (phi.T @ carry.astype(float))[None], [2.0 / 1999]
    for c in (_significant_nnls(P, e, V, rv), _significant_rows(P[None], e[None], V[:, None], rv)[0]):
        assert np.count_nonzero(c) == 1
        assert 0.9 <= (phi[carry] @ c).mean() / e2[carry].mean() <= 1.1


def test_a_corrected_row_keeps_a_load_term_the_significance_test_would_drop():
    """A row with a polynomial correction keeps every term the NNLS fits: its held-out error where
    the face carries is larger than the training residuals show (the correction absorbs part of its
    rows' misfit), and the 3-σ test, blind to the rows' own scatter, dropped real terms there
    (``quasi_total``, nonlinear cube, 0.33 %: 78–86 % coverage where the face carries, on six
    torques). An excess of 1.5 standard errors of the reference's noise: dropped on an affine row,
    kept whole on a corrected one."""
    from pito_core.calibration._residuals import _significant_rows

    rng = np.random.default_rng(1)
    n = 4000
    carry = np.arange(n) % 2 == 0
    q = np.where(carry, rng.uniform(0.5, 1.5, n), 0.0)
    phi = q_features(np.stack([q, np.zeros(n)], axis=1))[:, 0]  # [1, L, q, q², q_other]
    rv = [2.0 / 1999]  # v known to ±3.2 % from a 2000-sample tare
    e2 = phi @ np.array([0.0, 0.0, 1.5 * np.sqrt(rv[0]), 0.0, 0.0])  # E² − v, v = 1 where the face carries
    P, e, V = phi.T @ phi, phi.T @ e2, (phi.T @ carry.astype(float))[None]
    affine, corrected = _significant_rows(np.stack([P, P]), np.stack([e, e]), np.stack([V, V], axis=1), rv,
                                          np.array([False, True]))
    assert not np.any(affine[2:])
    assert 0.98 <= (phi[carry] @ corrected).mean() / e2[carry].mean() <= 1.02


@pytest.mark.parametrize("n", [1, 20, 100, 2000, 5001])
def test_the_coverage_bin_by_partial_sort_is_the_histograms(n):
    """An exact reference (every weight 1): the order statistic gives the histogram's 95 % bin,
    under load, where a face reads a load of its own (its own model's) and at rest."""
    from pito_core.calibration._residuals import _Z_WIDTH, _coverage_scales, _hist_bins, _order_bins

    rng = np.random.default_rng(n)
    F = 2
    phT = np.ones((F, N_FEATURES, n), dtype=np.float32)
    phT[:, 1:] = rng.uniform(0, 2, size=(F, N_FEATURES - 1, n))
    ET = (rng.standard_t(3, size=(F, 6, n)) * rng.uniform(0.5, 2, size=(F, 6, 1))).astype(np.float32)
    ET[0, 0, : n // 2] = 0.0  # ties
    none = np.zeros((F, n), dtype=bool)
    b = dict(ET=ET, phT=phT, carr=np.ones((F, n), dtype=bool), vT=None, sessions=[(0, slice(0, n))], rho=none, own=none,
             split=False)
    coef = np.stack([rng.uniform(0.1, 1.0, size=(6 * F, N_FEATURES))] * 2)

    def by_histogram(b, coef):  # the scales the weighted histogram gives (a noisy reference's route)
        return tuple((q * _Z_WIDTH / 1.959964) ** 2 for q in _hist_bins(b, coef)[:3])

    np.testing.assert_array_equal(_coverage_scales(b, coef)[:3], by_histogram(b, coef))
    b["carr"] = np.zeros((F, n), dtype=bool)
    b["carr"][1, ::3] = True  # a third loaded: those alone where they are 400 or more, else all; the rest at rest
    np.testing.assert_array_equal(_coverage_scales(b, coef)[:3], by_histogram(b, coef))
    b["carr"][:, ::2] = True  # face 2 reads a load of its own on half its loaded samples, by its own model
    b["rho"] = np.zeros((F, n), dtype=bool)
    b["rho"][1, ::4] = True
    b["own"], b["split"] = b["rho"] & b["carr"], True
    coef[1] *= rng.uniform(0.5, 2.0, size=coef[1].shape)
    np.testing.assert_array_equal(_coverage_scales(b, coef)[:3], by_histogram(b, coef))
    coef[:, 0] = 0.0  # a row of zero variance: weights below 1, the histogram's
    assert _order_bins(b, coef) is None


@pytest.mark.parametrize("noisy", [False, True])
def test_the_coverage_scale_is_the_loaded_samples_where_they_inform_it(noisy):
    """Pass 4 scales the variance to cover 95 % of the loaded samples' errors, not of a long rest's:
    5000 samples at rest with errors well inside their interval against 2000 loaded with errors
    at the modelled variance gave a scale of 0.45–0.50 (the loaded samples' intervals 0.7× too short).
    A face whose loaded samples the reference's noise swamps keeps every sample's: here a noise 3×
    the error's variance, weights 1/16 (500 of 8000 rows). There an error of 10 % in the
    reference's noise (a 200-sample tare) moves each row's need by 0.3 of the variance.
    At rest the samples at rest set the scale: their errors' 0.1² (one scale for both set it by the
    loaded samples, 100× too wide)."""
    from pito_core.calibration._residuals import _coverage_scales

    rng = np.random.default_rng(3)
    n_rest, n_load, F = 5000, 8000 if noisy else 2000, 2
    n = n_rest + n_load
    carr = np.zeros((F, n), dtype=bool)
    carr[:, n_rest:] = True
    phT = np.ones((F, N_FEATURES, n), dtype=np.float32)
    ET = rng.normal(size=(F, 6, n)).astype(np.float32)
    ET[:, :, :n_rest] *= 0.1  # at rest: far inside
    coef = np.zeros((6 * F, N_FEATURES))
    coef[:, 0] = 1.0
    vT = None
    if noisy:  # face 2's loaded samples under a reference noise 3× their error's variance
        vT = np.zeros((F, 6, n), dtype=np.float32)
        vT[1, :, n_rest:] = 3.0
        ET[1, :, n_rest:] = rng.normal(scale=2.0, size=(6, n_load))
    b = dict(ET=ET, phT=phT, carr=carr, vT=vT, sessions=[(0, slice(0, n))], rho=np.zeros((F, n), dtype=bool), split=False)
    b["own"] = b["rho"]
    s, _, s_rest, _ = _coverage_scales(b, np.stack([coef, coef]))
    np.testing.assert_allclose(s[:6], 1.0, atol=0.12)  # the loaded samples' N(0, 1)
    np.testing.assert_allclose(s_rest, 0.01, rtol=0.12)  # at rest: N(0, 0.1²)
    if noisy:  # every sample's: mostly the rest's 0.1² (the loaded ones weigh 500 of 5500)
        assert np.all(s[6:] < 0.1)


@NOISIER_THAN_THE_TARE_ALLOWS
def test_the_reference_noise_through_the_correction_is_its_coefficients_term():
    """Issue 25 item 4: a polynomial correction's many coefficients absorb the reference's noise of
    the rows they were fitted on; its term ``(zᵀ M_g M_k M_g' z) Σ_ref`` (``PolyReferenceBlock``)
    is that noise as it reaches a later sample.

    The same training counts fitted with and without 3 % reference noise (``total``, the nonlinear
    cube of ``test_nonlinear.py``): where both fits chose the same ridge, their difference is that
    noise alone. Its mean square over the held-out samples against the term's mean, pooled over
    draws, per corrected face and axis. Without the term (the affine design's leverage in its
    place) the ratio was 0.01–0.09 on corrected faces.
    """
    from gen import CASES
    from test_nonlinear import nonlinear_response

    K = true_sensitivity(1, coupling=0.05)
    kw = dict(CASES["total"], connected_face=6, noise=2.0, counts_dtype=float,
              response=nonlinear_response(1, K, 6, 0.08))
    test = make_session(K, k=300, seed=1001, **kw)
    loaded = test.loaded.any(axis=1)
    pred, actual = np.zeros((6, 6)), np.zeros((6, 6))
    for d in range(3):
        noisy = calibrate(make_session(K, k=1000, seed=2 + 31 * d, reference_noise=0.03, **kw), "total")
        clean = calibrate(make_session(K, k=1000, seed=2 + 31 * d, **kw), "total")
        cov = noisy.covariance
        assert cov.poly_reference, "a noisy reference and a correction give the correction's term"
        same = np.array(noisy.model.row_alpha) == np.array(clean.model.row_alpha)
        n, c = noisy.tare(test.counts[~loaded]), clean.tare(test.counts[~loaded])
        x = test.counts[loaded] - n.offset
        z = np.concatenate([x / n.correction.scale, n.correction.features(x)], axis=1)
        diff = n.wrenches(test.counts[loaded]) - c.wrenches(test.counts[loaded])
        for b in cov.poly_reference:
            f = noisy.output_faces[b.block] - 1
            use = b.rows & same[6 * b.block : 6 * b.block + 6]
            X = noisy._face_from_output[f]
            term = np.einsum("ij,njk,lk->nil", X, b.variances(z), X)  # the output frame is the face's for "total"
            pred[f, use] += np.diagonal(term, axis1=1, axis2=2).mean(axis=0)[use]
            actual[f, use] += (diff[:, f] ** 2).mean(axis=0)[use]
    ratio = pred[actual > 0] / actual[actual > 0]
    assert ratio.size >= 8, ratio
    assert 0.8 <= np.exp(np.log(ratio).mean()) <= 1.25 and ratio.min() > 0.5 and ratio.max() < 2.0, ratio


@NOISIER_THAN_THE_TARE_ALLOWS
def test_the_correction_s_reference_term_round_trips_and_stays_with_the_correction(tmp_path):
    """Saved and loaded with the calibration, kept by ``tare``, dropped by the linear alternative."""
    from test_nonlinear import nonlinear_response

    K = true_sensitivity(45)
    s = make_session(K, flange="face", connected_face=6, k=300, noise=2.0, reference_noise=0.01, counts_dtype=float,
                     response=nonlinear_response(45, K, 6, 0.08))
    cal = calibrate(s, "total", model="poly")
    assert cal.covariance.poly_reference and all(b.rows.all() for b in cal.covariance.poly_reference)
    cal.save(tmp_path / "c.pitocal")
    back = load_calibration(tmp_path / "c.pitocal")
    x = np.random.default_rng(1).normal(size=(5, 36)) * 1e3 + cal.offset
    np.testing.assert_array_equal(back.wrenches(x, return_cov=True)[1], cal.wrenches(x, return_cov=True)[1])
    assert len(cal.tare(s.counts[:50]).covariance.poly_reference) == len(cal.covariance.poly_reference)
    lin = cal.linear_alternative()
    assert lin.covariance.poly_reference == [] and np.all(np.isfinite(lin.wrenches(x, return_cov=True)[1]))
    with h5py.File(tmp_path / "c.pitocal", "r") as f:
        assert f["covariance"].attrs["n_poly_reference"] == len(cal.covariance.poly_reference)


def test_a_fit_in_the_reference_frame_models_its_errors_in_each_face_s_frame(tmp_path):
    """``loaded_frame`` fits in S_A, where a face's force and torque errors cancel in its own frame:
    its error model is fitted there (``error_frame == "face"``), saved and loaded with it; the
    face-frame fits keep theirs in the output frame (the same)."""
    from gen import CASES

    K = true_sensitivity(3, coupling=0.05)
    kw = dict(CASES["loaded_frame"], connected_face=5, noise=2.0, counts_dtype=float)
    cal = calibrate(make_session(K, k=300, seed=4, reference_noise=0.003, **kw), "loaded_frame", model="linear")
    assert cal.output_frame == "reference" and cal.covariance.error_frame == "face"
    cal.save(tmp_path / "c.pitocal")
    back = load_calibration(tmp_path / "c.pitocal")
    assert back.covariance.error_frame == "face"
    x = np.random.default_rng(1).normal(size=(5, 36)) * 1e3 + cal.offset
    np.testing.assert_array_equal(back.wrenches(x, return_cov=True)[1], cal.wrenches(x, return_cov=True)[1])
    face = calibrate(make_session(K, flange="face", connected_face=6, k=300, noise=2.0), "total")
    assert face.covariance.error_frame == "output"


def test_the_error_model_reads_the_residuals_a_tare_leaves():
    """A tare zeroes the wrench at rest: each session's mean residual at rest (``L`` 0) leaves
    every residual of that session, the loaded ones too, and is returned."""
    from pito_core.calibration._residuals import _retared

    rng = np.random.default_rng(3)
    kept = []
    for j, bias in enumerate(([0.02, 5.0, 0, 0, 0, -5.0], [1.0, 0, 0, 0, 0, 0])):
        E = (rng.normal(size=(400, 6)) * 0.01 + np.array(bias)).astype(np.float32)
        phi = np.ones((400, 1, N_FEATURES), dtype=np.float32)
        phi[100:, :, 1] = 0.0  # at rest
        E[:100] += 3.0  # loaded: an error of their own beside the bias
        kept.append((E, phi, np.zeros((400, 1), dtype=bool), j))
    out, means = _retared(kept, 2)
    for (E, *_), (Eo, *_), m in zip(kept, out, means):
        np.testing.assert_allclose(m, E[100:].mean(axis=0, dtype=float), rtol=1e-6)
        np.testing.assert_allclose(Eo[100:].mean(axis=0, dtype=float), 0, atol=1e-6)
        np.testing.assert_allclose(Eo[:100], E[:100] - m.astype(np.float32), rtol=1e-6)


@NOISIER_THAN_THE_TARE_ALLOWS
def test_the_offsets_noise_variance_is_that_of_the_session_means_on_linear_cubes(monkeypatch):
    """``ReferenceLeverage.offset_var`` predicts the spread of the mean residual at rest (on a
    linear cube that mean is the offset's noise alone): mean² / var is χ²₁. (``rest_bias`` is the
    excess of mean² over it.)"""
    from pito_core.calibration import _reference_noise, _residuals

    seen, means = [], []
    original_retared, original_var = _residuals._retared, _reference_noise.ReferenceLeverage.offset_var

    def record_means(kept, n_int):
        out, m = original_retared(kept, n_int)
        means.append(m[0])
        return out, m

    def record_var(self, F, X=None):
        v = original_var(self, F, X)
        seen.append(means[-1] ** 2 / v[0])
        return v

    monkeypatch.setattr(_residuals, "_retared", record_means)
    monkeypatch.setattr(_reference_noise.ReferenceLeverage, "offset_var", record_var)
    K = true_sensitivity(11, coupling=0.05)
    for method, kw in (("total", dict(flange="face", connected_face=6)),
                       ("loaded_frame", dict(flange="frame_hole", connected_face=5))):
        for d in range(3):
            calibrate(make_session(K, k=1500, seed=5 + 7 * d, noise=2.0, counts_dtype=float, reference_noise=0.01,
                                   **kw), method, model="linear")
    r = np.concatenate(seen)
    r = r[np.isfinite(r)]
    assert r.size >= 150
    assert 0.7 < r.mean() < 1.4, r.mean()  # χ²₁: mean 1 (± 0.12 over ~200 outputs)
    assert (r > 9).mean() < 0.02


def test_the_reference_term_leaves_out_what_the_gauge_noise_brings():
    """The reference's noise in the slopes, acting on a sample's gauge noise, is in the gauge noise
    through the fitted matrix already (the error model's floor, measured with that matrix): the
    reference term is ``x̃ᵀ Q x̃ − tr(Q Σ_g)``, at least 0, in training and in use.

    Unit: ``noise_leverages`` is the mean ``x̃ᵀ Q x̃`` of pure gauge noise. Whole: ``quasi_total``, linear
    cube, 0.33 % reference noise, the wizard's 2000-sample tare, 4 calibrations, samples at rest of a
    later session tared on the other half of them. Counted twice, the torques' lever-arm share of the
    reference's force noise made the intervals at rest 94.5–98.9 % (5 of 30 axes above 97 %, and on
    the loaded samples where another face carries 97.1–97.4 % on five torque axes, 128 calibrations);
    now 94.5–95.7 % at rest."""
    from pito_core.calibration._uncertainty import CovarianceGroup

    rng = np.random.default_rng(5)
    A = rng.normal(size=(8, 8))
    Q = np.zeros((2, 9, 9))
    Q[:, 1:, 1:] = [A @ A.T, np.eye(8)]
    g = CovarianceGroup(np.arange(8), np.arange(12), np.eye(9), np.eye(12), np.zeros(8), np.ones(1), 10,
                        reference_leverage=Q, reference_cov=np.broadcast_to(np.eye(6), (2, 6, 6)))
    L = rng.normal(size=(36, 36))
    gauge_cov = L @ L.T / 36
    noise = rng.multivariate_normal(np.zeros(36), gauge_cov, size=20000)
    raw = g.reference_leverages(noise, np.zeros(36))
    np.testing.assert_allclose(g.noise_leverages(gauge_cov), raw.mean(axis=0), rtol=0.03)
    net = g.reference_leverages(noise, np.zeros(36), gauge_cov)
    assert np.all(net >= 0) and np.all(net.mean(axis=0) < 0.5 * raw.mean(axis=0))

    seed, face = 1, 2
    K = true_sensitivity(seed, coupling=0.05)
    kw = dict(CASES["quasi_total"], connected_face=face, noise=2.0, counts_dtype=float, n_unloaded=2000)
    test = make_session(K, k=200, seed=seed + 1000, **kw)
    rest = np.flatnonzero(~test.loaded.any(axis=1))
    hits = 0
    for d in range(4):
        train = make_session(K, k=2000, seed=seed + 1 + 31 * d, reference_noise=0.0033, **kw)
        cal = calibrate(train, "quasi_total", model="linear").tare(test.counts[rest[:1000]])
        hits = hits + _coverage(cal, test.counts[rest[1000:]], test.true_face_wrenches[rest[1000:]])
    cover = hits / 4
    assert 0.93 <= cover.min() and cover.max() <= 0.97, cover


@pytest.mark.parametrize("reference_noise", [0.0, 0.0033])
def test_where_a_face_carries_its_interval_is_of_its_own_error(reference_noise):
    """``face_to_face`` fits each face on its own rows: where another face carries, its reading is
    crosstalk its fit never saw, and its error the crosstalk itself (``q = E²``). One error model of
    both read that identity at the face's own full load: on a linear cube with an exact reference its
    intervals covered 100.0 % on every axis where the face carried (``e²/var`` 0.003: 18× the error),
    95 % pooled over all rows. Now a face's own load has its own model (``own_q``).

    ``gen.py`` cube, later session (1000 samples per face), coverage on the rows where the face
    carries, per face and axis: exact reference, one calibration, 93–97 %. With 0.33 % reference
    noise (the wizard's limit) its variance is 2000× the face's own error on this linear cube: there
    ``E² − v`` cannot tell that error from the gauge noise (on one axis it was 60× the floor and went
    unseen: 84 % coverage), so each face's own model is a bound (``_residuals._own_bound``), wide
    where it carries but not short: σ 1.3–111× the error's RMS there, median 5.8 (with the one model
    each face had before, 2.4–114, median 23; the widest are samples whose own load stays under the
    crosstalk's ``own_q``, read by the crosstalk's model).
    """
    seed, face = 1, 3
    K = true_sensitivity(seed, coupling=0.05)
    kw = dict(CASES["face_to_face"], connected_face=face, noise=2.0, counts_dtype=float, n_unloaded=2000)
    test = make_session(K, k=1000, seed=seed + 1000, **kw)
    loaded = test.loaded.any(axis=1)
    truth = test.true_face_wrenches[loaded]
    carries = np.abs(truth).max(axis=2) > 0  # (n, 6)
    train = make_session(K, k=2000, seed=seed + 1, reference_noise=reference_noise, **kw)
    cal = calibrate(train, "face_to_face", model="linear").tare(test.counts[~loaded])
    W, cov = cal.wrenches(test.counts[loaded], return_cov=True)
    h = np.abs(W - truth) <= 1.959964 * np.sqrt(np.diagonal(cov, axis1=-2, axis2=-1))
    cover = (h & carries[:, :, None]).sum(axis=0) / carries.sum(axis=0)[:, None]
    if reference_noise == 0:
        assert np.isfinite(cal.covariance.own_q).all()  # every face has a model of its own
        assert 0.93 <= cover.min() and cover.max() <= 0.97, cover
    else:
        assert np.isfinite(cal.covariance.own_q).all()
        assert cover.min() >= 0.95, cover
        var = np.diagonal(cov, axis1=-2, axis2=-1)
        e2 = ((W - truth) ** 2 * carries[:, :, None]).sum(axis=0)
        ratio = np.sqrt((var * carries[:, :, None]).sum(axis=0) / e2)
        assert np.median(ratio) <= 10, ratio
    pooled = h[:, cal.has_output].mean(axis=0)
    assert 0.93 <= pooled.min() and pooled.max() <= 0.97, pooled


def test_own_q_is_where_the_crosstalk_ends():
    """A face reads a load of its own from the 99.5th percentile of the ``q`` its crosstalk reached
    (the loaded samples where it carried nothing); with fewer than 400 samples on either side, never."""
    from pito_core.calibration._residuals import own_q

    rng = np.random.default_rng(0)
    n = 6000
    carries = np.zeros((n, 3), dtype=bool)
    carries[:2000, 0] = carries[2000:4000, 1] = True
    carries[:, 2] = rng.random(n) < 0.99  # face 3 carries on almost every sample: 60 of crosstalk
    q = np.where(carries, rng.uniform(0.5, 2.0, (n, 3)), rng.uniform(0.0, 0.01, (n, 3)))
    loaded = np.ones(n, dtype=bool)
    q0 = own_q([q[:3000], q[3000:]], [carries[:3000], carries[3000:]], [loaded[:3000], loaded[3000:]])
    cross = np.sort(q[~carries[:, 0], 0])
    assert cross[int(0.995 * cross.size) - 1] <= q0[0] <= cross[-1]
    assert 0.009 < q0[1] < 0.01 and q0[2] == np.inf
    assert np.all(own_q([q], [carries], [loaded], faces=np.array([False, True, True]))[[0, 2]] == np.inf)


def test_a_face_to_face_fit_between_the_two_regimes_warns_of_nothing():
    """A random linear sensor with a reference 10× quieter than the wizard's limit, where a face's
    own error is near what the reference's noise lets the fit see (the faces try a model of their
    own load; this sensor's keep one). A term the reference's noise cannot move is infinitely
    significant: that division overflowed and printed a RuntimeWarning during the fit."""
    import warnings

    sensor = random_sensor(3, condition=(1.0, 30.0))
    train, _ = random_sensor_session(sensor, "frame_hole", 6, 2000, n_tare=2000, seed=13, reference_noise=0.0003)
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        cal = calibrate(train, "face_to_face", model="linear")
    assert cal.covariance.own_q.shape == (6,)


def test_a_reference_noisier_than_the_tare_limits_is_named_in_the_calibration_and_its_evaluation(tmp_path):
    """The intervals' coverage was checked with the reference's noise at rest up to the tare's stillness limits
    (0.05 N, 0.5 mN·m: the wizard refuses a tare above them). A session recorded elsewhere above them is fitted,
    with a NoisyReferenceWarning naming the session and its figures; the file keeps them, and ``evaluate`` (the
    CLI, the report) says the ± may be short. Nonlinear cube, ``quasi_total``, 3 %: 45.7 % where face 6 carries."""
    import warnings

    from pito_core.calibration import NoisyReferenceWarning, evaluate

    K = true_sensitivity(1, coupling=0.05)
    kw = dict(CASES["total"], connected_face=6, noise=2.0, counts_dtype=float, n_unloaded=2000)
    test = make_session(K, k=200, seed=9, **kw)
    for noise, loud in ((0.0, False), (0.001, False), (0.01, True)):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            cal = calibrate(make_session(K, k=500, seed=2, reference_noise=noise, **kw), "total", model="linear")
        mine = [w for w in caught if issubclass(w.category, NoisyReferenceWarning)]
        rn = cal.meta["reference_noise_at_rest"]
        assert rn["force_std_N"][0] == pytest.approx(noise * 15.0, rel=0.1, abs=1e-12)
        assert rn["torque_std_Nm"][0] == pytest.approx(noise * 0.1, rel=0.1, abs=1e-12)
        assert rn["within_limits"] is (not loud) and len(mine) == int(loud)
        if loud:
            assert "sessions[0].reference" in str(mine[0].message) and "0.15" in str(mine[0].message)
            assert mine[0].filename == __file__  # points at the caller of calibrate
        path = tmp_path / f"c{noise}.h5"
        cal.save(path)
        back = load_calibration(path)
        assert back.meta["reference_noise_at_rest"] == rn
        caveat = evaluate(back, test).uncertainty95_caveat
        assert (caveat is not None) is loud
        if loud:
            assert "may be short" in caveat and f"{rn['force_std_N'][0]:.3f} N" in caveat
    del back.meta["reference_noise_at_rest"]  # a file written before the check: nothing to say
    assert evaluate(back, test).uncertainty95_caveat is None

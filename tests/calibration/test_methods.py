"""Every method recovers a known gauge model, exactly without noise and to the noise floor with it."""

import numpy as np
import pytest
from gen import CASES, make_session, true_sensitivity

from pito_core.calibration import METHODS, calibrate, evaluate, get_method
from pito_core.frames import invert_pose, wrench_adjoint


def test_table_covers_the_five_methods():
    assert set(METHODS) == set(CASES)
    for name, spec in METHODS.items():
        assert CASES[name]["flange"] in spec.flanges
        assert spec.summary


@pytest.mark.parametrize("method", sorted(CASES))
def test_exact_recovery_without_noise(method):
    coupling = 0.0 if method == "face_to_face" else 0.05  # face_to_face cannot model coupling
    K = true_sensitivity(1, coupling=coupling)
    kw = dict(CASES[method], connected_face=6, k=400, noise=0, counts_dtype=float)
    cal = calibrate(make_session(K, **kw), method)
    test = make_session(K, **dict(kw, seed=99))
    W = cal.wrenches(test.counts, offset=test.true_offset)
    out = cal.has_output
    scale = np.abs(test.true_face_wrenches).max(axis=(0, 1))
    err = np.abs(W[:, out] - test.true_face_wrenches[:, out]).max(axis=(0, 1)) / scale
    assert err.max() < 1e-9
    assert np.isnan(W[:, ~out]).all()


@pytest.mark.parametrize("method", sorted(CASES))
def test_recovery_down_to_the_noise_floor(method):
    """Held-out error of the fitted matrix ≈ error of the true matrix on the same noisy counts."""
    coupling = 0.0 if method == "face_to_face" else 0.05
    K = true_sensitivity(2, coupling=coupling)
    kw = dict(CASES[method], connected_face=3, k=2500, noise=3.0)
    cal = calibrate(make_session(K, **kw), method)
    test = make_session(K, **dict(kw, seed=123))
    W = cal.wrenches(test.counts, offset=test.true_offset)
    out = cal.has_output
    # noise floor: the best any matrix can do that maps the true-model subspace exactly
    truth = test.true_face_wrenches[:, out]
    err = np.sqrt(np.mean((W[:, out] - truth) ** 2, axis=(0, 1)))
    # floor: propagate the counts noise through the exact inverse on the loaded subspace
    noise = np.random.default_rng(5).normal(scale=3.0, size=(len(test), 36))
    floor_W = cal.wrenches(test.true_offset + test.true_face_wrenches.reshape(-1, 36) @ K.T + noise, offset=test.true_offset)
    floor = np.sqrt(np.mean((floor_W[:, out] - truth) ** 2, axis=(0, 1)))
    np.testing.assert_array_less(err, 1.3 * floor + 1e-12)
    # and the floor itself is small against full scale (15 N, 0.1 N·m)
    assert floor[:3].max() < 0.01 * 15 and floor[3:].max() < 0.01 * 0.1


def test_total_combines_mounts():
    """Sessions under several face flanges fit one matrix that holds for a mount it never saw.

    Eq. 6 of the multi-touch paper: under a face flange the connected face carries the
    reaction −W of a load elsewhere and a direct load W on itself. The free faces' loads
    balance (30 dimensions); the direct loads on the connected face add its 6: `total`
    sees all 36 load dimensions, so its fit is exact for any mount.
    """
    K = true_sensitivity(3)
    kw = dict(flange="face", k=300, noise=0, counts_dtype=float)
    one = calibrate(make_session(K, connected_face=6, **kw), "total")
    assert one.meta["load_rank"] == [36] and one.meta["net_load"] == "measured"
    free = calibrate(make_session(K, connected_face=6, free_only=True, **kw), "total")
    assert free.meta["load_rank"] == [30]
    assert free.meta["net_load"] == "not measured: not identified (plain least squares)"
    both = calibrate([make_session(K, connected_face=c, seed=c, **kw) for c in (6, 5)], "total")
    assert both.meta["connected_faces"] == [5, 6]
    other = make_session(K, connected_face=2, seed=42, **kw)
    W = both.wrenches(other.counts, offset=other.true_offset)
    np.testing.assert_allclose(W, other.true_face_wrenches, atol=1e-9 * np.abs(other.true_face_wrenches).max())
    # the frame_hole mount loads every face independently: the full 36 dimensions
    full = calibrate(make_session(K, flange="frame_hole", connected_face=6, k=300, noise=0, counts_dtype=float), "loaded_frame")
    assert full.meta["load_rank"] == [36]


def test_total_direct_load_on_the_connected_face_is_carried_by_it():
    """Eq. 6: face 6's own load is W_6 in row 6 (not a zero-wrench sample)."""
    from pito_core.calibration import MountGeometry, block_targets
    from pito_core.frames import transform_wrench

    K = true_sensitivity(33)
    s = make_session(K, flange="face", connected_face=6, k=50, noise=0, counts_dtype=float)
    T, carries, usable, _ = block_targets(s.reference, s.loaded, MountGeometry(s), "face")
    on6 = s.loaded[:, 5] & (s.loaded.sum(axis=1) == 1)
    assert on6.any() and carries[on6, 5].all() and not carries[on6, :5].any()
    expected = transform_wrench(s.reference[on6], s.T_ati_face(6))
    np.testing.assert_allclose(T[on6, 5], expected, atol=1e-12)
    on1 = s.loaded[:, 0] & (s.loaded.sum(axis=1) == 1)
    np.testing.assert_allclose(T[on1, 5], -transform_wrench(s.reference[on1], s.T_ati_face(6)), atol=1e-12)
    cal = calibrate(s, "total")
    np.testing.assert_allclose(cal.wrenches(s.counts[on6], offset=s.true_offset), s.true_face_wrenches[on6],
                               atol=1e-9 * np.abs(s.true_face_wrenches).max())


def test_loaded_frame_fits_in_the_reference_frame():
    K = true_sensitivity(4)
    s = make_session(K, flange="frame_hole", connected_face=2, k=300, noise=0, counts_dtype=float)
    cal = calibrate(s, "loaded_frame")
    assert cal.output_frame == "reference"
    Kinv = np.linalg.inv(K)
    T_ati_core = invert_pose(s.T_core_ati)
    for i in range(1, 7):
        X_ati_face = np.linalg.inv(wrench_adjoint(T_ati_core @ s.core.face_pose(i)))
        expected = X_ati_face @ Kinv[6 * (i - 1) : 6 * i]
        np.testing.assert_allclose(cal.matrix[6 * (i - 1) : 6 * i], expected, atol=1e-9 * np.abs(expected).max())


def test_face_to_face_is_block_diagonal_and_ignores_other_faces():
    K = true_sensitivity(5, coupling=0.0)
    cal = calibrate(make_session(K, flange="frame", connected_face=1, k=300, noise=0, counts_dtype=float), "face_to_face")
    assert cal.output_faces == (2, 3, 4, 5, 6)  # face 1 carries nothing on a type-1 flange
    for k, f in enumerate(cal.output_faces):
        rows = cal.matrix[6 * k : 6 * k + 6]
        mask = np.ones(36, bool)
        mask[6 * (f - 1) : 6 * f] = False
        assert np.all(rows[:, mask] == 0)


def test_method_mount_mismatch_and_mixed_mounts_refused():
    K = true_sensitivity(6)
    s = make_session(K, flange="face", connected_face=6, k=50)
    with pytest.raises(ValueError, match=r"sessions\[0\].flange: method 'quasi_total' needs a flange in \('frame',\), got 'face'"):
        calibrate(s, "quasi_total")
    with pytest.raises(ValueError, match=r"method: expected one of"):
        calibrate(s, "magic")
    s2 = make_session(K, flange="face", connected_face=5, k=50, faces=[1, 2, 3, 4, 6])
    with pytest.raises(ValueError, match=r"sessions\[1\].connected_face: method 'unloaded_frame' fits one mount at a time"):
        calibrate([make_session(K, flange="face", connected_face=6, k=50, faces=[1, 2, 3, 4, 5]), s2], "unloaded_frame")
    bad = make_session(K, flange="frame", connected_face=2, k=50, faces=[1, 2])
    with pytest.raises(ValueError, match=r"the connected face 2 cannot be loaded with flange 'frame'"):
        calibrate(bad, "quasi_total")


def test_calibration_round_trip_and_corrupt_file(tmp_path):
    from pito_core.calibration import load_calibration
    from pito_core.io import FileFormatError

    K = true_sensitivity(7)
    cal = calibrate(make_session(K, flange="frame_hole", connected_face=4, k=200), "loaded_frame")
    cal.meta["validation"] = {"note": "x", "rmse": [1.0, None]}
    path = tmp_path / "cal.pitocal"
    cal.save(path)
    back = load_calibration(path)
    np.testing.assert_array_equal(back.matrix, cal.matrix)
    np.testing.assert_array_equal(back.offset, cal.offset)
    np.testing.assert_array_equal(back.T_core_ati, cal.T_core_ati)
    assert (back.method, back.output_faces, back.output_frame, back.core, back.meta) == (
        cal.method, cal.output_faces, cal.output_frame, cal.core, cal.meta)
    counts = np.random.default_rng(0).normal(size=(10, 36)) * 1e4 + 1e6
    np.testing.assert_array_equal(back.wrenches(counts), cal.wrenches(counts))
    data = path.read_bytes()
    (tmp_path / "cut").write_bytes(data[: len(data) // 3])
    with pytest.raises(FileFormatError):
        load_calibration(tmp_path / "cut")
    s = make_session(K, k=10)
    s.save(tmp_path / "s.h5")
    with pytest.raises(FileFormatError, match="expected a 'pito-calibration' file, got format 'pito-session'"):
        load_calibration(tmp_path / "s.h5")


def test_wrenches_shapes_and_tare():
    K = true_sensitivity(8)
    s = make_session(K, flange="face", connected_face=6, k=200)
    cal = calibrate(s, "total")
    one = cal.wrenches(s.counts[0])
    assert one.shape == (6, 6)
    assert cal.wrenches(s.counts[:5]).shape == (5, 6, 6)
    unloaded = s.counts[~s.loaded.any(axis=1)]
    tared = cal.tare(unloaded + 1000)
    np.testing.assert_allclose(tared.offset, unloaded.mean(axis=0) + 1000)
    with pytest.raises(ValueError, match=r"counts: expected shape \(N, 36\)"):
        cal.wrenches(np.zeros((3, 35)))
    with pytest.raises(ValueError, match=r"counts_unloaded: expected shape \(N, 36\) with N ≥ 1"):
        cal.tare(np.zeros((0, 36)))


def test_get_method_returns_spec():
    assert get_method("total").flanges == ("face",)
    assert get_method(get_method("total")) is get_method("total")


def test_validation_figures_match_truth():
    K = true_sensitivity(9)
    kw = dict(flange="face", connected_face=6, faces=[1, 2, 3, 4, 5], k=1500, noise=2.0)
    cal = calibrate(make_session(K, **kw), "unloaded_frame")
    test = make_session(K, **dict(kw, seed=77, squeeze_pairs=[(1, 3), (2, 4), (4, 5)]))
    ev = evaluate(cal, test)
    W = cal.wrenches(test.counts, offset=test.counts[~test.loaded.any(axis=1)].mean(axis=0))
    one = test.loaded.sum(axis=1) == 1
    face = np.argmax(test.loaded[one], axis=1)
    err = W[one, face] - test.true_face_wrenches[one, face]
    for f in range(5):
        np.testing.assert_allclose(ev.rmse_single[f], np.sqrt(np.mean(err[face == f] ** 2, axis=0)), rtol=1e-9)
    assert ev.n_single == one.sum() and ev.n_squeeze == (test.loaded.sum(axis=1) == 2).sum()
    assert ev.identification["single"]["either"] > 0.99
    assert ev.identification["squeeze"]["either"] > 0.99
    assert ev.rmse_squeeze[:3].max() < 0.01
    d = ev.to_dict(series=True)
    assert d["units"] == {"force": "N", "torque": "N·m"} and len(d["comparison"]["predicted"]) > 100


@pytest.mark.parametrize("method", ["total", "unloaded_frame", "quasi_total"])
def test_own_gauge_prior_fills_only_the_unexcited_directions(method):
    """A face flange balances the free faces' loads (and a frame flange leaves the connected
    face idle), so without direct loads on the connected face the data span 30 of 36 load
    dimensions. ``prior="own_gauge"`` keeps the least-squares response on those and takes
    each face's own-gauge fit on the other 6, so a free grasp's net load (the weight) is
    still measured — not forced to ΣF ≡ 0 as by the papers' plain fit."""
    from pito_core.calibration import equilibrium

    K = true_sensitivity(31, coupling=0.0)  # coupling-free: the own-gauge fit is exact too
    flange = "frame" if method == "quasi_total" else "face"
    s = make_session(K, flange=flange, connected_face=6, k=1500, noise=2.0, free_only=True)
    cal = calibrate(s, method, prior="own_gauge")
    plain = calibrate(s, method)
    assert cal.meta["prior"] == "own_gauge" and cal.meta["net_load"] == "not measured: from the faces' own-gauge fits"
    assert cal.meta["load_directions"] == {"measured": 30, "from_prior": 6, "not_identified": 0}
    assert plain.meta["net_load"] == "not measured: not identified (plain least squares)"
    assert 3e-4 < cal.inverse_condition_number < 1  # not singular
    test = make_session(K, flange="frame_hole", connected_face=6, k=400, noise=2.0, seed=8)  # every face on its own
    W = cal.wrenches(test.counts, offset=test.true_offset)
    out = cal.has_output
    err = np.sqrt(np.mean((W[:, out] - test.true_face_wrenches[:, out]) ** 2, axis=(0, 1)))
    assert err[:3].max() < 0.01 and err[3:].max() < 1e-4
    # on loads like the calibration's, the prior changes nothing but the noise of 6 more directions
    same = make_session(K, flange=flange, connected_face=6, k=400, noise=0, seed=9, free_only=True, counts_dtype=float)
    np.testing.assert_allclose(cal.wrenches(same.counts, offset=same.true_offset)[:, out],
                               plain.wrenches(same.counts, offset=same.true_offset)[:, out],
                               atol=0.02 * np.abs(same.true_face_wrenches).max())
    if method != "quasi_total":
        eq = equilibrium(W, cal.core, mass=1.0)
        truth = equilibrium(test.true_face_wrenches, cal.core, mass=1.0)
        np.testing.assert_allclose(eq.force_sum_norm, truth.force_sum_norm, atol=0.05)
        assert eq.force_sum_norm.max() > 5.0


def test_default_is_the_papers_plain_least_squares_blind_to_net_loads():
    from pito_core.calibration import equilibrium

    K = true_sensitivity(32, coupling=0.0)
    s = make_session(K, flange="face", connected_face=6, k=800, noise=2.0, free_only=True)
    plain = calibrate(s, "unloaded_frame")
    assert plain.meta["prior"] is None and plain.meta["load_rank"] == [30] and plain.meta["counts_rank"] == [36]
    assert plain.meta["load_directions"] == {"measured": 30, "from_prior": 0, "not_identified": 6}
    # rows of the connected face are (nearly) minus the others': blind to net loads
    test = make_session(K, flange="frame_hole", connected_face=6, k=100, noise=2.0, seed=3)
    eq = equilibrium(plain.wrenches(test.counts, offset=test.true_offset), plain.core, mass=1.0)
    truth = equilibrium(test.true_face_wrenches, plain.core, mass=1.0)
    assert np.median(eq.force_sum_norm) < 0.1 * np.median(truth.force_sum_norm)
    with pytest.raises(TypeError, match="min_snr"):
        calibrate(s, "unloaded_frame", min_snr=30)
    with pytest.raises(ValueError, match=r"prior: expected None or 'own_gauge', got 'ridge'"):
        calibrate(s, "unloaded_frame", prior="ridge")


@pytest.mark.parametrize("method", ["total", "unloaded_frame"])
def test_a_frame_hole_session_measures_the_net_load_directions(method):
    """A face-flange session with a ``frame_hole`` session: every load direction is fitted from data."""
    from pito_core.calibration import equilibrium

    K = true_sensitivity(34)  # with coupling: no prior could get the net loads right
    face = make_session(K, flange="face", connected_face=6, k=1500, noise=2.0, free_only=True)
    hole = make_session(K, flange="frame_hole", connected_face=5, k=300, noise=2.0, seed=5)
    cal = calibrate([face, hole], method)
    assert cal.meta["net_load"] == "measured" and cal.meta["load_rank"] == [36]
    assert cal.meta["flanges"] == ["face", "frame_hole"]
    test = make_session(K, flange="frame_hole", connected_face=6, k=300, noise=2.0, seed=11)
    W = cal.wrenches(test.counts, offset=test.true_offset)
    eq = equilibrium(W, cal.core, mass=1.0)
    truth = equilibrium(test.true_face_wrenches, cal.core, mass=1.0)
    np.testing.assert_allclose(eq.force_sum_norm, truth.force_sum_norm, atol=0.1)
    with pytest.raises(ValueError, match=r"needs at least one session with a flange in \('face',\)"):
        calibrate([hole], method)

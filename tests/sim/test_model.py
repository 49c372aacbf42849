"""The virtual cube: reproducibility, conditioning, drift, noise, saturation, validation."""

import numpy as np
import pytest

from pito_core.sim import SimParams, VirtualCube, hub_sensitivity


def _loads(n, seed=0, scale=(15, 15, 15, 0.1, 0.1, 0.1)):
    rng = np.random.default_rng(seed)
    return rng.uniform(-1, 1, (n, 6, 6)) * np.asarray(scale)


def test_same_seed_same_cube_and_counts():
    a, b = VirtualCube(seed=3), VirtualCube(seed=3)
    F = _loads(500)
    ca = a.counts_from_face_wrenches(F, rng=np.random.default_rng(1))
    cb = b.counts_from_face_wrenches(F, rng=np.random.default_rng(1))
    assert np.array_equal(a.sensitivity, b.sensitivity)
    assert np.array_equal(ca, cb)
    assert ca.dtype == np.int32 and ca.shape == (500, 36)


def test_other_seed_other_cube():
    a, b = VirtualCube(seed=0), VirtualCube(seed=1)
    assert not np.allclose(a.sensitivity, b.sensitivity)
    assert not np.allclose(a.offset, b.offset)


@pytest.mark.parametrize("seed", range(5))
def test_inverse_condition_number_in_papers_range(seed):
    icn = VirtualCube(seed=seed).inverse_condition_number()
    assert 1e-4 <= icn <= 1e-3


def test_hub_mixes_force_and_torque():
    S = hub_sensitivity(SimParams())
    # every gauge reads both a force and a torque component
    assert np.all(np.abs(S[:, :3]).max(axis=1) > 0)
    assert np.all(np.abs(S[:, 3:]).max(axis=1) > 0)
    assert np.linalg.matrix_rank(S) == 6


def test_coupling_reads_other_faces():
    cube = VirtualCube()
    M = cube.sensitivity
    off_diag = M.copy()
    for i in range(6):
        off_diag[6 * i : 6 * i + 6, 6 * i : 6 * i + 6] = 0
    assert np.abs(off_diag).max() > 0.01 * np.abs(M).max()
    # a load on face 1 moves face 2's gauges (noise-free comparison)
    p = SimParams(noise_std=0.0, temperature_amplitude=0.0)
    cube = VirtualCube(p)
    F = np.zeros((2, 6, 6))
    F[1, 0] = [10, 0, -10, 0, 0, 0.05]
    c = cube.counts_from_face_wrenches(F).astype(float)
    assert np.abs(c[1, 6:12] - c[0, 6:12]).max() > 100


def test_offsets_drift_with_temperature_only():
    cube = VirtualCube()
    assert np.allclose(cube.temperature([0.0]), 0.0)
    T = cube.temperature(np.linspace(0, 3600, 50))
    assert np.abs(T).max() > 0.05  # K: the temperature does move in an hour
    off = cube.offsets_at(np.array([0.0, 1800.0]))
    assert np.allclose(off[0], cube.offset)
    expected = cube.offset + cube.temperature([1800.0])[0] * cube.temperature_coefficient
    assert np.allclose(off[1], expected)
    assert np.abs(off[1] - off[0]).max() > 10  # counts


def test_noise_level():
    p = SimParams(temperature_amplitude=0.0)
    cube = VirtualCube(p)
    c = cube.counts_from_face_wrenches(np.zeros((20000, 6, 6)), t=np.zeros(20000)).astype(float)
    sd = c.std(axis=0)
    assert np.allclose(sd, np.hypot(p.noise_std, np.sqrt(1 / 12)), rtol=0.05)
    assert np.allclose(c.mean(axis=0), cube.offset, atol=5 * p.noise_std / np.sqrt(20000) + 1)


def test_saturation_at_adc_limits():
    cube = VirtualCube(SimParams(adc_bits=16))
    lo, hi = cube.counts_range
    assert (lo, hi) == (-32768, 32767)
    F = np.zeros((2, 6, 6))
    F[1, 4, 3] = 50.0  # N·m on face 5: far beyond the range
    c = cube.counts_from_face_wrenches(F)
    assert c.min() >= lo and c.max() <= hi
    assert np.any((c[1] == lo) | (c[1] == hi))


def test_linear_part_recovers_face_wrenches():
    p = SimParams(noise_std=0.0, temperature_amplitude=0.0, element_nonlinearity=0.0)
    cube = VirtualCube(p)
    F = _loads(200, seed=5)
    c = cube.counts_from_face_wrenches(F).astype(float) - cube.offset
    W = c @ cube.ideal_calibration().T
    assert np.allclose(W.reshape(-1, 6, 6)[..., :3], F[..., :3], atol=1e-3)


def test_frame_term_is_hysteretic():
    cube = VirtualCube()
    up = np.linspace(0, 15, 200)
    fx = np.concatenate([up, up[::-1]])
    W = np.zeros((fx.size, 6))
    W[:, 0] = fx
    extra = cube.frame_counts(W)
    # same load (7.5 N) on the way up and on the way down: different counts
    i_up, i_down = 100, fx.size - 1 - 100
    assert fx[i_up] == pytest.approx(fx[i_down])
    assert np.abs(extra[i_up] - extra[i_down]).max() > 0.5 * cube.params.frame_hysteresis * cube.signal_scale / np.sqrt(6)
    # ... and nonlinear: not proportional to the load
    slip = cube.frame_slip(W)
    assert np.all(np.abs(slip) <= 1 + 1e-12)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"edge": -1.0}, "edge"),
        ({"noise_std": -1.0}, "noise_std"),
        ({"adc_bits": 40}, "adc_bits"),
        ({"temperature_periods": ()}, "temperature_periods"),
        ({"rate": 0.0}, "rate"),
    ],
)
def test_params_validation(kwargs, match):
    with pytest.raises(ValueError, match=match):
        SimParams(**kwargs)


def test_counts_validation():
    cube = VirtualCube()
    with pytest.raises(ValueError, match="face_wrenches"):
        cube.counts_from_face_wrenches(np.zeros((3, 6)))
    with pytest.raises(ValueError, match="t:"):
        cube.counts_from_face_wrenches(np.zeros((3, 6, 6)), t=np.zeros(4))
    with pytest.raises(ValueError, match="W_frame"):
        cube.counts_from_face_wrenches(np.zeros((3, 6, 6)), W_frame=np.zeros((3, 5)))
    with pytest.raises(ValueError, match="params"):
        VirtualCube(params={"edge": 0.05})

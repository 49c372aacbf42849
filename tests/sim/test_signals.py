"""Signal building blocks: play operator, keypoint trajectories, counter-based noise."""

import numpy as np
import pytest

from pito_core.sim import KeypointTrajectory, play_operator
from pito_core.sim._signals import hashed_normal, hashed_uniform


def _naive_play(x, r, y0):
    y = np.empty_like(x)
    s = np.array(y0, dtype=float)
    for n in range(len(x)):
        s = np.minimum(np.maximum(s, x[n] - r), x[n] + r)
        y[n] = s
    return y


@pytest.mark.parametrize("seed", range(4))
def test_play_operator_matches_naive_loop(seed):
    rng = np.random.default_rng(seed)
    x = np.cumsum(rng.normal(size=(800, 3)), axis=0) * 0.2
    x[100:150, 1] = x[100, 1]  # flat stretch
    r = np.array([0.3, 0.5, 0.05])
    y0 = rng.normal(size=3) * 3
    assert np.allclose(play_operator(x, r, y0), _naive_play(x, r, y0))


def test_keypoint_trajectory_holds_and_is_monotone():
    kp = np.array([[0.0], [2.0], [-1.0], [3.0]])
    tr = KeypointTrajectory(kp, period=1.0, ramp=0.5)
    t = np.linspace(0, 3, 3001)
    v = tr(t)[:, 0]
    assert v[0] == 0 and v[-1] == pytest.approx(3.0)
    assert tr(np.array([0.75]))[0, 0] == pytest.approx(2.0)  # holding still
    seg = (t >= 1) & (t < 2)
    assert np.all(np.diff(v[seg]) <= 1e-12)  # monotone within a segment
    with pytest.raises(ValueError, match="period"):
        KeypointTrajectory(kp, period=0)
    with pytest.raises(ValueError, match="keypoints"):
        KeypointTrajectory(np.zeros(3), period=1)


def test_hashed_noise_is_a_function_of_index():
    idx = np.array([5, 9, 5, 1000])
    a = hashed_normal(7, idx, 4)
    assert np.array_equal(a[0], a[2])
    assert not np.allclose(a[0], a[1])
    assert np.array_equal(a, hashed_normal(7, idx, 4))
    assert not np.allclose(a, hashed_normal(8, idx, 4))
    u = hashed_uniform(0, np.arange(20000), 2)
    assert 0 < u.min() and u.max() < 1 and abs(u.mean() - 0.5) < 0.01
    z = hashed_normal(0, np.arange(20000), 2)
    assert abs(z.std() - 1) < 0.03

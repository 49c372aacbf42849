"""The papers' 9-point accuracy test on the 46 × 46 mm flat patch."""

import numpy as np
import pytest

from pito_core.contact import (
    ACCURACY_SQUARE,
    AccuracyResult,
    accuracy_points,
    contact_crb,
    flat_patch_accuracy,
    load_patch,
)


def test_accuracy_points_are_the_square_and_its_centre():
    xy = accuracy_points()
    assert xy.shape == (9, 2) and ACCURACY_SQUARE == 0.026
    assert np.allclose(xy[0], 0)
    edge = xy[1:]
    assert np.allclose(np.abs(edge).max(axis=1), 0.013)  # all eight on the square's edges
    assert len({tuple(p) for p in edge}) == 8


def test_exact_model_gives_zero_error():
    res = flat_patch_accuracy(torsion=0.002, force=(0.3, -0.2, -4.0))
    assert isinstance(res, AccuracyResult)
    assert res.true_points.shape == (9, 3) and res.estimated.shape == (9, 1, 3)
    assert np.allclose(res.true_points[:, 2], 0.003)
    assert res.max_error < 1e-12


def test_noisy_model_error_matches_the_bound():
    cov = np.diag([0.02**2] * 3 + [3e-4**2] * 3)
    res = flat_patch_accuracy(repeats=4000, wrench_cov=cov, rng=np.random.default_rng(40))
    assert res.errors.shape == (9, 4000)
    plane = load_patch("flat_46mm")
    bound = contact_crb(plane, res.true_points, np.tile([0, 0, -5.0], (9, 1)), cov)
    expected = np.sqrt(np.trace(bound.point_cov, axis1=1, axis2=2))
    assert np.allclose(res.point_errors / expected, 1.0, atol=0.06)
    assert 0 < res.mean_error < res.max_error


def test_measure_callable_is_used():
    calls = []

    def measure(points, forces, torsions):
        calls.append(points.copy())
        w = np.c_[forces, np.cross(points, forces)]
        w[:, 3] += 1e-4  # a biased sensor: 0.1 mN·m on tx
        return w

    res = flat_patch_accuracy(measure)
    assert len(calls) == 1 and res.estimated.shape == (9, 1, 3)
    # tx bias with fz = −5 N moves the point by 1e-4 / 5 = 20 µm along y
    assert np.allclose(res.errors, 2e-5, rtol=1e-9)


def test_bad_measure_output_raises():
    with pytest.raises(ValueError, match="measure: expected wrenches of shape"):
        flat_patch_accuracy(lambda p, f, t: np.zeros((8, 6)))
    with pytest.raises(ValueError, match="patch: expected a flat patch"):
        flat_patch_accuracy(patch="dome_r40")

"""The grasp-matrix split, normal/tangential forces and the net wrench on hand-made contacts (not the simulator)."""

import numpy as np
import pytest

from pito_core.analysis import grasp_decomposition, net_wrench, normal_tangential


def _random_rotation(rng):
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    return q * np.sign(np.diag(r))


def _two_finger_grasp(rng, n):
    """Two opposing contacts along a random axis, random squeeze and random extra forces: (point, normal, force, squeeze)."""
    point = np.full((n, 6, 3), np.nan)
    normal = np.zeros((n, 6, 3))
    force = np.zeros((n, 6, 3))
    squeeze = rng.uniform(0.5, 10, n)
    for j in range(n):
        R = _random_rotation(rng)
        d = R[:, 0]
        mid = rng.uniform(-0.02, 0.02, 3)
        half = rng.uniform(0.01, 0.05)
        point[j, 0], point[j, 3] = mid - half * d, mid + half * d
        normal[j, 0], normal[j, 3] = -d, d
        common = rng.normal(0, 2, 3)  # a common force, carried half by each finger
        force[j, 0] = squeeze[j] * d + common / 2
        force[j, 3] = -squeeze[j] * d + common / 2
    return point, normal, force, squeeze


def test_two_finger_internal_force_is_the_squeeze():
    rng = np.random.default_rng(1)
    point, normal, force, squeeze = _two_finger_grasp(rng, 50)
    active = np.zeros((50, 6), bool)
    active[:, [0, 3]] = True
    f_m, f_i = grasp_decomposition(point, force, active, cog=rng.uniform(-0.01, 0.01, 3))
    np.testing.assert_allclose(np.linalg.norm(f_i[:, 0], axis=1), squeeze, rtol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(f_i[:, 3], axis=1), squeeze, rtol=1e-9)
    np.testing.assert_allclose(f_m + f_i, np.where(active[..., None], force, 0), atol=1e-12)
    # the common force is split equally and carries no squeeze
    np.testing.assert_allclose(f_m[:, 0], f_m[:, 3], atol=1e-9)
    assert np.all(f_i[:, [1, 2, 4, 5]] == 0)


def _grasp_matrix(p, c):
    G = np.zeros((6, 3 * len(p)))
    for k, r in enumerate(p - c):
        G[:3, 3 * k:3 * k + 3] = np.eye(3)
        G[3:, 3 * k:3 * k + 3] = [[0, -r[2], r[1]], [r[2], 0, -r[0]], [-r[1], r[0], 0]]
    return G


@pytest.mark.parametrize("seed", range(5))
def test_split_against_lstsq_and_independent_of_reference_point(seed):
    rng = np.random.default_rng(seed)
    n = 20
    active = rng.random((n, 6)) < 0.6
    active[:, 0] = True
    point = rng.uniform(-0.04, 0.04, (n, 6, 3))
    force = rng.normal(0, 3, (n, 6, 3))
    c1, c2 = rng.uniform(-0.02, 0.02, (2, 3))
    f_m, f_i = grasp_decomposition(point, force, active, c1)
    f_m2, f_i2 = grasp_decomposition(point, force, active, c2)
    np.testing.assert_allclose(f_m, f_m2, atol=1e-9)
    for j in range(n):
        k = np.flatnonzero(active[j])
        G = _grasp_matrix(point[j, k], c1)
        f = force[j, k].ravel()
        naive = np.linalg.lstsq(G, G @ f, rcond=None)[0]  # minimum-norm forces with the same net wrench
        np.testing.assert_allclose(f_m[j, k].ravel(), naive, atol=1e-8)
        np.testing.assert_allclose(G @ f_i[j, k].ravel(), 0, atol=1e-9)  # internal: no net wrench
        assert abs(f_m[j, k].ravel() @ f_i[j, k].ravel()) < 1e-8  # orthogonal parts


def test_normal_tangential_and_net_wrench():
    rng = np.random.default_rng(7)
    n = 30
    normal = rng.normal(size=(n, 6, 3))
    normal /= np.linalg.norm(normal, axis=2, keepdims=True)
    fn, ft = rng.uniform(0, 5, (2, n, 6))
    tang = np.cross(normal, rng.normal(size=(n, 6, 3)))
    tang /= np.linalg.norm(tang, axis=2, keepdims=True)
    force = -fn[..., None] * normal + ft[..., None] * tang
    active = rng.random((n, 6)) < 0.7
    got_n, got_t = normal_tangential(force, normal, active)
    np.testing.assert_allclose(got_n, np.where(active, fn, 0), atol=1e-12)
    np.testing.assert_allclose(got_t, np.where(active, ft, 0), atol=1e-12)
    point = rng.uniform(-0.03, 0.03, (n, 6, 3))
    torsion = rng.normal(0, 0.01, (n, 6))
    c = np.array([0.001, -0.002, 0.003])
    F, M = net_wrench(point, force, torsion, normal, active, c)
    for j in range(n):
        k = active[j]
        np.testing.assert_allclose(F[j], force[j, k].sum(axis=0), atol=1e-12)
        m = sum(np.cross(point[j, i] - c, force[j, i]) + torsion[j, i] * normal[j, i] for i in np.flatnonzero(k))
        np.testing.assert_allclose(M[j], m if np.ndim(m) else np.zeros(3), atol=1e-12)


def test_closed_form_split_equals_the_pinv_of_the_grasp_matrix():
    """1–6 contacts anywhere, collinear ones (rank 5 and less), NaN points of inactive contacts."""
    from pito_core.analysis._grasp import grasp_decomposition_pinv

    rng = np.random.default_rng(9)
    n = 600
    point, force = rng.uniform(-0.04, 0.04, (n, 6, 3)), rng.normal(0, 3, (n, 6, 3))
    active = rng.random((n, 6)) < rng.uniform(0.1, 1.0, (n, 1))
    line = rng.normal(size=(100, 1, 3)) * rng.uniform(-0.04, 0.04, (100, 6, 1))  # points on lines through 0
    point[:100] = line + rng.uniform(-0.02, 0.02, (100, 1, 3))
    point[~active] = np.nan
    fast = grasp_decomposition(point, force, active, cog=(0.01, 0.0, -0.02))
    slow = grasp_decomposition_pinv(point, force, active, cog=(0.01, 0.0, -0.02))
    for a, b in zip(fast, slow):
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-11)
        assert (a[~active] == 0).all()

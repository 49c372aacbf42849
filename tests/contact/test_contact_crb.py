"""Cramér–Rao covariance and the point-contact (τ = 0) weighted least-squares estimate."""

import numpy as np
import pytest
import trimesh
from contact_helpers import pushing_forces, wrench_from_contact
from scipy.spatial.transform import Rotation

from pito_core.contact import Ellipsoid, MeshSurface, Plane, Sphere, contact_crb, solve
from pito_core.contact._crb import wrench_jacobian

SIGMA = np.diag([0.01**2] * 3 + [2e-4**2] * 3)  # 10 mN, 0.2 mN·m


def _cases():
    ell = Ellipsoid([0.001, 0, -0.01], [0.03, 0.02, 0.012], Rotation.random(random_state=3).as_matrix())
    q = np.array([0.3, 0.2, 0.9]) / np.linalg.norm([0.3, 0.2, 0.9])
    return [
        ("plane", Plane([0, 0, 0.003], [0, 0, 1]), np.array([0.01, -0.005, 0.003])),
        ("sphere", Sphere([0, 0, -0.02], 0.04), np.array([0.0, 0.0, -0.02]) + 0.04 * q),
        ("ellipsoid", ell, ell.center + ell.rotation @ (ell.semi_axes * q)),
        ("mesh", MeshSurface(trimesh.creation.box(extents=(0.05, 0.05, 0.006))), np.array([0.01, 0.004, 0.003])),
    ]


def _correlated_sigma(rng):
    A = rng.normal(size=(6, 6)) * 0.2 + np.eye(6)
    D = np.diag([0.01] * 3 + [2e-4] * 3)
    return D @ (A @ A.T) @ D / 2


@pytest.mark.parametrize("name,surface,c", _cases(), ids=lambda x: x if isinstance(x, str) else "")
@pytest.mark.parametrize("point_contact", [False, True])
def test_monte_carlo_rms_within_5_percent_of_crb(name, surface, c, point_contact):
    rng = np.random.default_rng(20)
    n = surface.normal_at(c[None]) if name != "mesh" else np.array([[0, 0, 1.0]])
    f = pushing_forces(rng, n, max_deg=40.0, magnitude=(3, 3))
    tau = 0.0 if point_contact else 0.003
    w0 = wrench_from_contact(c, f, [tau], n)[0]
    for S in (SIGMA, _correlated_sigma(rng)):
        K = 20000
        w = w0 + rng.multivariate_normal(np.zeros(6), S, size=K)
        est = solve(surface, w, point_contact=point_contact, wrench_cov=S)
        assert est.valid.all()
        rms = np.sqrt(np.mean(np.sum((est.point - c) ** 2, axis=1)))
        crb = contact_crb(surface, c[None], f, S, torsion=[tau], normal=n, point_contact=point_contact)
        bound = np.sqrt(np.trace(crb.point_cov[0]))
        assert rms / bound == pytest.approx(1.0, abs=0.05)
        # the per-sample covariance reported by solve is the bound at the estimate
        assert np.trace(est.point_cov, axis1=1, axis2=2).mean() == pytest.approx(bound**2, rel=0.05)


def test_point_contact_bound_is_tighter_than_soft_finger():
    rng = np.random.default_rng(21)
    s = Sphere([0, 0, 0], 0.03)
    q = rng.normal(size=(100, 3))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    c, n = 0.03 * q, q
    f = pushing_forces(rng, n, max_deg=60.0)
    soft = contact_crb(s, c, f, SIGMA)
    point = contact_crb(s, c, f, SIGMA, point_contact=True)
    ts = np.trace(soft.point_cov, axis1=1, axis2=2)
    tp = np.trace(point.point_cov, axis1=1, axis2=2)
    assert np.all(tp <= ts * (1 + 1e-9))
    assert np.all(point.torsion_var == 0) and np.all(soft.torsion_var > 0)
    # the point covariance lies in the tangent plane
    assert np.abs(np.einsum("nij,nj->ni", soft.point_cov, n)).max() < 1e-12 * ts.max()


def test_jacobian_matches_finite_differences():
    rng = np.random.default_rng(22)
    e = Ellipsoid([0.001, 0.002, -0.01], [0.03, 0.02, 0.012], Rotation.random(random_state=4).as_matrix())
    q = rng.normal(size=(20, 3))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    c = e.center + (q * e.semi_axes) @ e.rotation.T
    n = e.normal_at(c)
    f = pushing_forces(rng, n)
    tau = 0.01 * rng.normal(size=20)
    J, T = wrench_jacobian(c, n, e._shape_operator(c, n), f, tau)

    def model(x, k):
        ck = e._retract((c[k] + T[k] @ x[:2])[None])
        nk = e.normal_at(ck)[0]
        return np.r_[x[2:5], np.cross(ck[0], x[2:5]) + x[5] * nk]

    for k in range(20):
        x0 = np.r_[0.0, 0.0, f[k], tau[k]]
        h = 1e-7
        Jn = np.column_stack([(model(x0 + h * np.eye(6)[j], k) - model(x0 - h * np.eye(6)[j], k)) / (2 * h)
                              for j in range(6)])
        assert np.allclose(J[k], Jn, atol=1e-6, rtol=1e-6)


def test_point_contact_exact_data_and_single_wrench():
    rng = np.random.default_rng(23)
    s = Ellipsoid([0, 0, -0.01], [0.03, 0.02, 0.015])
    q = np.array([0.2, -0.3, 0.93]) / np.linalg.norm([0.2, -0.3, 0.93])
    c = s.center + s.semi_axes * q
    n = s.normal_at(c[None])
    f = pushing_forces(rng, n, max_deg=70.0)[0]
    est = solve(s, np.r_[f, np.cross(c, f)], point_contact=True)
    assert est.valid and np.abs(est.point - c).max() < 1e-9 and est.torsion == 0.0
    assert np.allclose(est.force, f, atol=1e-12)


def test_point_contact_beats_soft_finger_when_tau_is_zero():
    rng = np.random.default_rng(24)
    s = Sphere([0, 0, -0.02], 0.04)
    c = np.array([0.0, 0.01, -0.02 + np.sqrt(0.04**2 - 0.01**2)])
    n = s.normal_at(c[None])
    f = pushing_forces(rng, n, max_deg=50.0, magnitude=(3, 3))
    w = wrench_from_contact(c, f, [0.0], n)[0] + rng.multivariate_normal(np.zeros(6), SIGMA, size=20000)
    e_soft = solve(s, w, wrench_cov=SIGMA)
    e_point = solve(s, w, wrench_cov=SIGMA, point_contact=True)
    rms = [np.sqrt(np.mean(np.sum((e.point - c) ** 2, axis=1))) for e in (e_soft, e_point)]
    assert rms[1] < rms[0]


def test_covariance_rows_for_invalid_contacts_are_nan():
    s = Sphere([0, 0, 0], 0.02)
    est = solve(s, [[0, 0, -1.0, 0, 0, 0], [0, 0, 0.001, 0, 0, 0]], wrench_cov=SIGMA)
    assert np.isfinite(est.point_cov[0]).all() and np.isnan(est.point_cov[1]).all()
    assert np.isfinite(est.force_cov[0]).all() and np.isfinite(est.torsion_var[0])

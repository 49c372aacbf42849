"""Closed-form soft-finger solutions on planes, spheres and ellipsoids (exact and hard cases)."""

import numpy as np
import pytest
from contact_helpers import pushing_forces, random_on_ellipsoid, wrench_from_contact
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from pito_core.contact import Ellipsoid, Plane, Sphere, solve

EXACT = 1e-9  # m, the bound on exact wrenches


def _ellipsoids():
    rot = Rotation.random(4, random_state=11).as_matrix()
    return [
        Ellipsoid([0.001, -0.002, 0.003], [0.03, 0.02, 0.01], rot[0]),
        Ellipsoid([0, 0, -0.01], [0.02, 0.02, 0.02], rot[1]),  # equal axes
        Ellipsoid([0, 0, 0], [0.021, 0.02, 0.0199], rot[2]),  # sphere-like
        Ellipsoid([0, 0, -0.001], [0.03, 0.025, 1e-4], rot[3]),  # very flat
        Ellipsoid([0, 0, 0], [0.03, 0.03, 1e-6]),  # semi-axis near 0
        Ellipsoid([0.1, 0.0, -0.4], [0.5, 0.3, 0.005]),  # mixed scales
        Ellipsoid([0, 0, 0], [0.005, 0.5, 0.05]),
    ]


def _spheres():
    return [Sphere([0, 0, -0.02], 0.04), Sphere([0.001, -0.002, 0.003], 0.005),
            Sphere([0, 0, -0.45], 0.5)]


@pytest.mark.parametrize("surface", _ellipsoids() + _spheres(), ids=repr)
@pytest.mark.parametrize("tau_scale", [0.0, 1e-3, 0.05])
def test_exact_wrenches_recover_contact_on_quadrics(surface, tau_scale):
    rng = np.random.default_rng(1)
    N = 4000
    c, n = random_on_ellipsoid(rng, surface, N)
    f = pushing_forces(rng, n, max_deg=85.0)
    tau = tau_scale * rng.normal(size=N)
    est = solve(surface, wrench_from_contact(c, f, tau, n), force_threshold=0.1)
    assert est.valid.all()
    assert np.abs(est.point - c).max() < EXACT
    assert np.abs(est.normal - n).max() < 1e-6 * max(1.0, surface.semi_axes.max() / surface.semi_axes.min())
    assert np.abs(est.torsion - tau).max() < 1e-9
    assert np.array_equal(est.force, f)
    assert np.all(np.einsum("ij,ij->i", est.force, est.normal) < 0)  # the pushing side


@pytest.mark.parametrize("tau_scale", [0.0, 0.02])
def test_exact_wrenches_recover_contact_on_planes(tau_scale):
    rng = np.random.default_rng(2)
    for _ in range(5):
        normal = rng.normal(size=3)
        normal /= np.linalg.norm(normal)
        point = rng.normal(size=3) * 0.01
        plane = Plane(point, normal)
        N = 2000
        c = plane._retract(point + rng.normal(size=(N, 3)) * 0.02)
        n = np.tile(plane.normal, (N, 1))
        f = pushing_forces(rng, n, max_deg=85.0)
        tau = tau_scale * rng.normal(size=N)
        est = solve(plane, wrench_from_contact(c, f, tau, n))
        assert est.valid.all()
        assert np.abs(est.point - c).max() < EXACT
        assert np.abs(est.torsion - tau).max() < 1e-12
        assert np.allclose(est.normal, plane.normal)


def test_plane_matches_analytic_reference():
    # Pressing straight down at (0.01, −0.02) on z = 0.003 with 2 N and 0.01 N·m torsion.
    w = [0, 0, -2.0, 0.04, 0.02, 0.01]  # c × f = (0.04, 0.02, 0)
    est = solve(Plane([0, 0, 0.003], [0, 0, 1]), w)
    assert est.point.shape == (3,) and est.valid.shape == ()
    assert np.allclose(est.point, [0.01, -0.02, 0.003], atol=1e-15)
    assert est.torsion == pytest.approx(0.01)


def test_sphere_matches_analytic_reference():
    # Sphere r = 0.04 at the origin; the pole (0, 0, 0.04) pushed down with a tangential part.
    f = np.array([0.3, 0.0, -2.0])
    c = np.array([0.0, 0.0, 0.04])
    w = np.r_[f, np.cross(c, f) + 0.005 * np.array([0, 0, 1.0])]
    est = solve(Sphere([0, 0, 0], 0.04), w)
    assert np.allclose(est.point, c, atol=1e-15)
    assert est.torsion == pytest.approx(0.005, abs=1e-15)


def test_closed_form_matches_generic_nonlinear_solve():
    """Naive reference: a generic least-squares solve of the three moment equations."""
    rng = np.random.default_rng(3)
    surf = _ellipsoids()[0]
    a, R, c0 = surf.semi_axes, surf.rotation, surf.center
    c, n = random_on_ellipsoid(rng, surf, 30)
    f = pushing_forces(rng, n, max_deg=70.0)
    tau = 0.01 * rng.normal(size=30)
    w = wrench_from_contact(c, f, tau, n)
    est = solve(surf, w)
    for k in range(30):
        def resid(x):
            th, ph, t = x
            q = np.array([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)])
            p = c0 + R @ (a * q)
            nn = R @ (q / a)
            nn /= np.linalg.norm(nn)
            return np.cross(p, w[k, :3]) + t * nn - w[k, 3:]
        q0 = R.T @ (est.point[k] - c0) / a  # start from the estimate, perturbed
        x0 = [np.arccos(np.clip(q0[2], -1, 1)) + 0.05, np.arctan2(q0[1], q0[0]) - 0.05, 0.0]
        sol = least_squares(resid, x0, xtol=1e-15, ftol=1e-15, gtol=1e-15)
        th, ph, t = sol.x
        q = np.array([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)])
        assert np.linalg.norm(c0 + R @ (a * q) - est.point[k]) < 1e-9
        assert t == pytest.approx(est.torsion[k], abs=1e-9)


def test_sphere_path_equals_ellipsoid_path_with_equal_axes():
    rng = np.random.default_rng(4)
    s = Sphere([0.002, 0.0, -0.01], 0.03)
    e = Ellipsoid([0.002, 0.0, -0.01], [0.03] * 3, Rotation.random(random_state=5).as_matrix())
    w = np.c_[rng.normal(size=(500, 3)), 0.05 * rng.normal(size=(500, 3))]
    a, b = solve(s, w), solve(e, w)
    assert np.array_equal(a.valid, b.valid)
    assert np.nanmax(np.abs(a.point - b.point)) < 1e-12


def test_exact_point_contacts_give_no_nan():
    """τ = 0 exactly: the torsion root collapses; the classical formula divides 0 by 0."""
    rng = np.random.default_rng(5)
    for surf in _ellipsoids() + _spheres():
        c, n = random_on_ellipsoid(rng, surf, 500)
        f = pushing_forces(rng, n)
        w = np.c_[f, np.cross(c, f)]
        est = solve(surf, w)
        assert est.valid.all()
        assert np.isfinite(est.point).all()
        assert np.abs(est.point - c).max() < EXACT
        assert np.abs(est.torsion).max() < 1e-9


def test_tiny_torsion_is_continuous_no_cancellation():
    """τ → 0: the estimate moves by no more than the torsion's own effect."""
    surf = _ellipsoids()[0]
    rng = np.random.default_rng(6)
    c, n = random_on_ellipsoid(rng, surf, 200)
    f = pushing_forces(rng, n, max_deg=80.0)
    for tau in (1e-6, 1e-9, 1e-12, 1e-15):
        est = solve(surf, wrench_from_contact(c, f, np.full(200, tau), n))
        assert est.valid.all()
        assert np.abs(est.point - c).max() < 1e-12
        rel = np.abs(est.torsion - tau) / tau
        assert rel.max() < 1e-3 if tau >= 1e-12 else np.abs(est.torsion - tau).max() < 1e-15


def test_low_noise_error_scales_with_noise():
    rng = np.random.default_rng(7)
    surf = Sphere([0, 0, -0.02], 0.04)
    c, n = random_on_ellipsoid(rng, surf, 1000, upper_only=True)
    f = pushing_forces(rng, n, max_deg=60.0, magnitude=(2, 5))
    w = wrench_from_contact(c, f, np.zeros(1000), n)
    errs = []
    for sigma in (1e-6, 1e-9, 1e-12):
        est = solve(surf, w + sigma * rng.normal(size=w.shape))
        assert est.valid.all()
        errs.append(np.abs(est.point - c).max())
    assert errs[1] < errs[0] * 1e-2 and errs[2] < errs[1] * 1e-1


def test_forces_at_85_degrees_pick_the_pushing_side():
    rng = np.random.default_rng(8)
    for surf in [Plane([0, 0, 0], [0, 0, 1])] + _ellipsoids() + _spheres():
        if isinstance(surf, Plane):
            c = np.c_[rng.uniform(-0.02, 0.02, (300, 2)), np.zeros(300)]
            n = np.tile([0, 0, 1.0], (300, 1))
        else:
            c, n = random_on_ellipsoid(rng, surf, 300)
        f = pushing_forces(rng, n, exact_deg=85.0)
        est = solve(surf, wrench_from_contact(c, f, 0.01 * rng.normal(size=300), n))
        assert est.valid.all()
        assert np.abs(est.point - c).max() < EXACT


def test_grazing_line_of_action_does_not_jump_sides():
    """Just inside tangency (89.9°) the entry point is kept, never the exit point."""
    surf = Sphere([0, 0, 0], 0.02)
    c = np.array([[0.0, 0.0, 0.02]])
    n = np.array([[0.0, 0.0, 1.0]])
    th = np.radians(89.9)
    f = 3 * np.array([[np.sin(th), 0.0, -np.cos(th)]])
    est = solve(surf, wrench_from_contact(c, f, [0.0], n))
    assert est.valid[0] and np.abs(est.point - c).max() < EXACT


def test_force_under_threshold_and_pulling_are_not_valid():
    sphere = Sphere([0, 0, 0], 0.02)
    w = np.array([
        [0, 0, -0.01, 0, 0, 0],  # under the threshold
        [0, 0, 0, 0, 0, 0],  # no force at all
        [np.nan] * 6,  # face without output
        [0, 0, -2.0, 0, 0, 0],  # valid: top of the sphere
        [0, 0.0, 2.0, 0.1, 0.0, 0.0],  # line of action misses the sphere (τ = 0)
    ])
    est = solve(sphere, w, force_threshold=0.05)
    assert est.valid.tolist() == [False, False, False, True, False]
    assert np.isnan(est.point[[0, 1, 2, 4]]).all() and np.isnan(est.torsion[[0, 1, 2, 4]]).all()
    assert np.allclose(est.point[3], [0, 0, 0.02])
    plane = solve(Plane([0, 0, 0], [0, 0, 1]), [[0, 0, 1.0, 0, 0, 0], [1.0, 0, 0, 0, 0, 0]])
    assert not plane.valid.any() and np.isnan(plane.point).all()


def test_any_wrench_never_raises_and_valid_rows_are_consistent():
    """Random wrenches: no exception, NaN exactly where invalid, the model holds elsewhere."""
    rng = np.random.default_rng(9)
    w = np.c_[rng.normal(size=(20000, 3)), 0.05 * rng.normal(size=(20000, 3))]
    for surf in [Plane([0, 0, 0.001], [0.1, 0, 1])] + _ellipsoids() + _spheres():
        est = solve(surf, w)
        v = est.valid
        assert v.any()
        assert np.isnan(est.point[~v]).all() and np.isfinite(est.point[v]).all()
        m = np.cross(est.point[v], est.force[v]) + est.torsion[v, None] * est.normal[v]
        assert np.abs(m - w[v, 3:]).max() < 1e-9 * max(1.0, surf.semi_axes.max() if hasattr(surf, "semi_axes") else 1)
        assert np.all(np.einsum("ij,ij->i", est.force[v], est.normal[v]) < 0)


def test_batch_shapes():
    surf = Sphere([0, 0, 0], 0.02)
    w = np.zeros((4, 5, 6))
    w[..., 2] = -1.0
    est = solve(surf, w)
    assert est.point.shape == (4, 5, 3) and est.valid.shape == (4, 5) and est.torsion.shape == (4, 5)
    assert np.allclose(est.point[..., 2], 0.02)
    empty = solve(surf, np.zeros((0, 6)))
    assert empty.point.shape == (0, 3)

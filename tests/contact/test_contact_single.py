"""Single-contact plausibility: the contract (fields, reasons, patch friction) and the issue's case."""

import json

import numpy as np
import pytest

from pito_core.contact import (
    DEFAULT_FRICTION,
    SingleContactReason,
    load_assembly,
    load_patch,
    patches_dir,
    reason_names,
    solve,
    solve_object,
)

NOISE = np.diag([0.02**2] * 3 + [0.0005**2] * 3)  # 20 mN, 0.5 mN·m


def _wrench(points, forces):
    points, forces = np.asarray(points, float), np.asarray(forces, float)
    return np.r_[forces.sum(0), np.cross(points, forces).sum(0)]


def test_two_fingers_twisting_on_the_flat_patch_are_flagged_as_torsion():
    # the case: 30 mm apart, 3 N tangential each in opposite directions, 3 N pressing each
    w = _wrench([[0.015, 0, 0.003], [-0.015, 0, 0.003]], [[0, 3, -3], [0, -3, -3]])
    est = solve(load_patch("flat_46mm"), w, wrench_cov=NOISE)
    assert est.valid and est.torsion == pytest.approx(0.09)
    assert not est.single_contact
    assert est.single_contact_p < 1e-6
    assert est.single_contact_reason == SingleContactReason.TORSION
    assert reason_names(est.single_contact_reason) == "torsion"


def test_one_pressing_finger_is_plausible_and_no_force_is_not_judged():
    w = np.array([_wrench([[0.01, -0.005, 0.003]], [[0.3, 0.2, -4.0]]), np.zeros(6), np.full(6, np.nan)])
    est = solve(load_patch("flat_46mm"), w, wrench_cov=NOISE)
    assert est.single_contact.tolist() == [True, False, False]
    assert est.single_contact_p[0] > 0.5 and np.isnan(est.single_contact_p[1:]).all()
    assert est.single_contact_reason.tolist() == [0, SingleContactReason.NO_FORCE, SingleContactReason.NO_FORCE]
    assert est.single_contact_reason.dtype == np.int8


def test_reasons_pulling_friction_outside():
    patch = load_patch("flat_46mm")
    w = np.array([
        _wrench([[0.0, 0.0, 0.003]], [[0.0, 0.0, 3.0]]),  # pulls
        _wrench([[0.0, 0.0, 0.003]], [[3.0, 0.0, -1.0]]),  # shear 3x the normal force
        _wrench([[0.040, 0.0, 0.003]], [[0.0, 0.0, -3.0]]),  # 17 mm off the plate
    ])
    est = solve(patch, w, wrench_cov=NOISE)
    assert not est.single_contact.any()
    assert reason_names(est.single_contact_reason).tolist() == ["pulling", "friction", "outside"]


def test_point_contact_residual_flags_a_torsion():
    w = _wrench([[0.015, 0, 0.003], [-0.015, 0, 0.003]], [[0, 3, -3], [0, -3, -3]])
    est = solve(load_patch("flat_46mm"), w, point_contact=True, wrench_cov=NOISE)
    assert not est.single_contact and est.single_contact_reason == SingleContactReason.RESIDUAL


def test_object_contacts_carry_the_flag_per_face():
    W = np.zeros((2, 6, 6))
    W[0, 5] = _wrench([[0.015, 0, 0.003], [-0.015, 0, 0.003]], [[0, 3, -3], [0, -3, -3]])  # face 6: flat
    W[1, 5] = _wrench([[0.01, 0, 0.003]], [[0, 0, -3]])
    oc = solve_object(load_assembly("pito_mixed"), W, wrench_cov=NOISE)
    assert oc.single_contact.shape == oc.single_contact_p.shape == oc.single_contact_reason.shape == (2, 6)
    assert oc.flagged().tolist() == [[False] * 5 + [True], [False] * 6]
    assert oc.single_contact[1, 5] and (oc.single_contact_reason[:, :5] == SingleContactReason.NO_FORCE).all()


def test_patch_file_sets_friction_and_rejects_bad_values(tmp_path):
    d = json.loads(patches_dir().joinpath("flat_46mm.json").read_text())
    assert load_patch("flat_46mm").mu == DEFAULT_FRICTION or "friction" in d
    d["friction"] = {"mu": 0.2, "torsion_radius": 0.004}
    (tmp_path / "p.json").write_text(json.dumps(d))
    p = load_patch(tmp_path / "p.json")
    assert (p.mu, p.torsion_radius) == (0.2, 0.004)
    w = _wrench([[0.0, 0.0, 0.003]], [[1.0, 0.0, -3.0]])  # shear 1/3 of the normal force
    assert solve(load_patch("flat_46mm"), w, wrench_cov=NOISE).single_contact
    assert solve(p, w, wrench_cov=NOISE).single_contact_reason == SingleContactReason.FRICTION
    d["friction"] = {"mu": -1}
    (tmp_path / "q.json").write_text(json.dumps(d))
    with pytest.raises(ValueError, match="mu"):
        load_patch(tmp_path / "q.json")


def _pushes(surf, axes, k, rng):
    """``k`` contacts on the upper part of a sphere or ellipsoid ``surf`` (semi-axes ``axes``, m):
    points, normals, forces pushing in (N) with a random shear, torsions (N·m)."""
    q = rng.normal(size=(k, 3))
    q[:, 2] = np.abs(q[:, 2]) + 0.5
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    c = surf.center + q * axes
    n = surf.normal_at(c)
    return c, n, -3.0 * n + rng.normal(size=(k, 3)), rng.uniform(-0.005, 0.005, k)


def test_fast_variance_equals_the_cramer_rao_propagation_and_the_test_can_be_skipped():
    from pito_core.contact import Ellipsoid
    from pito_core.contact._crb import covariance_from_jacobian, wrench_jacobian
    from pito_core.contact._plausibility import param_variance, soft_finger_variance

    rng = np.random.default_rng(3)
    surf = Ellipsoid([0.0, 0.0, -0.01], [0.03, 0.02, 0.015])
    c, n, f, tau = _pushes(surf, surf.semi_axes, 50, rng)
    A = rng.normal(size=(6, 6))
    S = A @ A.T * 1e-4 + np.diag([1e-3] * 3 + [1e-7] * 3)
    J, T = wrench_jacobian(c, n, surf._shape_operator(c, n), f, tau)
    grad = rng.normal(size=(50, 6))
    rows = np.arange(50)
    np.testing.assert_allclose(soft_finger_variance(J, c, S)(grad, rows),
                               param_variance(covariance_from_jacobian(J, T, S).param_cov)(grad, rows), rtol=1e-8)
    est = solve(surf, np.c_[f, np.cross(c, f) + tau[:, None] * n], single_contact=False)
    assert est.single_contact is None and est.single_contact_p is None and est.valid.all()


def test_variances_take_several_gradients_at_once():
    # the single-contact test asks for the pushing and friction limits' variances in one call:
    # grad (2, n, k) gives each slice's variance, with a shared or a per-row covariance, any rows
    from pito_core.contact import Sphere
    from pito_core.contact._crb import covariance_from_jacobian, wrench_jacobian
    from pito_core.contact._plausibility import param_variance, soft_finger_variance

    rng = np.random.default_rng(5)
    surf = Sphere([0.0, 0.0, -0.02], 0.04)
    c, n, f, tau = _pushes(surf, surf.radius, 20, rng)
    A = rng.normal(size=(20, 6, 6))
    S_rows = A @ np.swapaxes(A, 1, 2) * 1e-4 + np.diag([1e-3] * 3 + [1e-7] * 3)
    J, T = wrench_jacobian(c, n, surf._shape_operator(c, n), f, tau)
    for S in (S_rows[0], S_rows):
        for rows in (slice(None), np.array([3, 0, 7, 19])):
            for k in (6, 5, 2):
                grad = rng.normal(size=(2, 20, k))[:, rows]
                for var in (soft_finger_variance(J, c, S), param_variance(covariance_from_jacobian(J, T, S).param_cov)):
                    both = var(grad, rows)
                    assert both.shape == grad.shape[:2]
                    np.testing.assert_allclose(both, [var(grad[0], rows), var(grad[1], rows)], rtol=1e-12)

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

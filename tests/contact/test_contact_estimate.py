"""The one contact record, ``ContactEstimate``: its frame, batch shapes, indexing and joining."""

import numpy as np
import pytest

from pito_core.contact import Assembly, ContactEstimate, load_assembly, load_patch, solve, solve_object
from pito_core.frames import FACES, CubeCore

NOISE = np.diag([0.02, 0.02, 0.02, 2e-5, 2e-5, 2e-5]) ** 2  # N², (N·m)²


def _flat_wrenches(rng, n, offset=0.003):
    """Exact soft-finger wrenches ``(n, 6)`` of contacts on a flat 46 mm patch (plane z = offset), face frame."""
    c = np.c_[rng.uniform(-0.02, 0.02, (n, 2)), np.full(n, offset)]
    f = np.c_[rng.uniform(-1, 1, (n, 2)), -rng.uniform(2, 6, n)]  # pushing in, inside a μ = 1 cone
    tau = rng.uniform(-2e-3, 2e-3, n)
    return np.c_[f, np.cross(c, f) + tau[:, None] * [0, 0, 1]]


def test_solve_object_is_the_face_solves_moved_to_the_core_frame():
    # a core unlike the simulated cube's (edge 0.08 m): the rotation and offset of every face matter
    core = CubeCore(edge=0.08)
    flat = load_patch("flat_46mm")
    asm = Assembly("flat_80", core, {i: flat for i in FACES})
    rng = np.random.default_rng(7)
    W = np.stack([_flat_wrenches(rng, 40) for _ in FACES], axis=1)  # (40, 6, 6)
    W[::7, 2] = np.nan  # faces without output: no contact there
    oc = solve_object(asm, W, wrench_cov=NOISE)
    assert oc.frame == "core" and oc.point.shape == (40, 6, 3) and oc.force_cov.shape == (40, 6, 3, 3)
    assert oc.valid.sum() == 40 * 6 - len(W[::7])
    for k, i in enumerate(FACES):
        T = core.face_pose(i)  # T_core_face
        R, t = T[:3, :3], T[:3, 3]
        fe = solve(flat, W[:, k], wrench_cov=NOISE)
        assert fe.frame == "face"
        np.testing.assert_allclose(oc.point[:, k], fe.point @ R.T + t, atol=1e-15)
        np.testing.assert_allclose(oc.force_cov[:, k], R @ fe.force_cov @ R.T, atol=1e-15)
        np.testing.assert_array_equal(oc.single_contact_p[:, k], fe.single_contact_p)
        # physics, in the core frame: the face's wrench moved to the core origin is [f, c × f + τ n]
        ok = oc.valid[:, k]
        f_core = W[ok, k, :3] @ R.T
        m_core = W[ok, k, 3:] @ R.T + np.cross(t, f_core)
        c, n, f, tau = oc.point[ok, k], oc.normal[ok, k], oc.force[ok, k], oc.torsion[ok, k]
        np.testing.assert_allclose(f, f_core, atol=1e-12)
        np.testing.assert_allclose(np.cross(c, f) + tau[:, None] * n, m_core, atol=1e-12)
        np.testing.assert_allclose(n, np.broadcast_to(R[:, 2], n.shape), atol=1e-12)  # the flat patch's normal is the face's z


def test_batch_shapes_and_a_mesh_face_among_analytic_ones():
    mixed = load_assembly("pito_mixed")
    patches = dict(mixed.patches)
    patches[3] = load_patch("faceted_dome")
    asm = Assembly("with_mesh", mixed.core, patches)
    rng = np.random.default_rng(2)
    W = rng.normal(size=(2, 3, 6, 6)) * [1, 1, 1, 0.02, 0.02, 0.02]
    W[..., 2] -= 4.0  # every face pushed
    oc = solve_object(asm, W)
    assert oc.point.shape == (2, 3, 6, 3) and oc.valid.shape == oc.facet.shape == (2, 3, 6)
    assert oc.point_cov is None and oc.force_cov is None and oc.torsion_var is None  # no wrench_cov
    assert (oc.facet[..., [0, 1, 3, 4, 5]] == -1).all()  # analytic patches: no facet
    mesh_face = oc.facet[..., 2]
    assert ((mesh_face >= 0) == oc.valid[..., 2]).all() and oc.valid[..., 2].any()
    one = solve_object(asm, W[1, 2])  # a single (6, 6): fields (6, …), the same numbers
    assert one.point.shape == (6, 3) and one.valid.shape == (6,)
    np.testing.assert_array_equal(one.point, oc.point[1, 2])
    np.testing.assert_array_equal(one.single_contact_reason, oc.single_contact_reason[1, 2])
    assert solve_object("cube", np.zeros((6, 6))).facet is None  # no mesh anywhere


def test_indexing_and_joining_keep_every_field():
    rng = np.random.default_rng(4)
    W = np.stack([_flat_wrenches(rng, 9) for _ in FACES], axis=1)
    oc = solve_object("cube", W, wrench_cov=NOISE)
    last = oc[-1]
    assert last.frame == "core" and last.point.shape == (6, 3) and last.point_cov.shape == (6, 3, 3)
    np.testing.assert_array_equal(last.torsion, oc.torsion[-1])
    assert last.facet is None
    parts = [oc[:4], oc[4:5], oc[5:]]
    joined = ContactEstimate.concatenate(parts)
    for name in ("point", "normal", "force", "torsion", "valid", "point_cov", "force_cov", "torsion_var",
                 "single_contact", "single_contact_p", "single_contact_reason"):
        np.testing.assert_array_equal(getattr(joined, name), getattr(oc, name), err_msg=name)
    assert ContactEstimate.concatenate([oc[:2], solve_object("cube", W[2:])]).point_cov is None  # None in one: None
    flat = solve(load_patch("flat_46mm"), W[:, 0])
    with pytest.raises(ValueError, match="estimates: expected one frame"):
        ContactEstimate.concatenate([oc, flat])
    with pytest.raises(ValueError, match="estimates: expected at least one"):
        ContactEstimate.concatenate([])


def test_flagged_and_a_record_built_by_hand():
    valid = np.array([True, True, False, False, False, False])
    hand = ContactEstimate(np.zeros((6, 3)), np.zeros((6, 3)), np.zeros((6, 3)), np.zeros(6), valid, frame="core")
    assert not hand.flagged().any() and hand.flagged().shape == (6,)  # no test: nothing flagged
    hand.single_contact = np.array([False, True, False, True, True, True])
    assert hand.flagged().tolist() == [True] + [False] * 5
    with pytest.raises(ValueError, match="frame: expected one of"):
        ContactEstimate(np.zeros((6, 3)), np.zeros((6, 3)), np.zeros((6, 3)), np.zeros(6), valid, frame="world")

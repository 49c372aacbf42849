"""``solve_object`` solves faces with alike patches together: the same numbers as one ``solve`` per face.

The reference below is the plain composition (one ``solve`` per face, then the face pose), on
random wrenches unlike the simulator's: pushing, pulling, tangent, tiny, zero and NaN faces,
with and without covariances, on every patch kind.
"""

import numpy as np
import pytest

from pito_core.contact import (
    Assembly,
    Ellipsoid,
    Patch,
    PatchBoundary,
    Plane,
    Sphere,
    load_assembly,
    load_patch,
    solve,
    solve_object,
)
from pito_core.contact._object import _face_groups
from pito_core.frames import FACES, CubeCore

NOISE = np.diag([0.02, 0.02, 0.02, 2e-5, 2e-5, 2e-5]) ** 2  # N², (N·m)²
FIELDS = ("point", "normal", "force", "torsion", "valid", "point_cov", "force_cov", "torsion_var", "facet",
          "single_contact", "single_contact_p", "single_contact_reason")


def _reference(assembly, W, force_threshold=0.05, *, point_contact=False, wrench_cov=None):
    """One ``solve`` per face, rotated to the core frame: ``{field: (M, 6, ...) or None}``."""
    lead = W.shape[:-2]
    W = W.reshape(-1, 6, 6)
    M = len(W)
    out = {k: [] for k in FIELDS}
    for i in FACES:
        cov = None if wrench_cov is None else np.asarray(wrench_cov)
        if cov is not None and cov.ndim >= 3:
            cov = cov.reshape(-1, 6, 6, 6)[:, i - 1] if cov.ndim == 4 else cov[i - 1]
            if cov.ndim == 3 and len(cov) == 1:
                cov = cov[0]
            if np.isnan(cov).all():  # a face without output (solve_object's rule)
                cov = np.eye(6)
        e = solve(assembly.patches[i], W[:, i - 1], force_threshold, point_contact=point_contact, wrench_cov=cov)
        T = assembly.core.face_pose(i)
        R, t = T[:3, :3], T[:3, 3]
        e.point, e.normal, e.force = e.point @ R.T + t, e.normal @ R.T, e.force @ R.T
        if e.point_cov is not None:
            e.point_cov, e.force_cov = R @ e.point_cov @ R.T, R @ e.force_cov @ R.T
        if e.facet is None:
            e.facet = np.full(M, -1, np.intp)
        for k in FIELDS:
            out[k].append(getattr(e, k))
    return {k: None if v[0] is None else np.stack(v, axis=1).reshape(lead + (6,) + v[0].shape[1:]) for k, v in out.items()}


def _random_wrenches(rng, M):
    """Face wrenches ``(M, 6, 6)``: mostly pushing, with pulling, tangent, tiny, zero and NaN faces."""
    f = rng.normal(size=(M, 6, 3)) * rng.uniform(0.1, 8.0, (M, 6, 1))
    f[..., 2] -= rng.uniform(-1.0, 6.0, (M, 6))  # mostly pushing in (face z out)
    m = rng.normal(size=(M, 6, 3)) * 0.03 * np.linalg.norm(f, axis=-1, keepdims=True)
    W = np.concatenate([f, m], axis=-1)
    kind = rng.integers(0, 10, (M, 6))
    W[kind == 0] = 0.0
    W[kind == 1] *= 1e-3  # below the threshold
    W[kind == 2] = np.nan
    W[kind == 3, 2] = 0.0  # a tangent force
    return W


def _assemblies():
    core = CubeCore(edge=0.07)
    sphere = Patch(Sphere([0.0, 0.0, -0.02], 0.03), PatchBoundary("ellipse", radii=[0.02, 0.018]), mu=0.7)
    flat = Patch(Plane([0, 0, 0.002], [0, 0, 1]), PatchBoundary("rectangle", size=[0.05, 0.05]))
    ell = Patch(Ellipsoid([0, 0, -0.01], [0.03, 0.025, 0.02]), PatchBoundary("rectangle", size=[0.05, 0.04]))
    other_sphere = Patch(Sphere([0.0, 0.0, -0.02], 0.03), None)  # the same surface, no boundary: its own group
    shared = Assembly("shared", core, {i: sphere for i in FACES})
    mixed = Assembly("mixed", core, {1: sphere, 2: flat, 3: ell, 4: other_sphere, 5: sphere, 6: flat})
    return [load_assembly(n) for n in ("cube", "sphere", "ellipsoid", "pito_mixed")] + [shared, mixed]


def _assert_same(got, ref):
    for k in FIELDS:
        a, b = getattr(got, k), ref[k]
        if b is None or (k == "facet" and (b == -1).all() and a is None):
            assert a is None or (k == "facet" and (a == -1).all()), k
            continue
        assert a.shape == b.shape, k
        np.testing.assert_array_equal(a, b, err_msg=k)


@pytest.mark.parametrize("point_contact", [False, True])
def test_grouped_faces_give_the_per_face_solves_bitwise(point_contact):
    rng = np.random.default_rng(11)
    for a in _assemblies():
        W = _random_wrenches(rng, 40)
        _assert_same(solve_object(a, W, point_contact=point_contact), _reference(a, W, point_contact=point_contact))
        _assert_same(solve_object(a, W, point_contact=point_contact, wrench_cov=NOISE),
                     _reference(a, W, point_contact=point_contact, wrench_cov=NOISE))
        for m in range(3):  # the live view: one sample, six faces
            _assert_same(solve_object(a, W[m]), _reference(a, W[m]))


def test_a_mesh_face_among_analytic_ones():
    mixed = load_assembly("pito_mixed")
    patches = dict(mixed.patches)
    patches[3] = patches[4] = load_patch("faceted_dome")
    a = Assembly("with_mesh", mixed.core, patches)
    assert sorted(len(faces) for _, faces in _face_groups(a)) == [1, 1, 2, 2]
    W = _random_wrenches(np.random.default_rng(3), 30)
    _assert_same(solve_object(a, W), _reference(a, W))


@pytest.mark.parametrize("point_contact", [False, True])
def test_per_face_covariances_agree_to_rounding(point_contact):
    # faces of one group with their own covariance: one batch with a covariance per row (another
    # summation order in the variance of the test, so equal to rounding, not bitwise)
    rng = np.random.default_rng(5)
    a = _assemblies()[4]
    scale = rng.uniform(0.5, 2.0, (6, 1, 1))
    covs = NOISE * scale
    covs[2] = np.nan  # a face without output: its covariance is NaN
    W = _random_wrenches(rng, 25)
    W[:, 2] = np.nan
    for cov, Wc in ((covs, W), (np.broadcast_to(covs, (25, 6, 6, 6)), W), (covs, W[0])):
        got = solve_object(a, Wc, wrench_cov=cov, point_contact=point_contact)
        ref = _reference(a, Wc, wrench_cov=cov, point_contact=point_contact)
        for k in FIELDS:
            x, y = getattr(got, k), ref[k]
            if k in ("valid", "single_contact", "single_contact_reason", "facet"):
                np.testing.assert_array_equal(x if x is not None else -1, y if k != "facet" else -1, err_msg=k)
            else:
                np.testing.assert_allclose(x, y, rtol=1e-12, atol=0, err_msg=k)


def test_groups_follow_the_patch_parameters():
    assert [faces for _, faces in _face_groups(load_assembly("cube"))] == [[0, 1, 2, 3, 4, 5]]
    assert len(_face_groups(load_assembly("ellipsoid"))) == 6  # six different caps
    assert sorted(len(f) for _, f in _face_groups(load_assembly("pito_mixed"))) == [1, 1, 4]
    assert sorted(len(f) for _, f in _face_groups(_assemblies()[5])) == [1, 1, 2, 2]


def test_the_demos_simulated_grasp_gives_the_per_face_solves_bitwise():
    # the demo's free grasp through the simulated cube's ideal calibration: noisy face wrenches, as live
    from pito_core.calibration import Calibration
    from pito_core.sim import VirtualCube, simulate_free_grasp

    cube = VirtualCube(seed=0)
    cal = Calibration("ideal", cube.ideal_calibration(), range(1, 7), "face", cube.offset, cube.core, np.eye(4))
    run = simulate_free_grasp(k=3000, seed=1, model=cube)
    W = cal.wrenches(run.counts.astype(float))[::10]
    for name in ("cube", "pito_mixed"):
        a = load_assembly(name)
        got = solve_object(a, W, 0.3)
        ref = _reference(a, W, 0.3)
        assert got.valid.sum() > 100  # the fingers are on the object
        _assert_same(got, ref)
        for m in range(0, len(W), 37):  # the live view: one sample per tick
            _assert_same(solve_object(a, W[m], 0.3), _reference(a, W[m], 0.3))

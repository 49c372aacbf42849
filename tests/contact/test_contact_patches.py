"""The patch library, assemblies (closed objects), boundaries and solve_object."""

import json
from pathlib import Path

import numpy as np
import pytest
from contact_helpers import pushing_forces, wrench_from_contact

from pito_core.contact import (
    Assembly,
    Ellipsoid,
    MeshSurface,
    Patch,
    PatchBoundary,
    Plane,
    Sphere,
    list_assemblies,
    list_patches,
    load_assembly,
    load_patch,
    patches_dir,
    solve,
    solve_object,
    surface_from_dict,
    surface_to_dict,
)
from pito_core.frames import FACES, CubeCore


def test_library_lists_and_loads_everything():
    import pito_core

    assert patches_dir() == Path(pito_core.__file__).resolve().parents[1] / "assets" / "patches"
    assert patches_dir().is_dir()
    assert {"cube", "sphere", "ellipsoid", "pito_mixed"} <= set(list_assemblies())
    names = list_patches()
    assert {"flat_46mm", "sphere_cap_r45", "dome_r40", "semi_ellipsoid_top", "faceted_dome"} <= set(names)
    for name in names:
        p = load_patch(name)
        assert isinstance(p, Patch) and p.name == name
        m = p.display_mesh()
        assert m.is_watertight and m.volume > 0


@pytest.mark.parametrize("name", ["cube", "sphere", "ellipsoid", "pito_mixed"])
def test_every_assembly_renders_a_closed_object(name):
    a = load_assembly(name)
    assert isinstance(a, Assembly) and a.core.edge == 0.05
    h = a.core.edge / 2
    for body in a.bodies():
        assert body.is_watertight and body.is_winding_consistent and body.volume > 0
    for i in FACES:
        # each patch solid sits on its face: its base lies in the face plane, inside the face
        local = a.patches[i].display_mesh().vertices
        assert local[:, 2].min() == pytest.approx(0.0, abs=1e-12)
        base = local[np.abs(local[:, 2]) < 1e-12]
        assert np.abs(base[:, :2]).max() <= h + 1e-12
        # the core-frame mesh is the face-frame mesh moved by T_core_face
        T = a.core.face_pose(i)
        assert np.allclose(a.face_mesh(i).vertices, local @ T[:3, :3].T + T[:3, 3])
    whole = a.mesh()
    assert len(whole.faces) == sum(len(b.faces) for b in a.bodies())


def test_sphere_assembly_tiles_the_ball():
    a = load_assembly("sphere")
    R = a.patches[1].surface.radius
    total = sum(b.volume for b in a.bodies())
    assert total == pytest.approx(4 / 3 * np.pi * R**3, rel=5e-3)
    # every direction from the centre lands on exactly one cap (boundaries inclusive)
    rng = np.random.default_rng(30)
    d = rng.normal(size=(20000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    hits = np.zeros(len(d), int)
    for i in FACES:
        T = a.core.face_pose(i)
        local = (R * d - T[:3, 3]) @ T[:3, :3]
        hits += a.patches[i].boundary.contains(local)
    assert np.all(hits >= 1) and np.mean(hits == 1) > 0.999


def test_ellipsoid_assembly_is_one_ellipsoid():
    a = load_assembly("ellipsoid")
    rng = np.random.default_rng(31)
    d = rng.normal(size=(5000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    ref = None
    hits = np.zeros(len(d), int)
    for i in FACES:
        s = a.patches[i].surface
        T = a.core.face_pose(i)
        # the quadric matrix of each cap, expressed in the core frame, is the same
        A_core = T[:3, :3] @ s._A @ T[:3, :3].T
        c_core = T[:3, :3] @ s.center + T[:3, 3]
        assert np.allclose(c_core, 0, atol=1e-15)
        ref = A_core if ref is None else ref
        assert np.allclose(A_core, ref, rtol=1e-12)
        pts = d / np.sqrt(np.einsum("ni,ij,nj->n", d, ref, d))[:, None]
        hits += a.patches[i].boundary.contains((pts - T[:3, 3]) @ T[:3, :3])
    assert np.all(hits >= 1)


def test_pito_mixed_is_the_papers_set():
    a = load_assembly("pito_mixed")
    assert all(isinstance(a.patches[i].surface, Sphere) for i in (1, 2, 3, 4))
    assert type(a.patches[5].surface) is Ellipsoid
    assert isinstance(a.patches[6].surface, Plane)


@pytest.mark.parametrize("name", ["cube", "sphere", "ellipsoid", "pito_mixed"])
def test_solve_object_recovers_contacts_in_core_frame(name):
    a = load_assembly(name)
    rng = np.random.default_rng(32)
    N = 300
    w = np.full((N, 6, 6), np.nan)
    truth = np.full((N, 6, 3), np.nan)
    for i in FACES:
        p = a.patches[i]
        s = p.surface
        # random points of the patch: sample the face plane and project onto the surface
        xy = rng.uniform(-0.03, 0.03, size=(4 * N, 2))
        if isinstance(s, Plane):
            c = np.c_[xy, np.full(len(xy), s.offset)]
        else:
            from pito_core.contact._display import ray_surface
            if p.boundary.projection == "central":
                o = np.tile(p.boundary.apex, (len(xy), 1))
                dirs = np.c_[xy, np.zeros(len(xy))] - o
            else:
                o = np.c_[xy, np.full(len(xy), -1.0)]
                dirs = np.tile([0, 0, 1.0], (len(xy), 1))
            c = ray_surface(s, o, dirs)
        c = c[p.boundary.contains(c)][:N]
        n = s.normal_at(c)
        f = pushing_forces(rng, n, max_deg=60.0)
        w[: len(c), i - 1] = wrench_from_contact(c, f, 0.002 * rng.normal(size=len(c)), n)
        T = a.core.face_pose(i)
        truth[: len(c), i - 1] = c @ T[:3, :3].T + T[:3, 3]
    res = solve_object(a, w)
    assert res.point.shape == (N, 6, 3) and res.valid.shape == (N, 6)
    has = np.isfinite(truth[..., 0])
    assert has.sum() > 5 * N
    assert np.array_equal(res.valid, has)
    assert np.nanmax(np.abs(res.point - truth)) < 1e-9
    # normals point away from the core centre side of each face; forces push in
    assert np.all(np.einsum("nij,nij->ni", res.force, res.normal)[has] < 0)


def test_solve_object_by_name_with_covariance_and_nan_faces():
    w = np.full((6, 6), np.nan)
    w[4] = [0, 0, -2.0, 0, 0, 0]  # face 5 pressed at its centre
    res = solve_object("cube", w, wrench_cov=np.diag([1e-4] * 3 + [1e-8] * 3))
    assert res.valid.tolist() == [False, False, False, False, True, False]
    assert np.allclose(res.point[4], [0, 0, 0.025 + 0.003])
    assert np.allclose(res.force[4], [0, 0, -2.0]) and np.allclose(res.normal[4], [0, 0, 1])
    assert res.point_cov.shape == (6, 3, 3) and np.isfinite(res.point_cov[4]).all()


def test_boundary_edge_contacts_are_valid_and_outside_is_not():
    flat = load_patch("flat_46mm")
    z = 0.003
    pts = np.array([[0.023, 0.0, z], [0.023, 0.023, z], [-0.023, -0.01, z], [0.0235, 0.0, z], [0.0, -0.024, z]])
    n = np.tile([0, 0, 1.0], (5, 1))
    f = np.tile([0.5, 0.2, -2.0], (5, 1))
    est = solve(flat, wrench_from_contact(pts, f, np.zeros(5), n))
    assert est.valid.tolist() == [True, True, True, False, False]
    assert np.abs(est.point[:3] - pts[:3]).max() < 1e-12

    dome = load_patch("dome_r40")
    rim = dome.boundary.radii[0]
    zc, R = dome.surface.center[2], dome.surface.radius
    on_rim = np.array([[rim, 0, zc + np.sqrt(R**2 - rim**2)]])
    below = np.array([[0.0, R, zc]])  # on the sphere but under the plinth (inside the core)
    for c, ok in ((on_rim, True), (below, False)):
        n = dome.surface.normal_at(c)
        est = solve(dome, wrench_from_contact(c, -2 * n, [0.0], n))
        assert bool(est.valid[0]) is ok

    cap = load_patch("sphere_cap_r45")  # central projection from the core centre
    d = np.array([[0.025, 0.0, 0.025], [0.0251, 0.0, 0.025]])  # through a face edge, and beyond
    c = cap.surface.center + 0.045 * d / np.linalg.norm(d, axis=1, keepdims=True)
    n = cap.surface.normal_at(c)
    est = solve(cap, wrench_from_contact(c, -n, [0.0, 0.0], n))
    assert est.valid.tolist() == [True, False]


def test_polygon_boundary():
    b = PatchBoundary("polygon", vertices=[[-0.01, -0.01], [0.02, -0.01], [0.0, 0.02]])
    pts = np.array([[0, 0, 0], [0.02, -0.01, 0], [0.01, 0.01, 0], [0.005, -0.01, 1.0], [-0.01, 0.01, 0]])
    assert b.contains(pts).tolist() == [True, True, False, True, False]
    assert b.outline(30).shape == (30, 2)
    assert PatchBoundary.from_dict(b.to_dict()).contains(pts).tolist() == b.contains(pts).tolist()


def _margin_rowwise(b, p):
    """The boundary margin of rectangles and ellipses as rows of (x, y) pairs (the layout it had)."""
    xy = b._project(p)
    if b.shape == "rectangle":
        d = np.abs(xy - b.center) - 0.5 * b.size
        out2 = np.maximum(d, 0.0)
        outside = np.sqrt((out2 * out2).sum(axis=1))
        lateral = np.where(outside > 0, -outside, -np.maximum(d[:, 0], d[:, 1]))
    else:
        v = xy - b.center
        r = np.sqrt((v * v).sum(axis=1))
        v /= b.radii
        rho = np.sqrt((v * v).sum(axis=1))
        with np.errstate(invalid="ignore", divide="ignore"):
            lateral = np.where(rho > 0, r * (1.0 / rho - 1.0), b.radii.min())
    return lateral if b.z_min is None else np.minimum(p[:, 2] - b.z_min, lateral)


def test_margin_by_columns_equals_rows_bit_for_bit():
    rng = np.random.default_rng(31)
    p = rng.normal(scale=0.02, size=(4000, 3))
    p[:5] = [[0.001, -0.002, 0.0], [0.0, 0.0, 0.01], [np.nan, 0.0, 0.0], [0.0, np.inf, 0.0], [0.023, 0.0, 0.0]]
    p[5:500] *= 1e-9  # near the centre and on it
    for b in (PatchBoundary("rectangle", size=[0.046, 0.03], center=(0.001, -0.002)),
              PatchBoundary("ellipse", radii=[0.023, 0.02], z_min=0.002),
              PatchBoundary("ellipse", radii=[0.02, 0.018], center=(0.002, 0.0), projection="central",
                            apex=[0.0, 0.0, -0.025])):
        with np.errstate(invalid="ignore"):
            want = _margin_rowwise(b, p)
        np.testing.assert_array_equal(b.margin(p).view(np.int64), want.view(np.int64))


def test_surface_round_trip_through_dict():
    for s in (Plane([0, 0, 1e-3], [0, 0, 2]), Sphere([0, 0, -0.02], 0.03), Ellipsoid([0, 0, 0], [0.03, 0.02, 0.01])):
        t = surface_from_dict(surface_to_dict(s))
        assert type(t) is type(s) and surface_to_dict(t) == surface_to_dict(s)


def test_mesh_patch_written_and_loaded(tmp_path):
    from contact_helpers import dome_mesh

    dome_mesh(rings=3, segments=12).export(tmp_path / "bump.ply")
    (tmp_path / "bump.json").write_text(json.dumps({
        "format": "pito-patch", "version": 1, "name": "bump",
        "surface": {"type": "mesh", "file": "bump.ply"}, "boundary": {"z_min": 0.002},
    }))
    p = load_patch(tmp_path / "bump.json")
    assert isinstance(p.surface, MeshSurface)
    assert solve(p, [0, 0, -1.0, 0, 0, 0]).valid
    (tmp_path / "obj.json").write_text(json.dumps({
        "format": "pito-assembly", "version": 1, "name": "obj", "core_edge": 0.05,
        "faces": {str(i): "bump" for i in FACES}}))
    a = load_assembly(tmp_path / "obj.json")
    assert a.core == CubeCore(0.05) and a.patches[1] is a.patches[6]


@pytest.mark.parametrize("content,match", [
    ("{not json", "not valid JSON"),
    ('{"format": "other", "version": 1}', "expected a 'pito-patch' file"),
    ('{"format": "pito-patch", "version": 99}', "unsupported version"),
    ('{"format": "pito-patch", "version": 1, "surface": {"type": "torus"}}', "unknown type 'torus'"),
    ('{"format": "pito-patch", "version": 1, "surface": {"type": "sphere", "center": [0,0,0]}}', "needs key 'radius'"),
    ('{"format": "pito-patch", "version": 1, "surface": {"type": "mesh", "file": "nope.stl"}}', "not found"),
    ('{"format": "pito-patch", "version": 1, "surface": {"type": "plane", "point": [0,0,0], "normal": [0,0,1]},'
     ' "boundary": {"shape": "rectangle", "size": [0.01, 0.01], "colour": 1}}', "unknown keys"),
])
def test_bad_patch_files_raise_clear_errors(tmp_path, content, match):
    p = tmp_path / "bad.json"
    p.write_text(content)
    with pytest.raises(ValueError, match=match):
        load_patch(p)


def test_bad_assembly_files_raise_clear_errors(tmp_path):
    p = tmp_path / "a.json"
    p.write_text(json.dumps({"format": "pito-assembly", "version": 1, "faces": {"7": "x"}}))
    with pytest.raises(ValueError, match="expected keys '1'..'6'"):
        load_assembly(p)
    with pytest.raises(ValueError, match="cannot read"):
        load_assembly(tmp_path / "missing.json")
    with pytest.raises(ValueError, match="missing \\[2, 3, 4, 5, 6\\]"):
        Assembly("x", CubeCore(), {1: load_patch("flat_46mm")})


def test_patch_solve_single_wrench_with_covariance():
    p = load_patch("semi_ellipsoid_top")
    est = p.solve([0.2, 0.0, -3.0, 0.0, 0.0, 0.001], wrench_cov=np.diag([1e-4] * 3 + [1e-8] * 3))
    assert est.valid.shape == () and bool(est.valid)
    assert est.point.shape == (3,) and est.point_cov.shape == (3, 3) and est.force_cov.shape == (3, 3)
    assert est.point[2] > p.boundary.z_min
    assert np.all(np.linalg.eigvalsh(est.point_cov) > -1e-18)


@pytest.mark.parametrize("name", ["flat_46mm", "sphere_cap_r45", "semi_ellipsoid_top", "faceted_dome"])
@pytest.mark.parametrize("with_cov", [False, True])
def test_a_patch_nobody_pushes_on_gives_what_the_full_solve_gives_such_rows(name, with_cov):
    """Rows under the force threshold skip the solver; their fields equal those of the same
    rows solved beside a real contact (NaN, not valid, facet −1, NaN covariances)."""
    patch = load_patch(name)
    rng = np.random.default_rng(3)
    weak = np.column_stack([rng.normal(scale=0.05, size=(4, 3)), rng.normal(scale=1e-3, size=(4, 3))])
    weak[1] = np.nan  # a face without output
    strong = np.r_[0.0, 0.0, -5.0, 0.0, 0.0, 0.0]  # pushing in the middle (patch frame)
    cov = np.eye(6) * 1e-4 if with_cov else None
    alone = solve(patch, weak, 0.3, wrench_cov=cov)
    beside = solve(patch, np.vstack([strong, weak]), 0.3, wrench_cov=cov)
    assert beside.valid[0] and not alone.valid.any()
    for f in ("point", "normal", "force", "torsion", "valid", "facet", "point_cov", "force_cov", "torsion_var"):
        a, b = getattr(alone, f, None), getattr(beside, f, None)
        if b is None:
            assert a is None, f
            continue
        assert a.shape == b[1:].shape and a.dtype == b.dtype, f
        np.testing.assert_array_equal(a, b[1:], err_msg=f)
    np.testing.assert_array_equal(solve(patch, weak.reshape(2, 2, 6), 0.3).point, alone.point.reshape(2, 2, 3))

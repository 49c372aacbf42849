"""Exact contact on triangle meshes, with pruning checked against brute force."""

import numpy as np
import pytest
import trimesh
from contact_helpers import dome_mesh, pushing_forces, wrench_from_contact

from pito_core.contact import MeshSurface, Sphere, load_patch, solve
from pito_core.contact._quadric import solve_plane
from pito_core.contact._surfaces import BARYCENTRIC_TOL


@pytest.fixture(scope="module")
def dome():
    mesh = dome_mesh()
    assert 4500 < len(mesh.faces) < 6000 and mesh.is_watertight
    return mesh


def _random_facet_contacts(rng, mesh, N, tau_scale, max_deg=85.0):
    fi = rng.integers(0, len(mesh.faces), N)
    b = rng.dirichlet([1, 1, 1], N)
    c = np.einsum("ni,nij->nj", b, mesh.triangles[fi])
    n = mesh.face_normals[fi]
    f = pushing_forces(rng, n, max_deg=max_deg)
    tau = tau_scale * rng.normal(size=N)
    return fi, c, n, f, tau


def brute_force(mesh, w):
    """Naive reference: solve every facet plane, keep the first valid one along f."""
    tri = mesh.triangles
    out = np.full((len(w), 3), np.nan)
    facet = np.full(len(w), -1)
    for k, wk in enumerate(w):
        best = np.inf
        for j, t in enumerate(tri):
            n = mesh.face_normals[j]
            c, _, _, ok = solve_plane(wk[None, :3], wk[None, 3:], t[0], n)
            if not ok[0]:
                continue
            # barycentric test
            e1, e2, d = t[1] - t[0], t[2] - t[0], c[0] - t[0]
            G = np.array([[e1 @ e1, e1 @ e2], [e1 @ e2, e2 @ e2]])
            u, v = np.linalg.solve(G, [d @ e1, d @ e2])
            tol = BARYCENTRIC_TOL
            if u >= -tol and v >= -tol and u + v <= 1 + tol:
                lam = c[0] @ wk[:3]
                if lam < best:
                    best, out[k], facet[k] = lam, c[0], j
    return out, facet


@pytest.mark.parametrize("tau_scale", [0.0, 0.005])
def test_exact_wrenches_on_5000_facets(dome, tau_scale):
    rng = np.random.default_rng(10)
    surf = MeshSurface(dome)
    fi, c, n, f, tau = _random_facet_contacts(rng, dome, 5000, tau_scale)
    est = solve(surf, wrench_from_contact(c, f, tau, n), force_threshold=0.1)
    assert est.valid.all()
    assert np.abs(est.point - c).max() < 1e-9
    assert np.abs(est.torsion - tau).max() < 1e-9
    assert np.array_equal(est.facet, fi)
    assert np.allclose(est.normal, n)


def test_pruned_solver_matches_brute_force():
    rng = np.random.default_rng(11)
    mesh = dome_mesh(rings=5, segments=16)  # small enough for the naive double loop
    surf = MeshSurface(mesh, group_size=4)
    _, c, n, f, tau = _random_facet_contacts(rng, mesh, 60, 0.01)
    w = wrench_from_contact(c, f, tau, n)
    w = np.vstack([w, w + 0.05 * rng.normal(size=w.shape), np.c_[rng.normal(size=(60, 3)),
                                                                 0.02 * rng.normal(size=(60, 3))]])
    est = solve(surf, w, force_threshold=0.0)
    ref, facet = brute_force(mesh, w)
    assert np.array_equal(est.facet, facet)
    assert np.array_equal(est.valid, facet >= 0)
    v = est.valid
    assert np.abs(est.point[v] - ref[v]).max() < 1e-12
    assert (~v).any() and v.sum() > 60  # both cases exercised


def test_point_contacts_match_trimesh_ray_first_hit(dome):
    rng = np.random.default_rng(12)
    surf = MeshSurface(dome)
    _, c, n, f, _ = _random_facet_contacts(rng, dome, 300, 0.0, max_deg=80.0)
    est = solve(surf, wrench_from_contact(c, f, np.zeros(300), n))
    fhat = f / np.linalg.norm(f, axis=1, keepdims=True)
    origins = c - 0.5 * fhat  # far outside, on the line of action
    locs, rays, _ = dome.ray.intersects_location(origins, fhat, multiple_hits=False)
    hit = np.full((300, 3), np.nan)
    hit[rays] = locs
    assert np.nanmax(np.abs(hit - est.point)) < 1e-9
    assert np.abs(est.point - c).max() < 1e-9


def test_contacts_on_facet_edges_and_vertices(dome):
    rng = np.random.default_rng(13)
    surf = MeshSurface(dome)
    fi = rng.integers(0, len(dome.faces), 200)
    tri = dome.triangles[fi]
    c = np.vstack([tri[:100, 0], 0.5 * (tri[100:, 1] + tri[100:, 2])])  # vertices, edge midpoints
    n = dome.face_normals[fi]
    f = pushing_forces(rng, n, max_deg=30.0)
    est = solve(surf, wrench_from_contact(c, f, np.zeros(200), n))
    assert est.valid.all()
    assert np.abs(est.point - c).max() < 1e-9


def test_mesh_misses_and_weak_forces_are_not_valid(dome):
    surf = MeshSurface(dome)
    w = np.array([
        [0, 0, -1.0, 0.5, 0, 0],  # line of action x-offset 0.5 m: misses the dome
        [0, 0, 1.0, 0, 0, 0],  # pulling outward through the base only (the base faces −z)
        [0, 0, -0.001, 0, 0, 0],  # under the threshold
        [np.nan] * 6,
        [0, 0, -1.0, 0, 0, 0],  # the dome's apex
    ])
    est = solve(surf, w)
    assert est.valid.tolist() == [False, True, False, False, True]
    assert est.facet[0] == -1 and np.isnan(est.point[0]).all()
    assert est.point[4, 2] == pytest.approx(dome.vertices[:, 2].max(), abs=1e-9)
    # with the patch boundary (z_min) the base is excluded
    patch = load_patch("faceted_dome")
    est = solve(patch, w[1])
    assert not est.valid and np.isnan(est.point).all()


def test_faceted_patch_from_stl_approximates_its_sphere():
    patch = load_patch("faceted_dome")
    assert isinstance(patch.surface, MeshSurface)
    assert patch.display_mesh().is_watertight
    est = solve(patch, [0, 0, -2.0, 0, 0, 0])
    assert est.valid and est.point[2] == pytest.approx(0.008, abs=1e-9)  # apex of the dome


def test_nonconvex_mesh_takes_the_first_surface_along_the_force():
    # Two stacked plates: a finger pushing down meets the upper one first.
    a = trimesh.creation.box(extents=(0.04, 0.04, 0.002))
    b = a.copy()
    a.apply_translation([0, 0, 0.001])
    b.apply_translation([0, 0, 0.011])
    surf = MeshSurface(trimesh.util.concatenate([a, b]))
    est = solve(surf, [[0, 0, -1.0, 0.0, 0.0, 0.0], [0, 0, 1.0, 0.0, 0.0, 0.0]])
    assert est.point[0, 2] == pytest.approx(0.012)
    assert est.point[1, 2] == pytest.approx(0.0)  # pushing up: the lowest surface facing down


def test_sphere_mesh_converges_to_sphere():
    sphere = Sphere([0, 0, 0], 0.02)
    mesh = trimesh.creation.icosphere(subdivisions=4, radius=0.02)
    rng = np.random.default_rng(14)
    d = rng.normal(size=(200, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    w = np.c_[-d, np.zeros((200, 3))]  # radial pushes through the centre
    a, b = solve(sphere, w), solve(MeshSurface(mesh), w)
    assert a.valid.all() and b.valid.all()
    assert np.abs(np.linalg.norm(a.point - b.point, axis=1)).max() < 0.02 * (1 - np.cos(0.1))


def test_pruning_never_drops_the_answer_on_a_large_mesh(dome, monkeypatch):
    """Fast (pruned) vs naive (every group evaluated) on 5,000 facets, random wrenches."""
    rng = np.random.default_rng(15)
    surf = MeshSurface(dome)
    fi, c, n, f, tau = _random_facet_contacts(rng, dome, 1500, 0.01)
    w = wrench_from_contact(c, f, tau, n)
    w = np.vstack([w, w + 0.02 * rng.normal(size=w.shape),
                   np.c_[rng.normal(size=(1500, 3)), 0.01 * rng.normal(size=(1500, 3))]])
    fast = solve(surf, w, force_threshold=0.0)
    index = surf._index

    def everything(f, m):
        si = np.repeat(np.arange(len(f)), index.n_groups)
        gi = np.tile(np.arange(index.n_groups), len(f))
        return si, gi

    monkeypatch.setattr(index, "candidate_groups", everything)
    naive = solve(surf, w, force_threshold=0.0)
    assert np.array_equal(fast.facet, naive.facet)
    assert np.array_equal(fast.valid, naive.valid)
    assert fast.valid.sum() > 3000 and (~fast.valid).sum() > 100

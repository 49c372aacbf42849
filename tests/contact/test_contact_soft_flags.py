"""The decision from the limits' signs (``soft_finger_flags``) and the deferred p-values of ``solve``.

Naive-vs-fast: ``soft_finger_flags`` gives the same flags and reasons as the full closed-form
test (``soft_finger_test``, every row's p-value) on random touches of every surface kind,
with and without a boundary, several patches side by side, shared and per-row covariances,
rows on the threshold to the last bits, and α on both sides of 1/2. ``solve``'s
``single_contact_p``, computed on first read, equals the full test's p bit for bit, whatever
was written into the estimate's arrays or the caller's wrenches in between.
"""

import pickle

import numpy as np
import pytest
from scipy.special import ndtri

from pito_core.contact import (ContactEstimate, Ellipsoid, MeshSurface, Patch, PatchBoundary, Plane, Sphere, solve,
                               solve_object)
from pito_core.contact._estimate import _Deferred
from pito_core.contact._solve import _solve_surface
from pito_core.contact._soft_screen import soft_finger_flags
from pito_core.contact._soft_test import soft_finger_test

from contact_helpers import dome_mesh, pushing_forces, random_on_ellipsoid, wrench_from_contact

MU, E = 0.8, 0.004
_R = np.array([[np.cos(0.5), -np.sin(0.5), 0], [np.sin(0.5), np.cos(0.5), 0], [0, 0, 1.0]])
SURFACES = {
    "plane": Plane([0.0, 0.0, 0.003], [0.0, 0.0, 1.0]),
    "plane -x": Plane([-0.002, 0.0, 0.0], [-1.0, 0.0, 0.0]),
    "tilted plane": Plane([0.001, 0.0, 0.003], [0.2, -0.1, 1.0]),
    "sphere": Sphere([0.0, 0.0, -0.01], 0.025),
    "ellipsoid": Ellipsoid([0.001, 0.0, -0.005], [0.03, 0.02, 0.015], _R),
}


def _touches(surface, N, rng):
    """Noisy wrenches ``(N, 6)`` of one finger: inside and beyond friction, some pulling, some NaN."""
    if isinstance(surface, Plane):
        T = np.linalg.svd(surface.normal[None])[2][1:]  # two tangents
        c = surface.point + rng.uniform(-0.03, 0.03, (N, 2)) @ T
        n = np.broadcast_to(surface.normal, (N, 3)).copy()
    else:
        c, n = random_on_ellipsoid(rng, surface, N, upper_only=True)
    f = pushing_forces(rng, n, max_deg=60.0, magnitude=(0.2, 5.0))
    f[: N // 10] *= -1  # pulling
    tau = rng.uniform(-0.01, 0.01, N)
    w = wrench_from_contact(c, f, tau, n) + rng.normal(size=(N, 6)) * ([0.05] * 3 + [5e-4] * 3)
    w[N // 10: N // 10 + 3, 3:] = np.nan  # no solution
    return w


def _solved(blocks, w):
    parts = [_solve_surface(s, w[sl, :3].copy(), np.ascontiguousarray(w[sl, 3:])) for s, _, sl in blocks]
    c, n, tau, ok = (np.concatenate([p[k] for p in parts]) for k in range(4))
    ok &= np.isfinite(c).all(axis=1)
    return c, n, w[:, :3].copy(), tau, ok


def _covs(rng, N):
    A = rng.normal(size=(N, 6, 6))
    return A @ np.swapaxes(A, 1, 2) * 1e-5 + np.diag([1e-3] * 3 + [1e-7] * 3)


def _on_threshold(c, n, f, tau, S, blocks, mu, alpha, ok, m):
    """Per-row covariances that put the failing rows' smallest z on Φ⁻¹(α) (to the rounding)."""
    S = np.array(np.broadcast_to(S, (len(f), 6, 6)))
    if alpha >= 0.5:
        return S
    z = ndtri(soft_finger_test(c, n, f, tau, S, blocks, mu, E, 0.5, ok, m)[1])
    scale = np.where(np.isfinite(z) & (z < 0), (z / ndtri(alpha)) ** 2, 1.0)
    return S * scale[:, None, None]


def _near(p, alpha):
    """How many rows' smallest z lies within 10⁻⁹ of Φ⁻¹(α), flagged and not."""
    za = ndtri(alpha)
    near = np.abs(ndtri(p) - za) < 1e-9 * (1 + abs(za))
    return np.count_nonzero(near & (p >= alpha)), np.count_nonzero(near & (p < alpha))


@pytest.mark.parametrize("kind", list(SURFACES))
@pytest.mark.parametrize("bounded", [False, True])
def test_flags_equal_the_full_test(kind, bounded):
    rng = np.random.default_rng(21)
    surface = SURFACES[kind]
    w = _touches(surface, 600, rng)
    boundary = PatchBoundary("ellipse", radii=(0.02, 0.015)) if bounded else None
    blocks = [(surface, boundary, slice(0, len(w)))]
    c, n, f, tau, ok = _solved(blocks, w)
    A = rng.normal(size=(6, 6))
    seen, near = 0, np.zeros(2, int)
    for S in (np.diag([0.05**2] * 3 + [5e-4**2] * 3), A @ A.T * 1e-5 + np.diag([1e-3] * 3 + [1e-7] * 3),
              _covs(rng, len(w))):
        for alpha in (0.05, 0.01, 0.5, 0.7):
            for cov in (S, _on_threshold(c, n, f, tau, S, blocks, MU, alpha, ok, w[:, 3:])):
                ref = soft_finger_test(c, n, f, tau, cov, blocks, MU, E, alpha, ok, w[:, 3:])
                single, reason = soft_finger_flags(c, n, f, tau, cov, blocks, MU, E, alpha, ok, w[:, 3:])
                np.testing.assert_array_equal(single, ref[0])
                np.testing.assert_array_equal(reason, ref[2])
                np.testing.assert_array_equal(single, ref[1] >= alpha)
                seen += np.count_nonzero(~ref[0])
                near += _near(ref[1], alpha)
    assert seen > 100 and (near > 5).all()  # both outcomes, and both on the threshold


@pytest.mark.parametrize("kind", ["plane", "plane -x"])
def test_the_faces_planes_screen_from_the_force_magnitude(kind):
    """With ``|f|²`` and ``ok`` (as ``solve`` passes them): the same flags, rows on the friction limit too."""
    rng = np.random.default_rng(26)
    surface = SURFACES[kind]
    w = _touches(surface, 800, rng)
    n0 = surface.normal
    T = np.linalg.svd(n0[None])[2][1:]
    c = surface.point + rng.uniform(-0.02, 0.02, (200, 2)) @ T
    fn = rng.uniform(0.5, 5.0, 200)
    ph = rng.uniform(0, 2 * np.pi, 200)
    on = np.repeat([1.0, 1 + 1e-13, 1 - 1e-13, 1 + 1e-9, 1 - 1e-9], 40)  # on the friction cone, just in, out
    f = -fn[:, None] * n0 + (on * MU * fn)[:, None] * (np.cos(ph)[:, None] * T[0] + np.sin(ph)[:, None] * T[1])
    w[:200] = wrench_from_contact(c, f, np.zeros(200), n0)  # no noise
    blocks = [(surface, None, slice(0, len(w)))]
    c, n, f, tau, ok = _solved(blocks, w)
    f2 = np.einsum("ij,ij->i", f, f)
    flagged = 0
    for S in (np.diag([0.05**2] * 3 + [5e-4**2] * 3), np.diag([1e-30] * 3 + [1e-34] * 3), _covs(rng, len(w))):
        for alpha in (0.05, 0.3):
            ref = soft_finger_test(c, n, f, tau, S, blocks, MU, E, alpha, ok, w[:, 3:])
            single, reason = soft_finger_flags(c, n, f, tau, S, blocks, MU, E, alpha, ok, w[:, 3:], f2=f2)
            np.testing.assert_array_equal(single, ref[0])
            np.testing.assert_array_equal(reason, ref[2])
            flagged += np.count_nonzero(~ref[0][:200])
    assert 0 < flagged < 6 * 200  # the limit's rows: both outcomes (with the tiny noise)


@pytest.mark.parametrize("chunk", [100, 16_000])
def test_several_patches_per_row_friction_and_covariances(chunk, monkeypatch):
    monkeypatch.setattr("pito_core.contact._soft_test.CHUNK", chunk)  # blocks across the passes' edges
    monkeypatch.setattr("pito_core.contact._soft_screen.CHUNK", chunk)
    monkeypatch.setattr("pito_core.contact._soft_screen.SCREEN_CHUNK", chunk // 2)
    rng = np.random.default_rng(22)
    kinds = ("plane", "ellipsoid", "sphere", "tilted plane")
    ws = [_touches(SURFACES[k], 150, rng) for k in kinds]
    w = np.concatenate(ws)
    edges = np.cumsum([0] + [len(x) for x in ws])
    bnd = PatchBoundary("rectangle", size=(0.04, 0.03))
    blocks = [(SURFACES[k], b, slice(edges[i], edges[i + 1]))
              for i, (k, b) in enumerate(zip(kinds, (bnd, None, bnd, None)))]
    c, n, f, tau, ok = _solved(blocks, w)
    mu = rng.uniform(0.5, 1.2, len(w))
    e = rng.uniform(0.003, 0.006, len(w))
    S = _on_threshold(c, n, f, tau, _covs(rng, len(w)), blocks, mu, 0.05, ok, w[:, 3:])
    ref = soft_finger_test(c, n, f, tau, S, blocks, mu, e, 0.05, ok, w[:, 3:])
    single, reason = soft_finger_flags(c, n, f, tau, S, blocks, mu, e, 0.05, ok, w[:, 3:])
    np.testing.assert_array_equal(single, ref[0])
    np.testing.assert_array_equal(reason, ref[2])
    assert 0.05 < np.mean(~single) < 0.95


def test_a_mesh_patch():
    rng = np.random.default_rng(23)
    mesh = MeshSurface(dome_mesh(rings=6, segments=24))
    sphere = Sphere([0, 0, -0.032], 0.04)
    w = _touches(sphere, 400, rng)
    blocks = [(mesh, None, slice(0, len(w)))]
    f = w[:, :3].copy()
    c, n, tau, ok, _ = _solve_surface(mesh, f, np.ascontiguousarray(w[:, 3:]))
    ok &= np.isfinite(c).all(axis=1)
    S = np.diag([0.05**2] * 3 + [5e-4**2] * 3)
    ref = soft_finger_test(c, n, f, tau, S, blocks, MU, E, 0.05, ok, w[:, 3:])
    single, reason = soft_finger_flags(c, n, f, tau, S, blocks, MU, E, 0.05, ok, w[:, 3:])
    np.testing.assert_array_equal(single, ref[0])
    np.testing.assert_array_equal(reason, ref[2])
    est = solve(Patch(mesh, None, mu=MU, torsion_radius=E), w, force_threshold=0.0, wrench_cov=S)
    np.testing.assert_array_equal(est.single_contact_p, ref[1])


@pytest.mark.parametrize("kind", ["plane", "sphere", "ellipsoid"])
def test_solve_reads_the_same_p_later_whatever_was_written_since(kind):
    rng = np.random.default_rng(24)
    surface = SURFACES[kind]
    w = _touches(surface, 500, rng)
    w[::7, :3] *= 1e-3  # some rows below the force threshold
    S = _covs(rng, len(w))
    keep_w, keep_S = w.copy(), S.copy()
    est = solve(surface, w, wrench_cov=S, mu=MU, torsion_radius=E)
    assert isinstance(est.__dict__["_single_contact_p"], _Deferred)
    for x in (est.point, est.normal, est.force, est.torsion, w, S):
        x[...] = 0.0  # the caller's arrays and the estimate's: the p-values do not move
    strong = np.einsum("ij,ij->i", keep_w[:, :3], keep_w[:, :3]) >= 0.05**2
    blocks = [(surface, None, slice(0, strong.sum()))]
    c, n, f, tau, ok = _solved(blocks, keep_w[strong])
    ref = soft_finger_test(c, n, f, tau, keep_S[strong], blocks, MU, E, 0.05, ok, keep_w[strong, 3:])
    p = est.single_contact_p
    np.testing.assert_array_equal(p[strong], ref[1])
    assert np.isnan(p[~strong]).all()
    np.testing.assert_array_equal(est.single_contact[strong], ref[0])
    np.testing.assert_array_equal(est.single_contact, p >= 0.05)


def test_the_deferred_field_through_the_record():
    rng = np.random.default_rng(25)
    faces = np.stack([_touches(SURFACES["plane"], 40, rng) for _ in range(6)], axis=1)  # (40, 6, 6)
    faces[:, :, 2] = -np.abs(faces[:, :, 2])
    lazy = solve_object("pito_mixed", faces)
    eager = solve_object("pito_mixed", faces)
    p = eager.single_contact_p  # read at once
    assert p.shape == (40, 6) and np.isfinite(p).any()
    assert isinstance(lazy.__dict__["_single_contact_p"], _Deferred)
    np.testing.assert_array_equal(lazy[3:9].single_contact_p, p[3:9])
    np.testing.assert_array_equal(lazy[lazy.valid].single_contact_p, p[eager.valid])
    np.testing.assert_array_equal(pickle.loads(pickle.dumps(lazy)).single_contact_p, p)
    both = ContactEstimate.concatenate([lazy[:10], lazy[10:]])
    np.testing.assert_array_equal(both.single_contact_p, p)
    one = solve(SURFACES["sphere"], _touches(SURFACES["sphere"], 1, rng)[0])
    assert one.single_contact_p.shape == () and one.single_contact.shape == ()
    assert (one.single_contact_p >= 0.05) == one.single_contact


def test_copies_come_back_only_when_no_longer_needed():
    rng = np.random.default_rng(27)
    surface = SURFACES["sphere"]
    ws = [_touches(surface, 300, rng) for _ in range(4)]
    ref = [solve(surface, w).single_contact_p for w in ws]  # read at once: the copies go back each time
    ests = [solve(surface, w) for w in ws]  # none read: each holds its own copy
    del ests[1]  # gone unread: its copy back, taken by the next solve
    again = solve(surface, ws[1])
    for k, e in zip((3, 2, 0), ests[::-1]):
        np.testing.assert_array_equal(e.single_contact_p, ref[k])
    np.testing.assert_array_equal(again.single_contact_p, ref[1])


@pytest.mark.parametrize("alpha", [0.05, 0.7])
def test_p_of_rows_tested_in_full_and_of_rows_single_by_their_signs(alpha):
    rng = np.random.default_rng(28)  # α > 1/2: every row tested in full, its p from the kept min z
    surface = SURFACES["ellipsoid"]
    w = _touches(surface, 600, rng)
    S = _covs(rng, len(w))
    est = solve(surface, w, wrench_cov=S, mu=MU, torsion_radius=E, alpha=alpha)
    strong = np.einsum("ij,ij->i", w[:, :3], w[:, :3]) >= 0.05**2
    blocks = [(surface, None, slice(0, strong.sum()))]
    c, n, f, tau, ok = _solved(blocks, w[strong])
    ref = soft_finger_test(c, n, f, tau, S[strong], blocks, MU, E, alpha, ok, w[strong, 3:])
    np.testing.assert_array_equal(est.single_contact_p[strong], ref[1])
    np.testing.assert_array_equal(est.single_contact[strong], ref[0])

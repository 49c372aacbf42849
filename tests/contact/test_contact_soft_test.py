"""The soft finger's closed-form single-contact test (``_soft_test``) against the general test.

Naive-vs-fast: the general test (``single_contact_test`` with tangent coordinates, the
Jacobian and ``soft_finger_variance``) and the closed form that ``solve`` runs give the same
p-values and reasons, on every surface kind, with and without a boundary, several patches
side by side, a shared or a per-row covariance.
"""

import numpy as np
import pytest

from pito_core.contact import Ellipsoid, PatchBoundary, Plane, Sphere, load_patch
from pito_core.contact._crb import wrench_jacobian
from pito_core.contact._plausibility import single_contact_test, soft_finger_variance
from pito_core.contact._solve import _solve_surface
from pito_core.contact._soft_test import soft_finger_test

from contact_helpers import pushing_forces, random_on_ellipsoid, wrench_from_contact

MU, E, ALPHA = 0.8, 0.004, 0.05


def _surfaces():
    R = np.array([[np.cos(0.5), -np.sin(0.5), 0], [np.sin(0.5), np.cos(0.5), 0], [0, 0, 1.0]])
    return {
        "plane": Plane([0.0, 0.0, 0.003], [0.0, 0.0, 1.0]),
        "tilted plane": Plane([0.001, 0.0, 0.003], [0.2, -0.1, 1.0]),
        "sphere": Sphere([0.0, 0.0, -0.01], 0.025),
        "ellipsoid": Ellipsoid([0.001, 0.0, -0.005], [0.03, 0.02, 0.015], R),
    }


def _touches(surface, N, rng):
    """Wrenches of one finger (some beyond friction, some pulling) with noise: ``(N, 6)``."""
    if isinstance(surface, Plane):
        c = np.c_[rng.uniform(-0.03, 0.03, (N, 2)), np.zeros(N)]
        c += surface.normal * (surface.offset - c @ surface.normal)[:, None]
        n = np.broadcast_to(surface.normal, (N, 3)).copy()
    else:
        c, n = random_on_ellipsoid(rng, surface, N, upper_only=True)
    f = pushing_forces(rng, n, max_deg=60.0, magnitude=(0.2, 5.0))
    f[: N // 10] *= -1  # pulling
    tau = rng.uniform(-0.02, 0.02, N)
    return wrench_from_contact(c, f, tau, n) + rng.normal(size=(N, 6)) * ([0.05] * 3 + [5e-4] * 3)


def _general(blocks, c, n, f, tau, w, S):
    shape = np.concatenate([s._shape_operator(c[sl], n[sl]) for s, _, sl in blocks])
    with np.errstate(invalid="ignore", divide="ignore"):
        J, T = wrench_jacobian(c, n, shape, f, tau)
        bnd = [(b, sl) for _, b, sl in blocks]
        return single_contact_test(c, n, f, tau, w, soft_finger_variance(J, c, S), T, shape,
                                   boundary=bnd, mu=MU, torsion_radius=E, alpha=ALPHA)


def _solved(blocks, w):
    parts = [_solve_surface(s, w[sl, :3].copy(), w[sl, 3:]) for s, _, sl in blocks]
    c, n, tau, ok = (np.concatenate([p[k] for p in parts]) for k in range(4))
    return c, n, w[:, :3].copy(), tau, ok


@pytest.mark.parametrize("kind", list(_surfaces()))
@pytest.mark.parametrize("bounded", [False, True])
def test_closed_form_test_equals_the_general_test(kind, bounded):
    rng = np.random.default_rng(11)
    surface = _surfaces()[kind]
    w = _touches(surface, 400, rng)
    boundary = PatchBoundary("ellipse", radii=(0.02, 0.015)) if bounded else None
    blocks = [(surface, boundary, slice(0, len(w)))]
    c, n, f, tau, ok = _solved(blocks, w)
    A = rng.normal(size=(6, 6))
    for S in (np.diag([0.05**2] * 3 + [5e-4**2] * 3), A @ A.T * 1e-5 + np.diag([1e-3] * 3 + [1e-7] * 3)):
        fast = soft_finger_test(c, n, f, tau, S, blocks, MU, E, ALPHA, ok, w[:, 3:])
        ref = _general(blocks, c, n, f, tau, w, S)
        assert 0.05 < np.mean(~ref.single) < 0.95  # both outcomes occur
        np.testing.assert_array_equal(fast[0], ref.single)
        np.testing.assert_allclose(fast[1], ref.p, rtol=1e-7, atol=1e-12)
        np.testing.assert_array_equal(fast[2], ref.reason)


@pytest.mark.parametrize("chunk", [16_000, 100])
def test_several_patches_side_by_side_and_per_row_covariances(chunk, monkeypatch):
    monkeypatch.setattr("pito_core.contact._soft_test.CHUNK", chunk)  # blocks across the passes' edges
    rng = np.random.default_rng(12)
    surfs = _surfaces()
    ws = [_touches(surfs[k], 150, rng) for k in ("plane", "ellipsoid", "sphere")]
    w = np.concatenate(ws)
    edges = np.cumsum([0] + [len(x) for x in ws])
    bnd = PatchBoundary("rectangle", size=(0.04, 0.03))
    blocks = [(surfs[k], b, slice(edges[i], edges[i + 1]))
              for i, (k, b) in enumerate((("plane", bnd), ("ellipsoid", None), ("sphere", bnd)))]
    c, n, f, tau, ok = _solved(blocks, w)
    A = rng.normal(size=(len(w), 6, 6))
    mu = np.full(len(w), MU)
    S = A @ np.swapaxes(A, 1, 2) * 1e-5 + np.diag([1e-3] * 3 + [1e-7] * 3)
    fast = soft_finger_test(c, n, f, tau, S, blocks, mu, E, ALPHA, ok, w[:, 3:])
    ref = _general(blocks, c, n, f, tau, w, S)
    np.testing.assert_array_equal(fast[0], ref.single)
    np.testing.assert_allclose(fast[1], ref.p, rtol=1e-7, atol=1e-12)
    np.testing.assert_array_equal(fast[2], ref.reason)


def test_a_library_patch_gives_the_same_flags_through_solve():
    from pito_core.contact import solve

    rng = np.random.default_rng(13)
    patch = load_patch("flat_46mm")
    w = _touches(Plane([0, 0, 0.003], [0, 0, 1.0]), 300, rng)
    w[:5] = np.nan
    est = solve(patch, w, wrench_cov=np.diag([0.05**2] * 3 + [5e-4**2] * 3))
    assert est.single_contact.shape == (300,) and not est.single_contact[:5].any()
    assert 0 < est.single_contact.sum() < 295

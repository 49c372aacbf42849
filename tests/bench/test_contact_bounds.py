"""pito_bench._contact_bounds: the bootstrap interval of the CRB ratio and the plane's second-order error.

Data here are our own random forms (a tilted plane off the face, correlated wrench noise),
not the benchmark's sampler.
"""

from __future__ import annotations

import numpy as np
import trimesh
from scipy.spatial import Delaunay

from pito_bench._contact_bounds import facet_of, plane_second_order_ratio, ratio_ci
from pito_core.contact import Plane, contact_crb, solve


def _tilted_case(rng, n_contacts=6, snr=10.0):
    """A plane tilted 20° off the face, correlated noise, contacts whose normal force is ``snr`` σ_n."""
    nrm = np.array([np.sin(0.35), 0.0, np.cos(0.35)])
    plane = Plane([0.003, -0.002, 0.006], nrm)
    A = rng.normal(size=(6, 6)) * np.r_[0.01, 0.01, 0.01, 1e-4, 1e-4, 1e-4][:, None]
    cov = A @ A.T + np.diag([4e-4] * 3 + [4e-8] * 3)
    t1 = np.cross(nrm, [0.0, 1.0, 0.0])
    t1 /= np.linalg.norm(t1)
    t2 = np.cross(nrm, t1)
    uv = rng.uniform(-0.02, 0.02, (n_contacts, 2))
    c = plane.point + uv[:, :1] * t1 + uv[:, 1:] * t2
    sigma_n = np.sqrt(np.r_[nrm, 0, 0, 0] @ cov @ np.r_[nrm, 0, 0, 0])
    tang = rng.normal(size=(n_contacts, 2)) * 0.5
    f = -snr * sigma_n * nrm + tang[:, :1] * t1 + tang[:, 1:] * t2
    tau = rng.uniform(-0.003, 0.003, n_contacts)
    return plane, cov, c, f, tau, nrm


def test_plane_second_order_error_matches_monte_carlo_and_its_first_term_is_the_crb():
    rng = np.random.default_rng(11)
    plane, cov, c, f, tau, nrm = _tilted_case(rng)
    mse, crb = plane_second_order_ratio(plane, c, f, cov)
    crb_ref = np.trace(contact_crb(plane, c, f, cov, torsion=tau, normal=nrm).point_cov, axis1=1, axis2=2)
    np.testing.assert_allclose(crb, crb_ref, rtol=1e-10)
    L = np.linalg.cholesky(cov)
    m_trials = 100_000
    for i in range(len(c)):
        w0 = np.r_[f[i], np.cross(c[i], f[i]) + tau[i] * nrm]
        w = w0 + rng.normal(size=(m_trials, 6)) @ L.T
        est = solve(plane, w)
        assert est.valid.mean() > 0.999
        sq = np.sum((est.point[est.valid] - c[i]) ** 2, axis=1)
        measured = sq.mean()
        assert mse[i] > 1.025 * crb[i]  # the excess is visible: the check can fail on a bare CRB
        assert abs(measured / mse[i] - 1) < 0.015, (i, measured / mse[i], mse[i] / crb[i])


def test_ratio_ci_covers_the_known_ratio_and_narrows_with_samples():
    rng = np.random.default_rng(5)
    widths = []
    covered = 0
    for n in (500, 20_000):
        for rep in range(10):
            crb_tr = rng.uniform(0.5, 2.0, n)
            sq = crb_tr * rng.chisquare(2, n) / 2 * 1.1**2  # true error/CRB ratio: 1.1
            lo, hi = ratio_ci(sq, crb_tr, seed=rep)
            point = np.sqrt(sq.mean() / crb_tr.mean())
            assert lo <= point <= hi
            covered += lo <= 1.1 <= hi
            widths.append((n, hi - lo))
    assert covered >= 17  # 95 % intervals over 20 draws
    w_small = np.mean([w for n, w in widths if n == 500])
    w_large = np.mean([w for n, w in widths if n == 20_000])
    assert w_large < 0.25 * w_small
    assert np.isnan(ratio_ci([1.0], [1.0])[0])


def test_facet_of_finds_the_triangle_a_point_was_drawn_in():
    rng = np.random.default_rng(3)
    V = np.c_[rng.uniform(-0.02, 0.02, (40, 2)), rng.uniform(0.0, 0.003, 40)]
    F = Delaunay(V[:, :2]).simplices
    mesh = trimesh.Trimesh(V, F, process=False)
    k = rng.integers(0, len(F), 200)
    u = rng.uniform(0.05, 0.45, (200, 2))  # well inside: away from the edges
    tri = mesh.triangles[k]
    p = tri[:, 0] + u[:, :1] * (tri[:, 1] - tri[:, 0]) + u[:, 1:] * (tri[:, 2] - tri[:, 0])

    class _Surface:  # only the attribute facet_of reads
        pass

    s = _Surface()
    s.mesh = mesh
    np.testing.assert_array_equal(facet_of(s, p), k)

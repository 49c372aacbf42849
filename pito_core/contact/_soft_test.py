"""The soft-finger single-contact test in closed form over component arrays (the path ``solve`` takes).

The same test as :func:`~pito_core.contact._plausibility.single_contact_test` with
:func:`~pito_core.contact._plausibility.soft_finger_variance` (module docstring there), written
out for the soft finger: every vector is held as three contiguous rows ``(3, N)`` (x, y, z)
so that each step is a handful of one-dimensional ufunc calls instead of small-axis einsums
and ``(N, 3, 3)`` matrix products. Per estimate:

* tangents ``t1 = n × a / |n × a|`` (``a`` = x, or y where ``|n_x| ≥ 0.9``), ``t2 = n × t1``
  (:func:`~pito_core.contact._surfaces.tangent_basis`);
* ``D_j = ∂n/∂θ_j = S t_j``: 0 on a plane or a facet, ``t_j / r`` on a sphere,
  ``(A t_j − n (n · A t_j)) / |A (c − c0)|`` on an ellipsoid;
* the Jacobian's moment columns ``a_j = t_j × f + τ D_j`` and the adjugate of ``M = [a1; a2; n]``
  (rows ``a2 × n``, ``n × a1``, ``a1 × a2``; ``det M = a1 · (a2 × n)``);
* for a limit with gradient ``(g_θ1, g_θ2, g_f, g_τ)``: ``u_m = (g_θ1 adj1 + g_θ2 adj2 + g_τ adj3) / det M``,
  ``u_f = g_f + c × u_m`` and ``σ² = uᵀ Σ u``; the limits are the pushing force ``f_n = −f · n``,
  the friction margin ``μ f_n − √(|f_t|² + (τ/e)²)`` and the boundary margin (central
  difference along the tangents, as the general test).

p-values ``Φ(z)`` are evaluated only where ``z < 8.3`` (above, ``Φ(z)`` is 1.0 in double precision).
"""

from __future__ import annotations

import numpy as np
from scipy.special import ndtr

from ._plausibility import _BOUNDARY_STEP, _decide, _z
from ._surfaces import Ellipsoid, Sphere

__all__ = ["soft_finger_test"]

#: Φ(z) rounds to 1.0 in double precision for every z at or above this
_Z_ONE = 8.3


def _cross(a, b):
    """Cross product of component arrays ``(3, N)``."""
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    np.multiply(a[1], b[2], out=out[0])
    out[0] -= a[2] * b[1]
    np.multiply(a[2], b[0], out=out[1])
    out[1] -= a[0] * b[2]
    np.multiply(a[0], b[1], out=out[2])
    out[2] -= a[1] * b[0]
    return out


def _dot(a, b):
    """Row-wise dot of component arrays ``(3, N)``: ``(N,)``."""
    out = a[0] * b[0]
    out += a[1] * b[1]
    out += a[2] * b[2]
    return out


def _mat3(A, x):
    """``A x`` for a ``(3, 3)`` matrix and component arrays ``(3, N)``, row by row (no BLAS: the same
    rounding whatever ``N``)."""
    out = np.empty_like(x)
    for i in range(3):
        np.multiply(A[i, 0], x[0], out=out[i])
        out[i] += A[i, 1] * x[1]
        out[i] += A[i, 2] * x[2]
    return out


def _quad6(u, S):
    """``uᵀ S u`` over the first axis of ``u (6, …)`` for a symmetric ``S (6, 6)``, term by term (no BLAS:
    the same rounding whatever the batch, so grouped and single solves agree bitwise)."""
    out = np.zeros(u.shape[1:])
    for i in range(6):
        if S[i, i] != 0.0:
            out += S[i, i] * (u[i] * u[i])
        for j in range(i + 1, 6):
            if S[i, j] != 0.0:
                out += (2.0 * S[i, j]) * (u[i] * u[j])
    return out


def _tangents(n):
    """``t1, t2`` ``(3, N)`` of unit normals ``n (3, N)`` (tangent_basis's rule)."""
    use_x = np.abs(n[0]) < 0.9
    t1 = np.empty_like(n)
    np.copyto(t1[0], np.where(use_x, 0.0, -n[2]))
    np.copyto(t1[1], np.where(use_x, n[2], 0.0))
    np.copyto(t1[2], np.where(use_x, -n[1], n[0]))
    t1 /= np.sqrt(_dot(t1, t1))
    return t1, _cross(n, t1)


def _dn(surface, c, n, t):
    """``∂n/∂θ = S t`` ``(3, N)`` for tangents ``t (3, N)`` on ``surface``; None where ``S = 0``."""
    if isinstance(surface, Sphere):
        return t * (1.0 / surface.radius)
    if isinstance(surface, Ellipsoid):
        A = surface._A
        At = _mat3(A, t)
        At -= n * _dot(n, At)
        g = _mat3(A, c - surface.center[:, None])
        At /= np.sqrt(_dot(g, g))
        return At
    return None  # plane, mesh facet


def soft_finger_test(c, n, f, tau, w_cov, blocks, mu, torsion_radius, alpha):
    """Single-contact test of soft-finger estimates: ``single (N,)``, ``p (N,)``, ``reason (N,) int8``.

    Parameters
    ----------
    c, n, f : ndarray, shape (N, 3)
        Estimated point (m), outward unit normal, force (N), face frame; NaN rows: no solution.
    tau : ndarray, shape (N,)
        Estimated torsion, N·m.
    w_cov : ndarray, shape (6, 6) or (N, 6, 6)
        Wrench noise covariance, ``[fx, fy, fz, tx, ty, tz]`` (N², N²·m, (N·m)²).
    blocks : list of (Surface, PatchBoundary or None, slice)
        Consecutive rows of each patch.
    mu, torsion_radius : float or ndarray, shape (N,)
        Friction coefficient, effective torsional radius (m).
    alpha : float
        Significance level.
    """
    N = len(c)
    cT, nT, fT = (np.ascontiguousarray(x.T) for x in (c, n, f))
    finite = np.isfinite(_dot(cT, cT))
    finite &= np.isfinite(_dot(nT, nT))
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        t1, t2 = _tangents(nT)
        finite &= np.isfinite(_dot(t1, t1) + _dot(t2, t2))
        a1, a2 = _cross(t1, fT), _cross(t2, fT)
        curved = any(isinstance(surface, Ellipsoid) for surface, _, _ in blocks)  # spheres too
        if curved:  # ∂n/∂θ; planes and facets have none (their θ-gradients below are 0)
            d1, d2 = np.zeros((3, N)), np.zeros((3, N))
            for surface, _, sl in blocks:
                got = _dn(surface, cT[:, sl], nT[:, sl], t1[:, sl])
                if got is not None:
                    d1[:, sl] = got
                    d2[:, sl] = _dn(surface, cT[:, sl], nT[:, sl], t2[:, sl])
            a1 += tau * d1
            a2 += tau * d2
        bounded = any(boundary is not None for _, boundary, _ in blocks)
        adj = (_cross(a2, nT), _cross(nT, a1) if curved or bounded else None, _cross(a1, a2))
        det = _dot(a1, adj[0])
        # the pushing force and the friction margin
        fn = -_dot(fT, nT)
        ft_vec = fT + fn * nT
        ft = np.sqrt(_dot(ft_vec, ft_vec))
        tq = tau / torsion_radius
        s = np.hypot(ft, tq)
        u = np.divide(ft_vec, ft, out=np.zeros((3, N)), where=ft > 0)
        k = ft / s
        shear_ok = s > 0
        # gradients [θ1, θ2, τ] and over f of the two limits, side by side: (…, 2, N)
        gb = np.zeros((3, 2, N))
        if curved:
            np.negative(_dot(fT, d1), out=gb[0, 0])
            np.negative(_dot(fT, d2), out=gb[1, 0])
            gs_t1 = fn * _dot(u, d1) * k
            gs_t2 = fn * _dot(u, d2) * k
        else:
            gs_t1 = gs_t2 = np.zeros(N)
        gs_tau = tq / (torsion_radius * s)
        gf = np.empty((3, 2, N))
        np.negative(nT, out=gf[:, 0])
        gs_f = u * k
        if not shear_ok.all():
            for x in (gs_t1, gs_t2, gs_tau):
                x[~shear_ok] = 0.0
            gs_f[:, ~shear_ok] = 0.0
        mu_ = mu if np.ndim(mu) == 0 else np.asarray(mu)
        np.subtract(mu_ * gb[0, 0], gs_t1, out=gb[0, 1])
        np.subtract(mu_ * gb[1, 0], gs_t2, out=gb[1, 1])
        np.subtract(0.0, gs_tau, out=gb[2, 1])
        np.subtract(mu_ * gf[:, 0], gs_f, out=gf[:, 1])
        g = np.empty((2, N))
        g[0] = fn
        np.subtract(mu_ * fn, s, out=g[1])
        var = _variance(gb, gf, cT, adj, det, w_cov, flat=not curved)
        z = np.full((3, N), np.inf)
        z[:2] = _z(g, var)
        for surface, boundary, sl in blocks:
            if boundary is None or sl.stop == sl.start:
                continue
            z[2, sl] = _boundary_z(boundary, cT[:, sl], t1[:, sl], t2[:, sl], adj, det, sl, w_cov)
    if not finite.all():
        z[:, ~finite] = np.inf
    p = np.ones((3, N))
    low = z < _Z_ONE
    p[low] = ndtr(z[low])
    if not finite.all():
        p[:, ~finite] = 0.0
    pmin = np.minimum(np.minimum(p[0], p[1]), p[2])
    single = pmin >= alpha
    if single.all():
        return single, pmin, np.zeros(N, np.int8)
    p_all = np.ones((N, 4))
    p_all[:, :3] = p.T
    z_all = np.zeros((N, 4))
    z_all[:, :3] = z.T
    shear = ft >= np.abs(tq)
    return _decide(p_all, z_all, finite, shear[finite], alpha, False)


def _variance(gb, gf, c, adj, det, w_cov, flat=False):
    """``σ²`` ``(K, N)`` of ``K`` functions with gradients ``gb (3, K, N)`` over ``[θ1, θ2, τ]`` and ``gf (3, K, N)`` over f.

    ``flat``: the θ-gradients are 0 (a plane or a facet): only the τ term of ``u_m``.
    """
    if flat:
        um = gb[2] * adj[2][:, None]
    else:
        um = gb[0] * adj[0][:, None] + gb[1] * adj[1][:, None] + gb[2] * adj[2][:, None]  # (3, K, N)
    um /= det
    u = np.empty((6,) + gb.shape[1:])
    u[3:] = um
    u[:3] = gf + _cross(c[:, None], um)
    if w_cov.ndim == 2:
        return _quad6(u, w_cov)
    return np.einsum("ikn,nij,jkn->kn", u, w_cov, u)


def _boundary_z(boundary, c, t1, t2, adj, det, sl, w_cov):
    """``z`` of the boundary margin on rows ``sl`` (central difference along the tangents)."""
    h = _BOUNDARY_STEP
    n = c.shape[1]
    pts = np.empty((5, n, 3))
    pts[0] = c.T
    pts[1] = (c + h * t1).T
    pts[2] = (c + h * t2).T
    pts[3] = (c - h * t1).T
    pts[4] = (c - h * t2).T
    m = boundary.margin(pts.reshape(-1, 3)).reshape(5, n)
    gb = np.zeros((3, 1, n))
    gb[0, 0] = (m[1] - m[3]) / (2 * h)
    gb[1, 0] = (m[2] - m[4]) / (2 * h)
    cov = w_cov if w_cov.ndim == 2 else w_cov[sl]
    var = _variance(gb, np.zeros((3, 1, n)), c, tuple(a[:, sl] for a in adj), det[sl], cov)
    return _z(m[0], var[0])

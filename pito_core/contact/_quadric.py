"""Closed-form soft-finger solutions for the plane, the sphere and the ellipsoid.

Model (Bicchi, Salisbury & Brock 1993): a finger pushing on the surface at ``c`` with
force ``f`` and torsion ``τ`` about the outward normal ``n(c)`` produces the moment
``m = c × f + τ n(c)`` about the frame origin, with ``f · n < 0``.

Every function here is pure numpy over batches ``f, m (N, 3)`` (N, N·m) and returns
``c (N, 3)`` m, ``n (N, 3)``, ``tau (N,)`` N·m and ``ok (N,) bool``; rows where no
pushing contact exists get ``ok = False`` (their other values are unspecified and the
caller overwrites them with NaN). No Python loop over samples, no exception.

Plane ``n · x = d``: ``c = (n × m + d f) / (n · f)``, ``τ = f · m / (f · n)`` — exact,
linear, no cancellation.

Ellipsoid ``c = c0 + R diag(a) q`` with ``|q| = 1``: with ``p = c − c0`` and the moment
about the centre ``m' = m − c0 × f``, the model is ``m' = p × f + K A p`` (``A`` the
quadric matrix, ``K = τ / |A p|``). In principal axes, the substitution ``p = a ⊙ q``
turns it exactly into a unit-sphere problem ``μ = q × g + κ q`` with
``g = a ⊙ f``, ``μ = a ⊙ m' / (a1 a2 a3)``, ``κ = K / (a1 a2 a3)``. Its solutions are

    q = [ v (g × μ) + σ r (α μ + v g) ] / (α² + v |g|²),   r = √v,   σ = ±1,

where ``α = g · μ`` and ``v ≥ 0`` is the non-negative root of ``v² − B v − α² = 0``,
``B = |g|² − |μ|²`` (one root is ≥ 0, the other ≤ 0). ``v`` is taken from the stable
form of the quadratic formula (no subtraction of nearly equal numbers, exact ``τ = 0``
gives ``v = B`` and the two ends of the line of action). The two signs ``σ`` give
solutions with opposite ``K``; since ``f · m' = K fᵀ A p``, exactly one of them pushes
in (``f · n < 0``) whenever ``f · m ≠ 0``, and for ``f · m = 0`` the pushing one is the
entry point of the line of action. We evaluate ``(f / a) · q`` (∝ ``f · n``) for both
and keep the smaller, so the side of the surface is never guessed.
"""

from __future__ import annotations

import numpy as np

from ..frames import cross_rows as _cross

__all__ = ["solve_plane", "solve_ellipsoid", "solve_sphere"]


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.einsum("ij,ij->i", a, b)


def _norm(x: np.ndarray) -> np.ndarray:
    """``|x|`` of rows ``x (N, 3)`` as ``(N, 1)`` (a sum of three squares; no small-axis reduction)."""
    return np.sqrt(np.einsum("ij,ij->i", x, x))[:, None]


def _mat(x: np.ndarray, M: np.ndarray) -> np.ndarray:
    """``x @ M`` for ``x (N, 3)`` and a small matrix ``M (3, K)`` (einsum: BLAS is slow here)."""
    return np.einsum("ij,jk->ik", x, M)


def _mat3(x: np.ndarray, M: np.ndarray) -> np.ndarray:
    """``x @ M`` for ``x (N, 3)`` and a ``(3, 3)`` matrix ``M``, column by column (no BLAS: the same
    rounding whatever ``N``; faster than einsum here)."""
    out = np.empty((len(x), 3))
    x0, x1, x2 = x[:, 0], x[:, 1], x[:, 2]
    for k in range(3):
        o = out[:, k]
        np.multiply(x0, M[0, k], out=o)
        o += x1 * M[1, k]
        o += x2 * M[2, k]
    return out


def solve_plane(f, m, point, normal):
    """Soft-finger contact on the plane through ``point (3,)`` with unit ``normal (3,)``.

    Returns ``c, n, tau, ok`` (see module docstring); ``ok`` is ``f · n < 0``.
    """
    fn = f[:, 0] * normal[0]
    fn += f[:, 1] * normal[1]
    fn += f[:, 2] * normal[2]
    d = float(point @ normal)
    ok = fn < 0
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / fn
        c = np.empty_like(f)
        for i, (j, k) in enumerate(((1, 2), (2, 0), (0, 1))):  # c_i = ((n × m)_i + d f_i) / (n · f)
            col = c[:, i]
            if normal[j] != 0.0:  # (n × m)_i = n_j m_k − n_k m_j, the zero terms of a constant normal left out
                np.multiply(normal[j], m[:, k], out=col)
                if normal[k] != 0.0:
                    col -= normal[k] * m[:, j]
            elif normal[k] != 0.0:
                np.multiply(-normal[k], m[:, j], out=col)
            else:
                col[:] = 0.0
            if d != 0.0:
                col += d * f[:, i]
            col *= inv
        tau = _dot(f, m) * inv
    n = np.empty_like(f)
    n[:] = normal
    return c, n, tau, ok


def _unit_sphere_terms(g, mu):
    """``P = v (g × μ)``, ``Q = r (α μ + v g)`` and ``den = α² + v |g|²`` (see module doc)."""
    gg = _dot(g, g)
    alpha = _dot(g, mu)
    B = gg - _dot(mu, mu)
    a2 = alpha * alpha
    D = np.sqrt(B * B + 4.0 * a2)
    with np.errstate(divide="ignore", invalid="ignore"):
        # Stable root: never subtract nearly equal numbers.
        v = np.where(B >= 0, 0.5 * (B + D), 2.0 * a2 / (D - B))
    v = np.where(np.isfinite(v), v, 0.0)
    r = np.sqrt(v)
    P = _cross(g, mu)
    P *= v[:, None]
    Q = alpha[:, None] * mu
    Q += v[:, None] * g
    Q *= r[:, None]
    den = a2 + v * gg
    return P, Q, den


def solve_sphere(f, m, center, radius):
    """Soft-finger contact on the sphere ``|c − center| = radius``.

    On a sphere ``f · n`` is proportional to ``g · q``, so the pushing root is always
    ``σ = −1`` (one candidate only).
    """
    radius = float(radius)
    if center.any():
        mp = m - _cross(center, f)
    else:
        mp = m
    g = f * (1.0 / radius)
    mu = mp * (1.0 / radius**2)
    P, Q, den = _unit_sphere_terms(g, mu)
    with np.errstate(divide="ignore", invalid="ignore"):
        n = P - Q
        n *= (1.0 / den)[:, None]
        ok = (den > 0) & (_dot(g, n) < 0)
        n /= _norm(n)  # |q| = 1 up to rounding
    c = n * radius
    c += center
    tau = _dot(n, m - _cross(c, f))
    return c, n, tau, ok


def solve_ellipsoid(f, m, center, semi_axes, rotation):
    """Soft-finger contact on the ellipsoid ``c0 + R diag(a) q``, ``|q| = 1``."""
    a = np.asarray(semi_axes, dtype=float)
    R = np.asarray(rotation, dtype=float)
    mp = m - _cross(center, f) if center.any() else m
    g = _mat3(f, R)  # components in the principal frame
    g /= a
    mu = _mat3(mp, R)
    mu *= a / (a[0] * a[1] * a[2])
    P, Q, den = _unit_sphere_terms(g, mu)
    with np.errstate(divide="ignore", invalid="ignore"):
        q = P - Q
        q *= (1.0 / den)[:, None]
        ok = (den > 0) & (_dot(g, q) < 0)
        q /= _norm(q)
        n_e = q / a
        n_e /= _norm(n_e)
    c = _mat3(q * a, R.T)
    c += center
    n = _mat3(n_e, R.T)
    tau = _dot(n, m - _cross(c, f))
    return c, n, tau, ok

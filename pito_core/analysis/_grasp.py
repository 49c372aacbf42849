"""Per-sample grasp quantities from contact arrays: pure, vectorised numpy (docs/analysis.md).

Every function takes the contacts of N samples on the six patches (core frame, face i at
index ``i − 1``): ``point (N, 6, 3)`` m, ``normal (N, 6, 3)`` outward unit normals,
``force (N, 6, 3)`` N (the force *on the object*, pushing in: ``f · n < 0``),
``torsion (N, 6)`` N·m, ``active (N, 6)`` bool (the contacts that count).

Grasp matrix (hard-finger contacts, moments about the centre of mass ``c``)::

    G = [ I₃        …  I₃       ]      (6 × 3K),   w = G f = Σ_k [f_k; (p_k − c) × f_k]
        [ [p_1−c]×  …  [p_K−c]× ]

The contact forces split into a part that balances the net wrench (the part that holds the
object up and moves it) and an internal part that squeezes without moving it::

    f = G⁺ G f  +  (I − G⁺ G) f  =  f_manip + f_internal,       G f_internal = 0

``G⁺ G f`` is the minimum-norm set of contact forces giving the same net wrench ``w``;
in equilibrium ``w = −w_ext`` (gravity and inertia), so ``f = −G⁺ w_ext + (I − G⁺G) f``.
The split does not depend on the reference point of the moments.
"""

from __future__ import annotations

import numpy as np

from ..frames import cross_rows

__all__ = ["normal_tangential", "grasp_decomposition", "grasp_decomposition_pinv", "net_wrench"]

#: Relative singular-value cut of the grasp matrix's pseudo-inverse (as ``numpy.linalg.pinv``'s ``rcond``).
_RCOND = 1e-10
#: ``J``'s smallest eigenvalue over its trace below which the contact points are collinear.
_COLLINEAR = 1e-12


def normal_tangential(force, normal, active):
    """Normal (pushing-in) and tangential force magnitudes of each contact, N.

    Parameters
    ----------
    force, normal : ndarray, shape (N, 6, 3)
        Force on the object (N) and outward unit normal.
    active : ndarray of bool, shape (N, 6)

    Returns
    -------
    f_n, f_t : ndarray, shape (N, 6)
        ``f_n = −f · n`` (N, ≥ 0 for a pushing finger) and ``f_t = ‖f + f_n n‖`` (N);
        0 where not active.
    """
    return _normal_tangential(np.where(active[..., None], finite(force), 0.0), finite(normal))


def finite(x) -> np.ndarray:
    """``numpy.nan_to_num(x)`` (float) without its cost when ``x`` has no infinities: NaN → 0."""
    x = np.asarray(x, float)
    nan = np.isnan(x)
    if not nan.any():
        return x if np.isfinite(x).all() else np.nan_to_num(x)
    out = np.where(nan, 0.0, x)
    return out if np.isfinite(out).all() else np.nan_to_num(x)


def _normal_tangential(f, n):
    """:func:`normal_tangential` of forces already zero where inactive and finite normals."""
    f_n = -np.einsum("nkj,nkj->nk", f, n)
    return f_n, norm3(f + f_n[..., None] * n)


def norm3(x) -> np.ndarray:
    """``numpy.linalg.norm(x, axis=-1)`` of ``(..., 3)`` (the same numbers), at a third of its cost."""
    x0, x1, x2 = x[..., 0], x[..., 1], x[..., 2]
    return np.sqrt(x0 * x0 + x1 * x1 + x2 * x2)


def grasp_decomposition(point, force, active, cog=(0.0, 0.0, 0.0)):
    """Split the contact forces into manipulation and internal parts with the grasp matrix.

    Parameters
    ----------
    point, force : ndarray, shape (N, 6, 3)
        Contact points (m) and forces on the object (N), core frame.
    active : ndarray of bool, shape (N, 6)
        Contacts in the grasp; the others get zero columns in ``G`` and zero parts.
    cog : array-like, shape (3,)
        Centre of mass, core frame, m (moments about it; the split does not depend on it, so
        it is computed about the active contacts' centroid).

    Returns
    -------
    f_manip, f_internal : ndarray, shape (N, 6, 3)
        ``G⁺ G f`` and ``(I − G⁺ G) f`` per contact, N (module docstring).

    Notes
    -----
    Closed form, no SVD: with moments about the centroid of the K active points
    (``r_k = p_k − p̄``, ``Σ r_k = 0``), ``G Gᵀ = diag(K I₃, J)`` with
    ``J = Σ_k (‖r_k‖² I₃ − r_k r_kᵀ)``, so ``G⁺ G f = Gᵀ (G Gᵀ)⁺ G f`` is, per contact,
    ``F / K + (J⁺ M) × r_k`` with ``F = Σ f_k`` and ``M = Σ r_k × f_k``. ``J`` has rank 3
    (inverse by its adjugate), 2 when the points are collinear (``J⁺ = J / s²``, ``s = Σ ‖r_k‖²``) or
    0 (one point). ``J``'s smallest eigenvalue counts as 0 below ``1e-12 · tr J`` (points
    collinear to rounding: a computed ``J`` of collinear points keeps ``~1e-16 · tr J`` there,
    where the ``pinv`` of ``G`` with ``rcond = 1e-10`` sees an exact zero); the result equals
    that ``pinv`` to rounding (:func:`grasp_decomposition_pinv`, tests/analysis/test_grasp_metrics.py).
    """
    active = np.asarray(active, bool)
    a = active[..., None]
    return _split(np.where(a, finite(point), 0.0), np.where(a, finite(force), 0.0), active)


def _split(p, f, active):
    """:func:`grasp_decomposition` of points and forces already zero where inactive (finite).

    Component-first arrays ``(3, 6, N)``: every product and sum runs over contiguous rows.
    """
    P = np.ascontiguousarray(p.transpose(2, 1, 0))
    Fc = np.ascontiguousarray(f.transpose(2, 1, 0))
    A = np.ascontiguousarray(active.T)
    k = A.sum(axis=0).astype(float)
    kk = np.maximum(k, 1.0)
    R = np.where(A, P - (P.sum(axis=1) / kk)[:, None], 0.0)  # about the active points' centroid
    F = Fc.sum(axis=1)
    M = np.stack([(R[1] * Fc[2] - R[2] * Fc[1]).sum(axis=0), (R[2] * Fc[0] - R[0] * Fc[2]).sum(axis=0),
                  (R[0] * Fc[1] - R[1] * Fc[0]).sum(axis=0)])
    xx, yy, zz = (R[0] * R[0]).sum(axis=0), (R[1] * R[1]).sum(axis=0), (R[2] * R[2]).sum(axis=0)
    xy, xz, yz = (R[0] * R[1]).sum(axis=0), (R[0] * R[2]).sum(axis=0), (R[1] * R[2]).sum(axis=0)
    tr = xx + yy + zz
    j00, j11, j22, j01, j02, j12 = yy + zz, xx + zz, xx + yy, -xy, -xz, -yz
    a00, a11, a22 = j11 * j22 - j12 * j12, j00 * j22 - j02 * j02, j00 * j11 - j01 * j01  # adjugate of J
    a01, a02, a12 = j02 * j12 - j01 * j22, j01 * j12 - j02 * j11, j01 * j02 - j00 * j12
    det = j00 * a00 + j01 * a01 + j02 * a02
    full = det > _COLLINEAR * tr * (a00 + a11 + a22)  # λ_min ≈ det / Σ principal minors, against tr
    line = ~full & (tr > _RCOND ** 2 * np.maximum(k, tr))  # rank 2: collinear points
    with np.errstate(divide="ignore", invalid="ignore"):
        x_full = np.stack([a00 * M[0] + a01 * M[1] + a02 * M[2], a01 * M[0] + a11 * M[1] + a12 * M[2],
                           a02 * M[0] + a12 * M[1] + a22 * M[2]]) / det
        x_line = np.stack([j00 * M[0] + j01 * M[1] + j02 * M[2], j01 * M[0] + j11 * M[1] + j12 * M[2],
                           j02 * M[0] + j12 * M[1] + j22 * M[2]]) / (tr * tr)
    x = np.where(full, x_full, np.where(line, x_line, 0.0))
    Fk = F / kk
    f_manip = np.empty(p.shape)
    out = f_manip.transpose(2, 1, 0)
    out[0] = (Fk[0] + (x[1] * R[2] - x[2] * R[1])) * A
    out[1] = (Fk[1] + (x[2] * R[0] - x[0] * R[2])) * A
    out[2] = (Fk[2] + (x[0] * R[1] - x[1] * R[0])) * A
    return f_manip, f - f_manip


def grasp_decomposition_pinv(point, force, active, cog=(0.0, 0.0, 0.0)):
    """:func:`grasp_decomposition` by ``numpy.linalg.pinv`` of each sample's ``G`` (6 × 18): the reference.

    The code of the analysis before the closed form (slow: one SVD per sample); kept to
    check the closed form against.
    """
    active = np.asarray(active, bool)
    n = point.shape[0]
    f = np.where(active[..., None], np.nan_to_num(force), 0.0)
    r = np.where(active[..., None], np.nan_to_num(point) - np.asarray(cog, float), 0.0)
    G = np.zeros((n, 6, 6, 3))  # (sample, wrench row, contact, force component)
    G[:, :3] = np.eye(3).T[None, :, None, :] * active[:, None, :, None]
    G[:, 3, :, 1], G[:, 3, :, 2] = -r[..., 2], r[..., 1]
    G[:, 4, :, 0], G[:, 4, :, 2] = r[..., 2], -r[..., 0]
    G[:, 5, :, 0], G[:, 5, :, 1] = -r[..., 1], r[..., 0]
    G = G.reshape(n, 6, 18)
    w = np.einsum("nij,nj->ni", G, f.reshape(n, 18))
    f_manip = np.einsum("nij,nj->ni", np.linalg.pinv(G, rcond=_RCOND), w).reshape(n, 6, 3)
    f_manip *= active[..., None]
    return f_manip, f - f_manip


def net_wrench(point, force, torsion, normal, active, cog=(0.0, 0.0, 0.0)):
    """Σ of the contact wrenches on the object: ``(force (N, 3) N, moment (N, 3) N·m about cog)``.

    ``Σ_k f_k`` and ``Σ_k (p_k − c) × f_k + τ_k n_k`` over the active contacts.
    """
    a = active[..., None]
    return _net(finite(point), np.where(a, finite(force), 0.0), finite(torsion), finite(normal), active, cog)


def _net(point, f, torsion, normal, active, cog):
    """:func:`net_wrench` of finite arrays, ``f`` zero where inactive."""
    r = np.where(active[..., None], point - np.asarray(cog, float), 0.0)
    tau = np.where(active, torsion, 0.0)[..., None] * normal
    n = f.shape[0]
    m = cross_rows(r.reshape(-1, 3), f.reshape(-1, 3)).reshape(n, 6, 3)
    m += tau
    return _sum_faces(f), _sum_faces(m)


def _sum_faces(x) -> np.ndarray:
    """``x.sum(axis=1)`` of ``(N, 6, 3)`` (the same numbers: numpy adds the faces in order), without its strided reduction."""
    out = x[:, 0] + x[:, 1]
    for i in range(2, x.shape[1]):
        out += x[:, i]
    return out

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

__all__ = ["normal_tangential", "grasp_decomposition", "net_wrench"]

#: Samples per block of the grasp-matrix split (bounds its memory to ~20 MB).
_BLOCK = 10_000


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
    f = np.where(active[..., None], np.nan_to_num(force), 0.0)
    n = np.nan_to_num(normal)
    f_n = -np.einsum("nkj,nkj->nk", f, n)
    f_t = np.linalg.norm(f + f_n[..., None] * n, axis=-1)
    return f_n, f_t


def grasp_decomposition(point, force, active, cog=(0.0, 0.0, 0.0)):
    """Split the contact forces into manipulation and internal parts with the grasp matrix.

    Parameters
    ----------
    point, force : ndarray, shape (N, 6, 3)
        Contact points (m) and forces on the object (N), core frame.
    active : ndarray of bool, shape (N, 6)
        Contacts in the grasp; the others get zero columns in ``G`` and zero parts.
    cog : array-like, shape (3,)
        Centre of mass, core frame, m (moments about it; the split does not depend on it).

    Returns
    -------
    f_manip, f_internal : ndarray, shape (N, 6, 3)
        ``G⁺ G f`` and ``(I − G⁺ G) f`` per contact, N (module docstring).
    """
    busy = active.any(axis=1)
    if not busy.all():  # samples without contact: G = 0, so both parts are 0 (no SVD to run)
        f_manip = np.zeros(point.shape)
        f_int = np.zeros(point.shape)
        if busy.any():
            f_manip[busy], f_int[busy] = grasp_decomposition(point[busy], force[busy], active[busy], cog)
        return f_manip, f_int
    if point.shape[0] > _BLOCK:  # bounded memory: the (n, 6, 18) matrices block by block
        parts = [grasp_decomposition(point[a:a + _BLOCK], force[a:a + _BLOCK], active[a:a + _BLOCK], cog)
                 for a in range(0, point.shape[0], _BLOCK)]
        return np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts])
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
    f_manip = np.einsum("nij,nj->ni", np.linalg.pinv(G, rcond=1e-10), w).reshape(n, 6, 3)
    f_manip *= active[..., None]  # rounding leaves ~1e-21 in the zero columns
    return f_manip, f - f_manip


def net_wrench(point, force, torsion, normal, active, cog=(0.0, 0.0, 0.0)):
    """Σ of the contact wrenches on the object: ``(force (N, 3) N, moment (N, 3) N·m about cog)``.

    ``Σ_k f_k`` and ``Σ_k (p_k − c) × f_k + τ_k n_k`` over the active contacts.
    """
    a = active[..., None]
    f = np.where(a, np.nan_to_num(force), 0.0)
    r = np.where(a, np.nan_to_num(point) - np.asarray(cog, float), 0.0)
    tau = np.where(active, np.nan_to_num(torsion), 0.0)[..., None] * np.nan_to_num(normal)
    n = f.shape[0]
    m = cross_rows(r.reshape(-1, 3), f.reshape(-1, 3)).reshape(n, 6, 3) + tau
    return f.sum(axis=1), m.sum(axis=1)

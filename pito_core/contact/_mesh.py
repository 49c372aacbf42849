"""Exact soft-finger contact on a triangle mesh, with conservative candidate pruning.

On facet j (plane ``n_j · x = d_j``) the soft-finger equations have the unique solution
``c_j = (n_j × m + d_j f) / (n_j · f)``, ``τ_j = f · m / (f · n_j)`` (see ``_quadric``).
The contact is a facet whose ``c_j`` lies inside its triangle with ``f · n_j < 0``.
Among several such facets (non-convex meshes) we keep the one met first by a finger
moving along ``f``: the smallest ``c_j · f``. For ``τ = 0`` this is exactly the first
entry of the line of action into the surface.

Pruning (exact, never drops the true facet). ``c_j`` lies on the line parallel to ``f``
offset from the line of action by ``δ_j = τ_j (n_j × f) / |f|²``, of length
``|k| tan α_j`` with ``k = f · m / |f|²`` and ``α_j`` the angle between ``n_j`` and
``−f``. Facets are sorted into groups of similar position and normal (median splits),
and runs of ``_FANOUT`` groups form a coarser level; every node has a bounding ball
(``O``, ``ρ``), a slab ``|ν · (x − O)| ≤ h`` and a normal cone (axis ``ν``, half-angle
``β``). A node is searched only if a facet may face the finger (``α − β < 90°``) and
the ball, slab and wedge tests of ``_Bounds.may_hold`` pass; the surviving groups are
then solved facet by facet in one vectorised pass.
"""

from __future__ import annotations

import numpy as np

from ._quadric import _cross, _mat
from ._tol import BARYCENTRIC_TOL

__all__ = ["MeshIndex"]

#: Samples per vectorised chunk (bounds the memory of the candidate arrays).
_CHUNK = 2048

#: Groups per level-0 node of the two-level pruning hierarchy.
_FANOUT = 4


class _Bounds:
    """Bounding balls (centre ``O``, radius ``rho``) and normal cones (``axis``, ``β``)."""

    def __init__(self, tris: list, normals: list, scale: float):
        k = len(tris)
        self.O = np.zeros((k, 3))
        rho = np.zeros(k)
        self.axis = np.zeros((k, 3))
        beta = np.full(k, np.pi)
        for i, (t, nm) in enumerate(zip(tris, normals)):
            pts = t.reshape(-1, 3)
            self.O[i] = 0.5 * (pts.min(0) + pts.max(0))
            rho[i] = np.linalg.norm(pts - self.O[i], axis=1).max()
            s = nm.sum(0)
            ns = np.linalg.norm(s)
            if ns > 1e-12:
                self.axis[i] = s / ns
                beta[i] = np.arccos(np.clip(nm @ self.axis[i], -1.0, 1.0).min())
        self.rho = rho * (1 + 1e-9) + 1e-12 * scale
        # Slab half-thickness along the cone axis: every triangle lies in |ν·(x − O)| ≤ h.
        h = np.array([np.abs((t.reshape(-1, 3) - o) @ ax).max() for t, o, ax in zip(tris, self.O, self.axis)])
        self.h = h * (1 + 1e-9) + 1e-12 * scale
        self.axis_O = (self.axis * self.O).sum(1)
        self.O_x_axis = np.cross(self.O, self.axis)
        beta = np.minimum(beta + 1e-9, np.pi)
        self.cos_beta = np.cos(beta)
        self.sin_beta = np.sin(beta)
        self.O2 = (self.O * self.O).sum(1)

    def may_hold(self, ca, Ol, Of, Nl, FW, PN, l0sq, k, idx):
        """Whether node ``idx`` may hold the contact (broadcasting arrays).

        Inputs: ``ca = −f̂·ν``, ``Ol = ℓ0·O``, ``Of = f̂·O``, ``Nl = ν·ℓ0``,
        ``FW = f̂·(O × ν)``, ``PN = ν·(f̂ × ℓ0)``, ``|ℓ0|²`` and ``k = f·m/|f|²``, with
        ``ℓ0`` the point of the line of action nearest the origin. Three necessary
        conditions, with ``κ = |k|``: (ball) the line of action passes within
        ``ρ + κ tan(α + β)`` of ``O``; (slab) where it crosses the mid-plane
        ``ν·(x − O) = 0`` it is within ``ρ + h/|cos α| + κ tan(α + β) (1 + 1/|cos α|)``;
        (wedge) the offset of facet j, ``δj = −k tan αj (ej × f̂)`` (``ej`` the direction of
        ``nj`` across ``f̂``), lies in a wedge of half-angle ``γ = asin(sin β / sin α)``
        about ``−k (ν × f̂)``, and ``O − ℓ0`` (across ``f̂``) must come within ``ρ`` of it.
        """
        ca = np.clip(ca, -1.0, 1.0)
        sa = np.sqrt(1.0 - ca * ca)
        cb, sb = self.cos_beta[idx], self.sin_beta[idx]
        front = (cb <= 0.0) | (ca * cb + sa * sb > 0.0)  # α − β < 90°: a facet may face f
        cos_max = ca * cb - sa * sb  # cos(α + β)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            # α + β < 90° needs β < 90° (else α + β may wrap past 270° where cos > 0 again)
            tan_max = np.where((cb > 0.0) & (cos_max > 0.0), (sa * cb + ca * sb) / cos_max, np.inf)
            # κ = 0 (no torsion): every candidate lies on the line of action itself.
            kappa = np.abs(k)
            shift = np.where(kappa > 0, kappa * tan_max, 0.0)
            rho = self.rho[idx]
            O2 = self.O2[idx]
            d2 = O2 - 2.0 * Ol + l0sq - Of * Of  # squared distance O – line of action
            ball = d2 <= (rho + shift + 1e-12) ** 2
            # slab test: t = ν·(O − ℓ0) / (ν·f̂) locates the crossing of the mid-plane
            inv_c = 1.0 / np.abs(ca)
            t = (self.axis_O[idx] - Nl) / (-ca)
            x2 = l0sq - 2.0 * Ol + O2 - 2.0 * t * Of + t * t  # |ℓ0 + t f̂ − O|²
            lim = rho + self.h[idx] * inv_c + shift * (1.0 + inv_c) + 1e-12
            slab = (np.abs(ca) < 1e-6) | ~np.isfinite(lim) | (x2 <= lim * lim)
            # wedge test (what bounds the groups whose normals are nearly across f)
            narrow = (cb > np.abs(ca)) & (sa > 1e-9)  # cap holds neither ±f̂: γ < 90°
            sin_g = np.where(narrow, np.minimum(sb / np.where(narrow, sa, 1.0), 1.0), 0.0)
            cos_g = np.where(narrow, np.sqrt(1.0 - sin_g * sin_g), -1.0)
            dist = np.sqrt(np.maximum(d2, 0.0))
            sgn = np.where(k < 0, 1.0, -1.0)
            Du = sgn * (FW - PN) / np.where(sa > 1e-9, sa, 1.0)  # (O − ℓ0) · u0
            cos_p = np.clip(Du / np.where(dist > 0, dist, 1.0), -1.0, 1.0)
            sin_p = np.sqrt(1.0 - cos_p * cos_p)
            wedge = (~narrow) | (dist == 0) | (cos_p >= cos_g - 1e-9) | (
                dist * (sin_p * cos_g - cos_p * sin_g) <= rho + 1e-12
            )
        return front & ball & slab & wedge


class MeshIndex:
    """Facet planes, barycentric dual vectors and the pruning groups of a mesh.

    Parameters
    ----------
    triangles : ndarray, shape (F, 3, 3)
        Vertices of every facet, m; counter-clockwise seen from outside.
    group_size : int
        Facets per group (leaves of the median-split tree).
    """

    def __init__(self, triangles: np.ndarray, group_size: int = 8):
        if group_size < 1:
            raise ValueError(f"group_size: expected a positive integer, got {group_size}")
        F = len(triangles)
        v0, v1, v2 = triangles[:, 0], triangles[:, 1], triangles[:, 2]
        e1, e2 = v1 - v0, v2 - v0
        nrm = np.cross(e1, e2)
        area2 = np.linalg.norm(nrm, axis=1)
        scale = max(float(np.ptp(triangles.reshape(-1, 3), axis=0).max()), 1e-300)
        good = area2 > 1e-14 * scale**2
        if not good.any():
            raise ValueError("mesh: expected at least one non-degenerate facet")
        normals = np.zeros((F, 3))
        normals[good] = nrm[good] / area2[good, None]
        self.normals_orig = normals
        # Barycentric dual vectors: u = (x − v0)·b1, v = (x − v0)·b2.
        g11, g12, g22 = (e1 * e1).sum(1), (e1 * e2).sum(1), (e2 * e2).sum(1)
        det = np.where(good, area2**2, 1.0)
        b1 = (g22[:, None] * e1 - g12[:, None] * e2) / det[:, None]
        b2 = (g11[:, None] * e2 - g12[:, None] * e1) / det[:, None]
        centroids = triangles.mean(axis=1)

        # Split on position and normal together (normal scaled by the mesh size), so that
        # a group's normal cone stays narrow even where two sheets lie close together.
        keys = np.hstack([centroids, normals * scale])
        order = list(self._groups(keys, np.flatnonzero(good), group_size))
        G = group_size
        n_groups = max(len(order), 1)
        idx = -np.ones((n_groups, G), dtype=np.intp)
        for k, members in enumerate(order):
            idx[k, : len(members)] = members
        flat = idx.ravel()
        pad = flat < 0
        take = np.where(pad, 0, flat)
        self.facet = flat  # original facet index, −1 for padding
        self.G = G
        self.v0 = np.where(pad[:, None], 0.0, v0[take])
        self.n = np.where(pad[:, None], 0.0, normals[take])  # padding never faces a finger
        self.d = (self.v0 * self.n).sum(1)
        self.b1 = np.where(pad[:, None], 0.0, b1[take])
        self.b2 = np.where(pad[:, None], 0.0, b2[take])
        self.v0b1 = (self.v0 * self.b1).sum(1)
        self.v0b2 = (self.v0 * self.b2).sum(1)
        # One row per padded facet, gathered in one go: n, d, b1, v0·b1, b2, v0·b2.
        self.packed = np.hstack([self.n, self.d[:, None], self.b1, self.v0b1[:, None],
                                 self.b2, self.v0b2[:, None]])

        # Bounding balls and normal cones: groups (level 1) and runs of _FANOUT
        # consecutive groups (level 0; consecutive leaves of the split tree are close).
        self.n_groups = n_groups
        self.level1 = _Bounds([triangles[mb] for mb in order], [normals[mb] for mb in order], scale)
        supers = [np.concatenate(order[i : i + _FANOUT]) for i in range(0, n_groups, _FANOUT)]
        self.level0 = _Bounds([triangles[mb] for mb in supers], [normals[mb] for mb in supers], scale)
        self.packed_groups = self.packed.reshape(n_groups, G, -1)

    @staticmethod
    def _groups(centroids, members, G):
        """Spatially coherent groups of at most G facets (median splits, longest axis)."""
        stack = [members]
        while stack:
            m = stack.pop()
            if len(m) == 0:
                continue
            if len(m) <= G:
                yield m
                continue
            c = centroids[m]
            ax = int(np.argmax(np.ptp(c, axis=0)))
            m = m[np.argsort(c[:, ax], kind="stable")]
            half = G * int(np.ceil(len(m) / G / 2))
            stack.append(m[half:])
            stack.append(m[:half])

    # ------------------------------------------------------------------------------
    def candidate_groups(self, f, m):
        """Pairs ``(sample, group)`` whose group may hold the contact (conservative)."""
        ff = (f * f).sum(1)
        fhat = f / np.sqrt(ff)[:, None]
        l0 = _cross(f, m) / ff[:, None]  # point of the line of action closest to origin
        l0sq = (l0 * l0).sum(1)
        k = (f * m).sum(1) / ff
        p = _cross(fhat, l0)
        B0 = self.level0
        keep = B0.may_hold(
            -_mat(fhat, B0.axis.T), _mat(l0, B0.O.T), _mat(fhat, B0.O.T), _mat(l0, B0.axis.T),
            _mat(fhat, B0.O_x_axis.T), _mat(p, B0.axis.T), l0sq[:, None], k[:, None], slice(None),
        )
        si, bi = np.nonzero(keep)
        gi = (bi[:, None] * _FANOUT + np.arange(_FANOUT)).ravel()
        si = np.repeat(si, _FANOUT)
        inside = gi < self.n_groups
        si, gi = si[inside], gi[inside]
        B1 = self.level1
        ok = B1.may_hold(
            -np.einsum("ij,ij->i", fhat[si], B1.axis[gi]),
            np.einsum("ij,ij->i", l0[si], B1.O[gi]),
            np.einsum("ij,ij->i", fhat[si], B1.O[gi]),
            np.einsum("ij,ij->i", l0[si], B1.axis[gi]),
            np.einsum("ij,ij->i", fhat[si], B1.O_x_axis[gi]),
            np.einsum("ij,ij->i", p[si], B1.axis[gi]),
            l0sq[si],
            k[si],
            gi,
        )
        return si[ok], gi[ok]

    def solve(self, f, m):
        """Contact ``c, n, tau, ok, facet`` for force ``f`` and moment ``m`` ``(N, 3)``.

        Rows must have ``|f| > 0`` (the caller applies the force threshold first).
        ``facet`` is the original facet index, −1 where there is no contact.
        """
        N = len(f)
        c = np.full((N, 3), np.nan)
        n = np.full((N, 3), np.nan)
        tau = np.full(N, np.nan)
        facet = np.full(N, -1, dtype=np.intp)
        for s0 in range(0, N, _CHUNK):
            sl = slice(s0, min(s0 + _CHUNK, N))
            self._solve_chunk(f[sl], m[sl], c[sl], n[sl], tau[sl], facet[sl])
        return c, n, tau, facet >= 0, facet

    def _solve_chunk(self, f, m, c_out, n_out, tau_out, facet_out):
        si, gi = self.candidate_groups(f, m)
        if len(si) == 0:
            return
        G = self.G
        fk, mk = f[si][:, None, :], m[si][:, None, :]  # (K, 1, 3)
        P = self.packed_groups[gi]  # (K, G, 12): contiguous blocks
        nj = P[..., 0:3]
        fn = np.einsum("kgj,kzj->kg", nj, fk)
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = 1.0 / fn
            cj = _cross(nj, mk)
            cj += P[..., 3:4] * fk
            cj *= inv[..., None]
            u = np.einsum("kgj,kgj->kg", cj, P[..., 4:7]) - P[..., 7]
            v = np.einsum("kgj,kgj->kg", cj, P[..., 8:11]) - P[..., 11]
        tol = BARYCENTRIC_TOL
        ok = (fn < 0) & (u >= -tol) & (v >= -tol) & (u + v <= 1.0 + tol)
        if not ok.any():
            return
        k, g = np.nonzero(ok)
        rows_all = si[k]
        ce = cj[k, g]
        fe = f[rows_all]
        lam = np.einsum("ij,ij->i", ce, fe) / np.sqrt(np.einsum("ij,ij->i", fe, fe))
        order = np.lexsort((lam, rows_all))
        first = order[np.unique(rows_all[order], return_index=True)[1]]
        k, g, rows = k[first], g[first], rows_all[first]
        c_out[rows] = cj[k, g]
        n_out[rows] = nj[k, g]
        tau_out[rows] = np.einsum("ij,ij->i", f[rows], m[rows]) * inv[k, g]
        facet_out[rows] = self.facet[gi[k] * G + g]

"""The soft finger's single-contact decision at the cost of its limits' signs (``soft_finger_flags``).

:func:`~pito_core.contact._soft_test.soft_finger_test` gives every row ``z = g / σ_g`` of each
limit ``g`` (pushing ``f_n``, friction ``μ f_n − s``, the boundary's margin) and
``p = Φ(min z)``; ``single = p ≥ α``. A row whose margins are all ``≥ 0`` has every
``z ≥ 0`` or ``+∞`` (``_z``'s rules: a zero or unbounded σ never turns a margin ``≥ 0``
negative), so ``p ≥ Φ(0) = 1/2 ≥ α``: it is single whatever its noise, and nothing but
the margins' signs is needed to say so. The margins here are computed with the same
operations in the same order as in ``_soft_test`` (the same bits), so their signs are the
full test's. Only the other rows (pulling, beyond friction, off the patch, not finite:
usually few) get the full test, and among them ``Φ`` only where ``min z`` lies within
``10⁻⁹`` of ``Φ⁻¹(α)`` (elsewhere the comparison of ``min z`` with that quantile decides).
With ``α > 1/2`` every row gets the full test.

The p-values are read later, if at all (:func:`deferred_soft_p`, ``solve``'s
``single_contact_p``): ``p = Φ(min z)`` of the rows tested in full comes from the ``min z``
the decision kept; only the other rows' ``z`` are computed then, from copies of those rows
taken at solve time. Each row's ``z`` depends on its own row alone (no BLAS, the same
operations whatever the batch), so ``p`` is :func:`soft_finger_test`'s bit for bit.
"""

from __future__ import annotations

import weakref

import numpy as np

from ._estimate import COPIES, _Deferred
from ._plausibility import _ndtr
from ._soft_test import _Z_ONE, CHUNK, _chunk_blocks, _dot3, _finite_rows, _reasons, _work, _z_rows, _zmin
from ._surfaces import Plane

__all__ = ["soft_finger_flags", "deferred_soft_p"]

#: half-width of the band around Φ⁻¹(α), relative (1 + |Φ⁻¹(α)|), where Φ itself decides
_BAND = 1e-9
#: rows per pass of the screen (a handful of ufunc calls per pass: fewer, longer passes than the full test's)
SCREEN_CHUNK = 32768
#: the largest double: a margin ≤ this is finite
_BIG = np.finfo(float).max


def soft_finger_flags(c, n, f, tau, w_cov, blocks, mu, torsion_radius, alpha, ok=None, m=None, f2=None, zmin=None):
    """``single (N,)`` and ``reason (N,) int8``: those of :func:`soft_finger_test` (the same values).

    Arguments as :func:`~pito_core.contact._soft_test.soft_finger_test`; its ``p`` is left to
    the caller (``solve``: on first read, :func:`deferred_soft_p`). ``f2 (N,)``: ``|f|²`` of the
    rows if the caller has it (``solve``: its force threshold's), for the faces' planes' cheaper
    screen (``_face_plane_keep``). ``zmin (N,)``, optional, is filled: the smallest ``z`` of the
    rows tested in full (−inf: not finite), NaN on the rows single by their margins' signs.
    """
    N = len(f)
    e = torsion_radius
    finite = _finite_rows(c, n, ok)
    take = lambda x, rows: x if x is None or np.ndim(x) == 0 else x[rows]  # noqa: E731
    # planes without a boundary: their z come from f, m and τ alone (the normal only names a failure)
    need_cn = any(bnd is not None or not (isinstance(s, Plane) and m is not None) for s, bnd, _ in blocks)
    args = (c if need_cn else None, n if need_cn else None, f, tau, w_cov if w_cov.ndim == 3 else None, mu, e,
            finite, m)
    if alpha <= 0.5:
        keep = np.empty(min(N, SCREEN_CHUNK), bool)  # the rows whose margins are all >= 0 (single)
        rest, got = [], []
        for a in range(0, N, SCREEN_CHUNK):
            b = min(N, a + SCREEN_CHUNK)
            k = keep[:b - a]
            _screen(c, n, f, tau, blocks, mu, e, m, a, b, k, ok, f2)
            if finite is not None:
                k &= finite[a:b]
            if not k.all():  # the others' rows taken now, while the pass has them in cache
                rows = a + np.flatnonzero(~k)
                rest.append(rows)
                got.append([take(x, rows) for x in args])
        rest = np.concatenate(rest) if rest else np.empty(0, np.intp)
        got = [x if x is None or np.ndim(x) == 0 else np.concatenate([g[i] for g in got])
               for i, x in enumerate(args)] if got else []
    else:
        rest = np.arange(N)
        got = list(args)
    single = np.ones(N, bool)
    reason = np.zeros(N, np.int8)
    if zmin is not None:
        zmin.fill(np.nan)
    if len(rest):
        cr, nr, fr, taur, covr, mur, er, fin, mr = got
        if not need_cn:
            nr = _Rows(n, rest)
        single[rest], reason[rest], zr = _full_rows(rest, cr, nr, fr, taur, w_cov if covr is None else covr, blocks,
                                                    mur, er, alpha, fin, mr)
        if zmin is not None:
            zmin[rest] = zr
    return single, reason


class _Rows:
    """``x[rows[i]]`` for ``[i]``: rows of ``x`` taken only when asked (the normals of failing rows)."""

    def __init__(self, x, rows):
        self.x, self.rows = x, rows

    def __getitem__(self, i):
        return _Rows(self.x, self.rows[i]) if isinstance(i, slice) else self.x[self.rows[i]]


def _screen(c, n, f, tau, blocks, mu, e, m, a, b, out, ok=None, f2=None):
    """``out (b − a,)``: rows ``a:b`` whose pushing, friction and boundary margins are all ``≥ 0``
    (``ok``, ``f2``: the solve's pushing rows and ``|f|²``, for ``_face_plane_keep``)."""
    W = _work()
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        for surface, boundary, sl in blocks:
            lo, hi = max(sl.start, a), min(sl.stop, b)
            if hi <= lo:
                continue
            rows = slice(lo, hi)
            at = lambda x: x if np.ndim(x) == 0 else x[rows]  # noqa: E731
            o = out[lo - a:hi - a]
            k = _face_axis(surface) if f2 is not None and ok is not None and m is not None else None
            if k is None or not _face_plane_keep(W, k, f[rows], f2[rows], at(tau), at(mu), at(e), ok[rows], o):
                g1 = _friction_margin(W, surface, f[rows], m is not None, n[rows], at(tau), at(mu), at(e))
                if g1.min() >= 0 and g1.max() <= _BIG:  # the usual case: one pass each, no masks
                    o[:] = True
                else:
                    np.greater_equal(g1, 0.0, out=o)
                    o &= g1 <= _BIG
            if boundary is not None:
                o &= boundary.margin(c[rows]) >= 0.0


def _face_axis(surface):
    """``k`` if ``surface`` is a plane with normal ``±e_k`` (a face's), else None."""
    if not isinstance(surface, Plane):
        return None
    nz = np.flatnonzero(surface.normal)
    return int(nz[0]) if len(nz) == 1 and abs(surface.normal[nz[0]]) == 1.0 else None


#: the faces' planes' screen keeps a row only if its margin is this much (relative) on the safe side
_SAFE = 2.0**-40
#: ... and ``f_n²`` within these bounds (no underflow or overflow in the bound's arithmetic)
_TINY, _HUGE = 1e-280, 1e280


def _face_plane_keep(W, k, f, f2, tau, mu, e, ok, out):
    """Rows of a face's plane (normal ``±e_k``) whose friction margin the full test finds ``≥ 0``, from
    ``|f|²`` (the solve's): ``out``; False (``out`` unset) when the rows' scale is outside the bound's.

    The full test keeps a row if ``fl(μ f_n) ≥ fl(√s²)``, ``s² = |f_t|² + (τ/e)²``. Here
    ``a = (|f|² − f_n²) + (τ/e)²`` (``f_n² = f_k²``) and ``b = f_n² μ² (1 − δ)``, each within
    ``6u(|f|² + (τ/e)²)`` (``u = 2⁻⁵³``) of its exact value; ``a ≤ b`` gives
    ``s² ≤ μ² f_n² (1 − 6u)(1 − 12u)`` whenever ``δ ≥ 20u + 6u/μ²`` (``δ`` below is larger), so the
    full test's own roundings (``≤ 3u`` relative) keep its margin ``≥ 0``: a row kept here is kept
    there. Rows near the limit (within ``δ``) are left to the full test. Only the solve's ``ok``
    (pushing: ``f_n > 0``) rows are kept; a non-finite ``a`` or ``b`` keeps nothing.
    """
    r = len(f2)
    fk2, t, K = W("fn", r), W("t", r), W("s", r)
    np.multiply(f[:, k], f[:, k], out=fk2)
    mu_lo, mu_hi = (mu, mu) if np.ndim(mu) == 0 else (mu.min(), mu.max())
    if not (fk2.min() >= _TINY and fk2.max() <= _HUGE and mu_hi <= 1e10):  # b finite: a inf or NaN keeps nothing
        return False
    shrink = 1.0 - (_SAFE + 8.0 * 2.0**-53 / (mu_lo * mu_lo))
    if np.ndim(mu):
        np.multiply(mu, mu, out=K)
        K *= shrink
        K *= fk2
    else:
        np.multiply(fk2, mu * mu * shrink, out=K)  # b
    np.subtract(f2, fk2, out=fk2)
    np.divide(tau, e, out=t)
    t *= t
    fk2 += t  # a
    np.less_equal(fk2, K, out=out)
    if not ok.all():
        out &= ok
    return True


def _friction_margin(W, surface, f, with_m, n, tau, mu, e):
    """``μ f_n − s`` of rows ``f (r, 3)``, bit for bit as ``_soft_test``'s ``_plane_z``/``_curved_z``
    (``_dot3``'s order: ``(x0 y0 + x1 y1) + x2 y2``); its sign implies ``f_n``'s (``μ > 0``)."""
    r = len(f)
    fn, s, t = W("fn", r), W("s", r), W("t", r)
    if isinstance(surface, Plane) and with_m:  # _plane_z: the constant normal's components
        nv = surface.normal
        nz = [i for i in range(3) if nv[i] != 0.0]
        np.multiply(f[:, nz[0]], -nv[nz[0]], out=fn)
        for i in nz[1:]:
            np.multiply(f[:, i], nv[i], out=t)
            fn -= t
        if len(nz) == 1 and abs(nv[nz[0]]) == 1.0:  # a face's plane: f_t = f with that component 0
            i, j = (k for k in range(3) if k != nz[0])  # (0 + x) and (x + 0) are x: only two terms
            np.multiply(f[:, i], f[:, i], out=s)
            np.multiply(f[:, j], f[:, j], out=t)
            s += t  # (NaN, ±inf forces: a non-finite margin, never kept)
        else:
            ft = W("ft", r, 3)
            np.multiply(nv[:, None], fn, out=ft)
            ft += f.T
            _dot3(ft, ft, s, W("T3", r, 3))
    else:  # _curved_z: f_n = −(f · n)
        T3 = W("T3", r, 3)
        fT, nT = W("fT", r, 3), W("nT", r, 3)
        np.copyto(fT, f.T)
        np.copyto(nT, n.T)
        _dot3(fT, nT, fn, T3)
        np.negative(fn, out=fn)
        ft = W("ft", r, 3)
        np.multiply(nT, fn, out=ft)
        ft += fT
        _dot3(ft, ft, s, T3)
    np.divide(tau, e, out=t)
    t *= t
    s += t
    np.sqrt(s, out=s)
    np.multiply(fn, mu, out=fn)
    fn -= s
    return fn


def _sub_blocks(blocks, rows) -> list:
    """``blocks`` (slices of all rows) as slices of the rows ``rows`` (sorted) taken one after the other."""
    starts = np.searchsorted(rows, [sl.start for _, _, sl in blocks])
    stops = np.searchsorted(rows, [sl.stop for _, _, sl in blocks])
    return [(s, bnd, slice(int(i), int(j))) for (s, bnd, _), i, j in zip(blocks, starts, stops) if j > i]


def _full_rows(rows, cr, nr, fr, taur, cov, blocks, mur, er, alpha, fin, mr):
    """``single, reason, zmin`` of the rows ``rows`` (sorted) by the full test, deciding on ``min z`` against
    Φ⁻¹(α).

    The arguments are those rows' (``cr = c[rows]``, …; numbers and a shared ``cov`` as they are);
    ``blocks`` index all rows."""
    k = len(rows)
    sub = _sub_blocks(blocks, rows)
    single = np.empty(k, bool)
    reason = np.empty(k, np.int8)
    zmins = np.empty(k)
    from scipy.special import ndtri  # at the first test: pito-app's window never pays its import

    za = float(ndtri(alpha))
    band = _BAND * (1.0 + abs(za))
    for a in range(0, k, CHUNK):
        b = min(k, a + CHUNK)
        part = _chunk_blocks(sub, a, b)
        r = slice(a, b)
        ch = lambda x: x if x is None or np.ndim(x) == 0 else x[r]  # noqa: E731
        z0, z1, z2, fz = _z_rows(ch(cr), ch(nr), ch(fr), ch(taur), cov if cov.ndim == 2 else cov[r], part,
                                 ch(mur), ch(er), None, ch(mr), finite=ch(fin))
        zmin = zmins[r] = _zmin(z0, z1, z2, fz)
        s = zmin >= za + band
        near = np.flatnonzero(~s & ~(zmin < za - band))  # (NaN: never; _z leaves none)
        if len(near):
            s[near] = _ndtr(zmin[near]) >= alpha
        single[r] = s
        reason[r] = 0 if s.all() else _reasons(s, z0, z1, z2, fz, ch(fr), ch(nr), ch(taur), ch(er), alpha)
    return single, reason, zmins


def _p_of(zmin: np.ndarray) -> np.ndarray:
    """``p = Φ(min z)`` as the full test forms it (1 from ``_Z_ONE`` up; −inf, a row not finite: 0)."""
    p = np.ones(len(zmin))
    low = zmin < _Z_ONE
    p[low] = _ndtr(zmin[low])
    return p


def deferred_soft_p(blocks, c, n, tau, ws, w_cov, mu, torsion_radius, zmin) -> _Deferred:
    """``single_contact_p (N,)`` of rows :func:`soft_finger_flags` decided, computed on first read.

    ``zmin (N,)``: what ``soft_finger_flags`` filled (kept, not copied: the caller's to give).
    The rows tested in full take ``Φ(min z)`` from it; the others' (NaN) ``z`` are computed
    at read time by the full test's own steps from copies of those rows taken now: ``tau``,
    the wrench rows ``ws (N, 6)`` (forces: the solve's numbers; moments), and the points and
    normals only for the blocks that read them (curved, or with a boundary). The copies share
    one buffer from ``COPIES``, given back when the p-values are read or the field is gone.
    Other arguments as :func:`soft_finger_flags`.
    """
    N = len(ws)
    todo = np.flatnonzero(np.isnan(zmin))
    k = len(todo)
    need_cn = any(bnd is not None or not isinstance(s, Plane) for s, bnd, _ in blocks)
    buf = COPIES.take(k * (7 + (6 if need_cn else 0)))
    tau_c = np.take(tau, todo, out=buf[:k], mode="clip")
    ws_c = np.take(ws, todo, axis=0, out=buf[k:7 * k].reshape(k, 6), mode="clip")
    c_c = n_c = None
    if need_cn:
        c_c = np.take(c, todo, axis=0, out=buf[7 * k:10 * k].reshape(k, 3), mode="clip")
        n_c = np.take(n, todo, axis=0, out=buf[10 * k:13 * k].reshape(k, 3), mode="clip")
    cov = np.array(w_cov) if w_cov.ndim == 2 else w_cov[todo]
    mu_c, e_c = (x if np.ndim(x) == 0 else x[todo] for x in (mu, torsion_radius))
    sub = _sub_blocks(blocks, todo)

    def p():
        out = np.empty(N)
        known = ~np.isnan(zmin)
        out[known] = _p_of(zmin[known])
        for a in range(0, k, CHUNK):
            b = min(k, a + CHUNK)
            r = slice(a, b)
            ch = lambda x: x if x is None or np.ndim(x) == 0 else x[r]  # noqa: E731
            z0, z1, z2, _ = _z_rows(ch(c_c), ch(n_c), ws_c[r, :3], tau_c[r], cov if cov.ndim == 2 else cov[r],
                                    _chunk_blocks(sub, a, b), ch(mu_c), ch(e_c), None, ws_c[r, 3:], finite=None)
            out[todo[r]] = _p_of(_zmin(z0, z1, z2, None))
        done()  # the copies back to the pool
        return out

    deferred = _Deferred((N,), p)
    done = weakref.finalize(deferred, COPIES.give, buf)
    return deferred

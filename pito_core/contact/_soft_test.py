"""The soft-finger single-contact test in closed form over component arrays (the path ``solve`` takes).

The same test as :func:`~pito_core.contact._plausibility.single_contact_test` with
:func:`~pito_core.contact._plausibility.soft_finger_variance` (module docstring there), written
without tangent coordinates: every vector is three one-dimensional arrays (x, y, z), each
step a handful of ufunc calls over the solve's own arrays, no per-sample Python, no
``(N, 3, 3)`` products.

A limit ``g(c, f, τ)`` of the estimate (``c`` on the surface) has the wrench gradient
``u = (u_f, u_m)`` with ``σ_g² = uᵀ Σ u``. Writing ``f = f_t − f_n n`` (``f_n = −f · n``),
``S`` the shape operator (``δn = S δc``) and ``J = n ×`` (a quarter turn in the tangent
plane), ``δm − c × δf = δc × f + τ S δc + δτ n`` gives

* ``u_m = g_τ n + X⁻¹ (g_c + g_τ n × f_t)`` with ``X = τ S − f_n J`` on the tangent plane,
* ``u_f = g_f + c × u_m``,

and in two dimensions ``X⁻¹ r = (τ (H r − S r) + f_n n × r) / (τ² K + f_n²)`` (``H = tr S``,
``K = det S``: the mean and Gaussian curvatures' sums and products). A plane or a facet has
``S = 0`` (``X⁻¹ r = n × r / f_n``); a sphere ``S = I / r``; an ellipsoid ``(c − c0)ᵀ A
(c − c0) = 1`` with ``γ = |A (c − c0)|``: ``S r = (A r − n (n · A r)) / γ``,
``H = (tr A − n · A n) / γ`` and ``K = det A / γ⁴``. The limits:

* pushing, ``g = f_n``: ``g_c = −S f_t``, ``g_f = −n``, ``g_τ = 0``;
* friction, ``g = μ f_n − s``, ``s = √(|f_t|² + (τ/e)²)``: ``g_c = −(μ + f_n/s) S f_t``,
  ``g_f = −μ n − f_t / s``, ``g_τ = −τ / (e² s)`` (the ``s`` terms 0 where ``s = 0``);
* on the patch (a boundary): the signed distance's central difference along two tangents.

so with ``P = X⁻¹ S f_t`` and ``Q = n + X⁻¹ (n × f_t)`` the pushing limit has ``u_m = −P`` and the
friction limit ``u_m = −(μ + f_n/s) P + g_τ Q``.

``p = Φ(min z)`` (``Φ`` is monotone: the smallest p-value is that of the smallest margin),
evaluated only where ``min z < 8.3`` (above, ``Φ(z)`` is 1.0 in double precision); the
per-limit p-values are formed only for the rows that fail, to name the reason.
"""

from __future__ import annotations

import threading

import numpy as np

from ._plausibility import _BOUNDARY_STEP, _decide, _z
from ._plausibility import _ndtr as ndtr  # scipy.special's, imported at the first test
from ._surfaces import Ellipsoid, Plane, Sphere

__all__ = ["soft_finger_test"]

#: Φ(z) rounds to 1.0 in double precision for every z at or above this
_Z_ONE = 8.3


def _cross(a, b):
    """Cross product of vectors given as three component arrays each."""
    a0, a1, a2 = a
    b0, b1, b2 = b
    x = a1 * b2
    x -= a2 * b1
    y = a2 * b0
    y -= a0 * b2
    z = a0 * b1
    z -= a1 * b0
    return x, y, z


def _dot(a, b):
    out = a[0] * b[0]
    out += a[1] * b[1]
    out += a[2] * b[2]
    return out


#: Rows per pass: the temporaries of a pass are named buffers of this many rows, kept per thread
#: and reused (a fresh array per temporary costs its pages' faults, more than the arithmetic).
CHUNK = 8192

_local = threading.local()


class _Work:
    """Named float buffers of ``CHUNK`` rows (``(k, CHUNK)`` for ``k`` components), one set per thread."""

    def __init__(self):
        self._bufs = {}

    def __call__(self, name, rows, k=None):
        b = self._bufs.get((name, k))
        if b is None or b.shape[-1] < rows:
            b = self._bufs[(name, k)] = np.empty((max(rows, CHUNK),) if k is None else (k, max(rows, CHUNK)))
        return b[..., :rows]


def _work() -> _Work:
    w = getattr(_local, "work", None)
    if w is None:
        w = _local.work = _Work()
    return w


def soft_finger_test(c, n, f, tau, w_cov, blocks, mu, torsion_radius, alpha, ok=None, m=None, *, finite=False):
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
    ok : ndarray of bool, shape (N,), optional
        The solve's pushing rows with a finite point (their point and normal are finite;
        only the others are checked).
    m : ndarray, shape (N, 3), optional
        The measured moments (N·m) the estimates solve exactly: on a plane ``c × f = m − τ n``.
    finite : ndarray of bool, shape (N,), or None, optional
        The rows with a finite point and normal, already known (None: all; ``ok`` unused);
        then ``c`` and ``n`` may be None if every block is a plane without boundary (with ``m``).
    """
    N = len(f)
    if finite is False:
        finite = _finite_rows(c, n, ok)
    if N <= CHUNK:
        return _test_rows(c, n, f, tau, w_cov, blocks, mu, torsion_radius, alpha, finite, m)
    single, p, reason = np.empty(N, bool), np.empty(N), np.empty(N, np.int8)
    for a in range(0, N, CHUNK):
        b = min(N, a + CHUNK)
        sub = _chunk_blocks(blocks, a, b)
        rows = slice(a, b)
        at = lambda x: x if x is None or np.ndim(x) == 0 else x[rows]  # noqa: E731
        single[rows], p[rows], reason[rows] = _test_rows(
            at(c), at(n), f[rows], tau[rows], w_cov if w_cov.ndim == 2 else w_cov[rows], sub, at(mu),
            at(torsion_radius), alpha, at(finite), at(m))
    return single, p, reason


def _cross3(a, b, out, t):
    """``out = a × b`` for ``(3, r)`` arrays, ``t`` an ``(r,)`` scratch row."""
    for i, j, k in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):
        np.multiply(a[j], b[k], out=out[i])
        np.multiply(a[k], b[j], out=t)
        out[i] -= t


def _dot3(a, b, out, T):
    """``out = a · b`` column-wise for ``(3, r)`` arrays, ``T`` a ``(3, r)`` scratch."""
    np.multiply(a, b, out=T)
    np.add(T[0], T[1], out=out)
    out += T[2]
    return out


def _matvec(A, x, out, t):
    """``out = A x`` for a ``(3, 3)`` matrix and ``(3, r)`` columns (zero entries skipped; no BLAS)."""
    for i in range(3):
        first = True
        for j in range(3):
            if A[i, j] == 0.0:
                continue
            if first:
                np.multiply(x[j], A[i, j], out=out[i])
                first = False
            else:
                np.multiply(x[j], A[i, j], out=t)
                out[i] += t
        if first:
            out[i] = 0.0


def _quad6(U, S, out, W):
    """``out = uᵀ S u`` per column of ``U (6, r)`` (``[u_f, u_m]``); ``S (6, 6)`` or ``(r, 6, 6)`` (no BLAS:
    the same rounding whatever the batch, so grouped and single solves agree bitwise)."""
    if S.ndim == 3:
        return np.einsum("in,nij,jn->n", U, S, U, out=out)
    if not np.any(S - np.diag(np.diagonal(S))):
        U2 = W("U2", U.shape[1], 6)
        np.multiply(U, U, out=U2)
        return np.einsum("i,in->n", np.diagonal(S), U2, out=out)
    return np.einsum("in,ij,jn->n", U, S, U, out=out)


def _limits_z(W, fn, s, mu, U0, var0, U1, w_cov, z0, z1):
    """``z0 = f_n / σ_0`` and ``z1 = (μ f_n − s) / σ_1`` into ``z0``, ``z1`` (``var0`` given, or from ``U0``)."""
    r = len(fn)
    if var0 is None:
        var0 = _quad6(U0, w_cov, W("var0", r), W)
    var1 = _quad6(U1, w_cov, W("var1", r), W)
    g1 = W("g1", r)
    np.multiply(fn, mu, out=g1)
    g1 -= s
    sq = W("sq", r)
    if np.ndim(var0):
        np.sqrt(var0, out=sq)
        np.divide(fn, sq, out=z0)
    else:  # one variance for every row (a plane)
        np.multiply(fn, 1.0 / np.sqrt(var0), out=z0)
    np.sqrt(var1, out=sq)
    np.divide(g1, sq, out=z1)
    if np.isnan(z0.sum()):  # degenerate rows (rare): _z's rules on them (a row's z is its own)
        bad = np.isnan(z0)
        z0[bad] = _z(fn[bad], var0 if np.ndim(var0) == 0 else var0[bad])
    if np.isnan(z1.sum()):
        bad = np.isnan(z1)
        z1[bad] = _z(g1[bad], var1[bad])


def _shear(W, fn, ft, tau, e):
    """``s = √(|f_t|² + (τ/e)²)`` and ``1/s`` (0 where ``s = 0``) of ``f_t (3, r)``; returns ``s, inv_s, tq``."""
    r = len(fn)
    T3, t = W("T3", r, 3), W("t", r)
    s = _dot3(ft, ft, W("s", r), T3)
    tq = W("tq", r)
    np.divide(tau, e, out=tq)
    np.multiply(tq, tq, out=t)
    s += t
    np.sqrt(s, out=s)
    inv_s = W("inv_s", r)
    np.divide(1.0, s, out=inv_s)
    if not s.min() > 0:
        inv_s[~(s > 0)] = 0.0  # no shear and no twist: the √ has no gradient
    return s, inv_s, tq


def _plane_z(plane, W, f, m, c, tau, w_cov, mu, e, z0, z1, edge=None):
    """The pushing and friction limits' ``z`` on a plane (constant normal, ``S = 0``) into ``z0``, ``z1``.

    There ``X⁻¹ r = n × r / f_n``, ``P = 0``, ``Q = −f / f_n``, ``c × f = m − τ n``: the pushing
    limit's gradient is ``u = (−n, 0)`` (one variance for every row) and the friction
    limit's ``u_m = a f``, ``u_f = −(μ + f_n/s) n − f/s + a (m − τ n)`` with ``a = τ / (e² s f_n)``.
    ``edge``: ``(margin, gradient (3, r), z2)`` of a boundary (``c (3, r)`` given), or None.
    """
    r = f.shape[1]
    nv = plane.normal
    T3, t = W("T3", r, 3), W("t", r)
    fn = W("fn", r)
    nz = [i for i in range(3) if nv[i] != 0.0]  # a face frame's plane: one component
    np.multiply(f[nz[0]], -nv[nz[0]], out=fn)
    for i in nz[1:]:
        np.multiply(f[i], nv[i], out=t)
        fn -= t
    ft = W("ft", r, 3)
    np.multiply(nv[:, None], fn, out=ft)
    ft += f
    s, inv_s, tq = _shear(W, fn, ft, tau, e)
    a = W("a", r)
    np.multiply(tq, inv_s, out=a)
    a /= fn
    a /= e
    U = W("U", r, 6)
    uf, um = U[:3], U[3:]
    np.multiply(nv[:, None], tau, out=uf)
    np.subtract(m, uf, out=uf)
    uf *= a
    np.multiply(f, inv_s, out=T3)
    uf -= T3
    b = W("b", r)
    np.multiply(fn, inv_s, out=b)
    b += mu
    np.multiply(nv[:, None], b, out=T3)
    uf -= T3
    np.multiply(f, a, out=um)
    var0 = np.einsum("i,...ij,j->...", nv, w_cov[..., :3, :3], nv)
    _limits_z(W, fn, s, mu, None, var0, U, w_cov, z0, z1)
    if edge is not None:  # X⁻¹ g = n × g / f_n
        um = W("um2", r, 3)
        _cross3(np.broadcast_to(nv[:, None], (3, r)), edge[1], um, W("t", r))
        um /= fn
        _boundary_z(W, c, um, w_cov, edge[0], edge[2])


def _curved_z(surface, W, c, n, f, tau, w_cov, mu, e, z0, z1, edge=None):
    """The pushing and friction limits' ``z`` on any surface's rows into ``z0``, ``z1`` (module docstring).

    ``c, n, f``: ``(3, r)``. ``edge``: ``(margin, gradient (3, r), z2)`` of a boundary, or None.
    """
    r = f.shape[1]
    T3, t = W("T3", r, 3), W("t", r)
    fn = _dot3(f, n, W("fn", r), T3)
    np.negative(fn, out=fn)
    ft = W("ft", r, 3)
    np.multiply(n, fn, out=ft)
    ft += f
    s, inv_s, tq = _shear(W, fn, ft, tau, e)
    v = W("v", r, 3)
    _cross3(n, ft, v, t)  # n × f_t; n × (n × f_t) = −f_t
    Q = W("Q", r, 3)  # Q = n + X⁻¹ (n × f_t)
    P = None  # P = X⁻¹ S f_t
    den, al, be = W("den", r), W("al", r), W("be", r)
    if isinstance(surface, Sphere):  # S = I / R: X⁻¹ r = (τ/R r + f_n n × r) / ((τ/R)² + f_n²)
        k = 1.0 / surface.radius
        at = W("at", r)
        np.multiply(tau, k, out=at)
        np.multiply(at, at, out=den)
        np.multiply(fn, fn, out=t)
        den += t
        np.divide(at, den, out=al)
        np.divide(fn, den, out=be)
        np.multiply(v, al, out=Q)
        Q += n
        np.multiply(ft, be, out=T3)
        Q -= T3
        P = W("P", r, 3)
        np.multiply(ft, al, out=P)
        np.multiply(v, be, out=T3)
        P += T3
        P *= k
        if edge is not None:  # X⁻¹ g = (τ/R) g + f_n n × g) / det X
            um2 = W("um2", r, 3)
            _cross3(n, edge[1], um2, t)
            um2 *= be
            np.multiply(edge[1], al, out=T3)
            um2 += T3
            _boundary_z(W, c, um2, w_cov, edge[0], edge[2])
    elif isinstance(surface, Ellipsoid):
        A = surface._A
        Ap, ig, H = W("Ap", r, 3), W("ig", r), W("H", r)
        np.subtract(c, surface.center[:, None], out=T3)
        _matvec(A, T3, Ap, t)
        _dot3(Ap, Ap, ig, T3)
        np.sqrt(ig, out=ig)
        np.divide(1.0, ig, out=ig)  # 1/γ
        An = W("An", r, 3)
        _matvec(A, n, An, t)
        _dot3(n, An, H, T3)
        np.subtract(float(np.trace(A)), H, out=H)
        H *= ig  # tr S
        np.multiply(ig, ig, out=den)
        np.multiply(den, den, out=den)
        den *= float(np.linalg.det(A))
        np.multiply(tau, tau, out=t)
        den *= t
        np.multiply(fn, fn, out=t)
        den += t  # det X = τ² K + f_n²

        def shape(x, out):  # S x = (A x − n (n · A x)) / γ
            Ax = W("Ax", r, 3)
            _matvec(A, x, Ax, t)
            _dot3(n, Ax, be, T3)
            np.multiply(n, be, out=out)
            np.subtract(Ax, out, out=out)
            out *= ig

        def inv(x, nx, out):  # X⁻¹ x = (τ (H x − S x) + f_n n × x) / det X
            Sx = W("Sx", r, 3)
            shape(x, Sx)
            np.multiply(x, H, out=out)
            out -= Sx
            out *= tau
            np.multiply(nx, fn, out=Sx)
            out += Sx
            out /= den

        mft = W("mft", r, 3)
        np.negative(ft, out=mft)
        inv(v, mft, Q)  # n × v = −f_t
        Q += n
        h, nh = W("h", r, 3), W("nh", r, 3)
        shape(ft, h)
        _cross3(n, h, nh, t)
        P = W("P", r, 3)
        inv(h, nh, P)
        if edge is not None:
            um2, ng = W("um2", r, 3), W("ng", r, 3)
            _cross3(n, edge[1], ng, t)
            inv(edge[1], ng, um2)
            _boundary_z(W, c, um2, w_cov, edge[0], edge[2])
    else:  # a plane or a facet: X⁻¹ r = n × r / f_n, Q = −f / f_n
        np.divide(f, fn, out=Q)
        np.negative(Q, out=Q)
        if edge is not None:
            um2 = W("um2", r, 3)
            _cross3(n, edge[1], um2, t)
            um2 /= fn
            _boundary_z(W, c, um2, w_cov, edge[0], edge[2])
    # the friction limit: u_m = g_τ Q − (μ + f_n/s) P, u_f = c × u_m − μ n − f_t / s
    gt = W("gt", r)
    np.multiply(tq, inv_s, out=gt)
    gt /= -e
    U1 = W("U", r, 6)
    uf1, um1 = U1[:3], U1[3:]
    np.multiply(Q, gt, out=um1)
    if P is not None:
        np.multiply(fn, inv_s, out=al)
        al += mu
        np.multiply(P, al, out=T3)
        um1 -= T3
    _cross3(c, um1, uf1, t)
    np.multiply(n, mu, out=T3)
    uf1 -= T3
    np.multiply(ft, inv_s, out=T3)
    uf1 -= T3
    # the pushing limit: u = −(n + c × P, P)
    U0 = W("U0", r, 6)
    if P is not None:
        _cross3(c, P, U0[:3], t)
        U0[:3] += n
        U0[3:] = P
    else:
        U0[:3] = n
        U0[3:] = 0.0
    _limits_z(W, fn, s, mu, U0, None, U1, w_cov, z0, z1)


def _test_rows(c, n, f, tau, w_cov, blocks, mu, e, alpha, finite, m):
    """:func:`soft_finger_test` on at most ``CHUNK`` rows (``finite``: None, or the finite rows)."""
    z0, z1, z2, _ = _z_rows(c, n, f, tau, w_cov, blocks, mu, e, None, m, finite)
    zmin = _zmin(z0, z1, z2, finite)
    low = zmin < _Z_ONE
    if low.all():
        p = ndtr(zmin)
    else:
        p = np.ones(len(zmin))
        p[low] = ndtr(zmin[low])
    if finite is not None and not finite.all():
        p[~finite] = 0.0
    single = p >= alpha
    if single.all():
        return single, p, np.zeros(len(p), np.int8)
    return single, p, _reasons(single, z0, z1, z2, finite, f, n, tau, e, alpha)


def _zmin(z0, z1, z2, finite):
    """The smallest ``z`` of each row (−inf where the estimate is not finite)."""
    zmin = np.minimum(z0, z1)
    if z2 is not None:
        np.minimum(zmin, z2, out=zmin)
    if finite is not None and not finite.all():
        zmin[~finite] = -np.inf
    return zmin


def _finite_rows(c, n, ok):
    """Rows with a finite point and normal, or None for all (every row ``ok``: finite by the solve).

    Row by row: an ``ok`` row's point and normal are finite (the solve's rule), so the rows
    checked here are the others; the result is the same for any batch of the rows."""
    if ok is not None and ok.all():
        return None
    C = (c[:, 0], c[:, 1], c[:, 2])
    Nn = (n[:, 0], n[:, 1], n[:, 2])
    with np.errstate(invalid="ignore", over="ignore"):
        return np.isfinite(_dot(C, C) + _dot(Nn, Nn))


def _z_rows(c, n, f, tau, w_cov, blocks, mu, e, ok, m, finite=False):
    """The limits' ``z0`` (pushing), ``z1`` (friction), ``z2`` (boundary, None without one) of at most
    ``CHUNK`` rows, and ``finite`` (None: all); ``finite`` given (not False): ``ok`` unused."""
    N = len(f)
    if finite is False:
        finite = _finite_rows(c, n, ok)
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        # block by block (each row's figures depend on its own block only: grouped solves equal single ones)
        z0, z1, z2 = np.empty(N), np.empty(N), None
        W = _work()
        for surface, boundary, sl in blocks:
            r = sl.stop - sl.start
            if r == 0:
                continue
            at = lambda x, sl=sl: x if np.ndim(x) == 0 else x[sl]  # noqa: E731
            fT = W("f", r, 3)
            np.copyto(fT, f[sl].T)
            tb, mub, eb = at(tau), at(mu), at(e)
            cov = w_cov if w_cov.ndim == 2 else w_cov[sl]
            edge = None
            if boundary is not None:
                if z2 is None:
                    z2 = np.full(N, np.inf)
                edge = (*_boundary_grad(boundary, c[sl], n[sl]), z2[sl])
            if isinstance(surface, Plane) and m is not None:
                mT = W("m", r, 3)
                np.copyto(mT, m[sl].T)
                cT = None
                if edge is not None:
                    cT = W("c", r, 3)
                    np.copyto(cT, c[sl].T)
                _plane_z(surface, W, fT, mT, cT, tb, cov, mub, eb, z0[sl], z1[sl], edge)
            else:
                cT, nT = W("c", r, 3), W("n", r, 3)
                np.copyto(cT, c[sl].T)
                np.copyto(nT, n[sl].T)
                _curved_z(surface, W, cT, nT, fT, tb, cov, mub, eb, z0[sl], z1[sl], edge)
    return z0, z1, z2, finite


def _reasons(single, z0, z1, z2, finite, f, n, tau, e, alpha):
    """``reason (N,) int8``: the failing limit of the rows not ``single`` (the general test's rule, _decide)."""
    N = len(single)
    bad = np.flatnonzero(~single)
    zb = np.zeros((len(bad), 4))
    zb[:, 0], zb[:, 1] = z0[bad], z1[bad]
    zb[:, 2] = np.inf if z2 is None else z2[bad]
    fin = np.ones(len(bad), bool) if finite is None else finite[bad]
    zb[~fin, :3] = np.inf
    p_all = np.ones((len(bad), 4))
    lo = zb[:, :3] < _Z_ONE
    p_all[:, :3][lo] = ndtr(zb[:, :3][lo])
    p_all[~fin] = 0.0
    fb, nb = f[bad], n[bad]
    with np.errstate(invalid="ignore", divide="ignore"):
        ftb = fb - np.einsum("ij,ij->i", fb, nb)[:, None] * nb
        eb = e if np.ndim(e) == 0 else e[bad]
        shear = np.sqrt(np.einsum("ij,ij->i", ftb, ftb)) >= np.abs(tau[bad] / eb)
    _, _, reason_bad = _decide(p_all, zb, fin, shear[fin], alpha, False)
    reason = np.zeros(N, np.int8)
    reason[bad] = reason_bad
    return reason


def _tangents(n):
    """Two unit tangents of unit normals ``n`` (component arrays; tangent_basis's rule)."""
    use_x = np.abs(n[0]) < 0.9
    t1 = [np.where(use_x, 0.0, -n[2]), np.where(use_x, n[2], 0.0), np.where(use_x, -n[1], n[0])]
    norm = np.sqrt(_dot(t1, t1))
    t1 = [x / norm for x in t1]
    return t1, list(_cross(n, t1))


def _boundary_grad(boundary, c, n):
    """The boundary margin ``(r,)`` m (> 0 inside) at ``c (r, 3)`` and its tangent gradient ``(3, r)``
    (central difference along two tangents of the unit normals ``n (r, 3)``)."""
    h = _BOUNDARY_STEP
    k = len(c)
    t1, t2 = _tangents((n[:, 0], n[:, 1], n[:, 2]))
    T1, T2 = np.stack(t1, axis=1), np.stack(t2, axis=1)
    pts = np.empty((5, k, 3))
    pts[0] = c
    pts[1] = c + h * T1
    pts[2] = c + h * T2
    pts[3] = c - h * T1
    pts[4] = c - h * T2
    m = boundary.margin(pts.reshape(-1, 3)).reshape(5, k)
    d1 = (m[1] - m[3]) / (2 * h)
    d2 = (m[2] - m[4]) / (2 * h)
    return m[0], np.array([d1 * t1[i] + d2 * t2[i] for i in range(3)])


def _boundary_z(W, c, um, w_cov, margin, z2):
    """``z2`` of the boundary margin from ``u_m = X⁻¹ g_c`` in ``um (3, r)`` (``u_f = c × u_m``)."""
    r = um.shape[1]
    U = W("U2b", r, 6)
    U[3:] = um
    _cross3(c, um, U[:3], W("t", r))
    z2[:] = _z(margin, _quad6(U, w_cov, W("var2", r), W))


def _chunk_blocks(blocks, a: int, b: int) -> list:
    """``blocks`` (``(surface, boundary, slice)``) cut to rows ``a:b``, their slices relative to ``a``."""
    return [(s, bnd, slice(max(sl.start, a) - a, min(sl.stop, b) - a)) for s, bnd, sl in blocks
            if min(sl.stop, b) > max(sl.start, a)]

"""Single-contact plausibility: can one soft finger on this patch give the measured wrench?

Two fingers on one patch give one resultant wrench, and the solver turns any wrench into
one contact. This module tests, per estimate, whether a single soft-finger contact on the
patch can produce the measured wrench within its noise. The single-contact model is

* the finger pushes: ``f_n = −f · n > 0``;
* friction holds (elliptic limit surface of a soft fingertip, Howe & Cutkosky 1996):
  ``√(|f_t|² + (τ / e)²) ≤ μ f_n``, with ``μ`` the fingertip–patch friction coefficient and
  ``e`` the effective torsional radius (``|τ| ≤ μ e f_n`` for a pure twist; a Hertzian
  fingertip of contact radius ``a`` gives ``e = 3πa/16``). With ``point_contact``
  (``τ = 0``) it is the Coulomb cone ``|f_t| ≤ μ f_n``;
* the point lies on the patch (inside its boundary; signed distance in m);
* point contact only: the six equations agree with five parameters — the weighted
  residual ``r² = eᵀ Σ⁻¹ e`` is χ² with one degree of freedom.

Each limit ``g(θ) ≥ 0`` is tested at the estimate ``θ̂`` with its Cramér–Rao covariance
``C`` (the calibration's wrench covariance through the solver's Jacobian): ``z = g(θ̂) / σ_g``,
``σ_g² = ∇gᵀ C ∇g``, and its p-value is ``Φ(z)`` — the probability of a margin this low or
lower if the true contact sat exactly on the limit (the least favourable single contact).
The residual's p-value is ``P(χ²₁ ≥ r²)``. ``single_contact_p`` is the smallest of these
p-values (with ``point_contact``, twice the smallest, capped at 1: Bonferroni over the two
families of tests, limits and residual, keeps the false alarms of the residual — exactly
χ²₁ — within ``alpha``), ``single_contact_reason`` names the limit that gives it, and
``single_contact = single_contact_p ≥ alpha`` (default ``SINGLE_CONTACT_ALPHA = 0.05``: a
single contact exactly on one limit is flagged 5 % of the time, one inside its limits far
less often). See ``docs/contact.md``.
"""

from __future__ import annotations

from enum import IntEnum

import numpy as np

from ._quadric import _cross


def _ndtr(x):
    """``scipy.special.ndtr`` (the standard normal CDF), imported at its first call: scipy.special takes
    0.2 CPU s to import, which a process that loads patches but tests no contact never pays
    (pito-app's window: docs/app.md, "Start-up")."""
    from scipy.special import ndtr

    return ndtr(x)


#: row indices (1, 2, 0) and (2, 0, 1): the adjugate's rows are cyclic cross products
_NEXT3, _PREV3 = np.array([1, 2, 0]), np.array([2, 0, 1])

__all__ = [
    "DEFAULT_FRICTION",
    "DEFAULT_TORSION_RADIUS",
    "SINGLE_CONTACT_ALPHA",
    "SingleContactReason",
    "SingleContactTest",
    "reason_names",
    "single_contact_test",
    "soft_finger_variance",
    "param_variance",
]

#: Fingertip–patch friction coefficient μ when the patch file gives none (dimensionless). Dry
#: skin on plastic or metal is 0.4–1.0, moist skin reaches 1.5; a patch file sets its own
#: (``"friction": {"mu": ...}``). A μ set too low flags true single touches.
DEFAULT_FRICTION = 1.0

#: Effective torsional radius ``e`` of a fingertip (m): the largest torsion is ``μ e f_n``. A
#: Hertzian contact of radius ``a`` gives ``e = 3πa/16``; a human index fingertip pressing
#: 1–10 N has ``a ≈ 6–10 mm``, so ``e ≈ 4–6 mm``. Patch files set it with
#: ``"friction": {"torsion_radius": ...}``.
DEFAULT_TORSION_RADIUS = 0.005

#: Significance level of the single-contact test: ``single_contact = single_contact_p >= alpha``.
SINGLE_CONTACT_ALPHA = 0.05

#: Finite-difference step (m) for the boundary margin's gradient along the surface.
_BOUNDARY_STEP = 1e-6


class SingleContactReason(IntEnum):
    """Why an estimate is not a plausible single contact (``single_contact_reason`` codes).

    ``NONE`` (0): plausible. ``NO_FORCE`` (1): force below the threshold (or NaN), nothing to
    judge. ``NO_SOLUTION`` (2): no point of the surface explains the wrench (a mesh whose
    facets all miss). ``OUTSIDE`` (3): the point is off the patch. ``PULLING`` (4): the force
    pulls. ``FRICTION`` (5): the tangential force exceeds the friction limit. ``TORSION`` (6):
    the torsion exceeds what a fingertip's friction gives. ``RESIDUAL`` (7): point contact
    only, the six wrench equations disagree beyond the noise (χ² test).
    """

    NONE = 0
    NO_FORCE = 1
    NO_SOLUTION = 2
    OUTSIDE = 3
    PULLING = 4
    FRICTION = 5
    TORSION = 6
    RESIDUAL = 7


def reason_names(codes) -> np.ndarray:
    """Short lower-case names (``""``, ``"no_force"``, ``"friction"``, ...) of reason codes, same shape."""
    names = np.array(["" if r == 0 else r.name.lower() for r in SingleContactReason], dtype=object)
    return names[np.asarray(codes, dtype=np.intp)]


class SingleContactTest:
    """Result of :func:`single_contact_test` for ``N`` estimates.

    Attributes
    ----------
    single : ndarray, shape (N,), bool
        One soft-finger contact on the patch can produce the wrench (``p >= alpha``).
    p : ndarray, shape (N,)
        Smallest per-limit p-value in [0, 1] (NaN where no force).
    reason : ndarray, shape (N,), int8
        :class:`SingleContactReason` of the failing limit (``NONE`` where plausible).
    z : ndarray, shape (N, 4)
        Margins in standard deviations for ``[pushing, friction, boundary, residual]``
        (the residual column holds ``r`` = √χ², 0 for the soft finger).
    """

    def __init__(self, single, p, reason, z):
        self.single, self.p, self.reason, self.z = single, p, reason, z


def _friction_margin(f, n, D, tau, mu, e, point_contact):
    """Pushing and friction margins, their gradients over θ, and the shear share.

    Margins ``(2, N)``: ``[f_n, g]`` with ``f_n = −f · n`` and ``g = μ f_n − √(|f_t|² + (τ/e)²)``
    (N); gradients ``(2, N, k)``, columns ``[θ1, θ2, fx, fy, fz(, τ)]``; shear ``(N,)``: the
    tangential force's share ``|f_t| ≥ |τ/e|``. ``D (N, 3, 2)``: ``∂n/∂θ``; ``mu``, ``e``: numbers
    or ``(N,)``. One array each, so that a single variance call serves both limits.
    """
    N = len(f)
    k = 5 if point_contact else 6
    fn = -np.einsum("ij,ij->i", f, n)
    ft_vec = f + fn[:, None] * n
    ft = np.sqrt((ft_vec * ft_vec).sum(axis=1))  # |f_t|
    tq = np.zeros(N) if point_contact else tau / e
    s = np.hypot(ft, tq)
    fu = np.zeros((N, 2, 3))  # rows f and u = f_t / |f_t| (0 without shear)
    fu[:, 0] = f
    np.divide(ft_vec, ft[:, None], out=fu[:, 1], where=ft[:, None] > 0)
    grad = np.zeros((2, N, k))  # [∇f_n, ∇g]
    with np.errstate(invalid="ignore", divide="ignore"):
        fD = np.einsum("nka,naj->nkj", fu, D)  # (N, 2, 2): f ∂n/∂θ and u ∂n/∂θ
        np.negative(fD[:, 0], out=grad[0, :, :2])
        np.negative(n, out=grad[0, :, 2:5])
        g_s = grad[1]  # ∇√(|f_t|² + (τ/e)²), built in place: ft ∇|f_t| / s (+ τ/(e s) on the τ column)
        np.multiply(fn[:, None], fD[:, 1], out=g_s[:, :2])
        g_s[:, 2:5] = fu[:, 1]
        g_s *= ft[:, None]
        g_s /= s[:, None]
        if not point_contact:
            g_s[:, 5] += tq / (e * s)
    g_s[~(s > 0)] = 0.0
    np.subtract((mu if np.ndim(mu) == 0 else mu[:, None]) * grad[0], g_s, out=grad[1])
    g = np.empty((2, N))
    g[0] = fn
    np.subtract(mu * fn, s, out=g[1])
    return g, grad, ft >= np.abs(tq)


def _boundary_margin(boundary, c, T):
    """Signed distance (m, > 0 inside) of ``c`` to the patch edge and its gradient over θ ``(N, 2)``.

    The gradient is a central difference along the two tangents, all five points in one
    ``margin`` call.
    """
    h = _BOUNDARY_STEP
    N = len(c)
    steps = (h * T).transpose(2, 0, 1)  # (2, N, 3): h t1, h t2
    m = boundary.margin(np.concatenate([c[None], c + steps, c - steps]).reshape(-1, 3)).reshape(5, N)
    return m[0], ((m[1:3] - m[3:5]) / (2 * h)).T


def param_variance(C):
    """``grad (..., n, k) -> (..., n)``: ``gradᵀ C grad`` for parameter covariances ``C (n, k, k)``."""
    def var(grad, rows):
        k = grad.shape[-1]
        return np.einsum("...ni,nij,...nj->...n", grad, C[rows][:, :k, :k], grad)
    return var


def soft_finger_variance(J, c, S):
    """``grad (..., n, 6) -> (..., n)``: variance of a function of the soft-finger estimate, without inverses.

    The estimate solves ``w = model(θ)`` exactly, so a function ``g(θ̂)`` has the wrench
    gradient ``u = J⁻ᵀ ∇g`` and variance ``uᵀ Σ u``. With ``J = [[0, I, 0], [A, [c]×, n]]``
    (columns ``θ1, θ2, f, τ``), ``Jᵀ u = ∇g`` splits into ``M u_m = (∇g_θ1, ∇g_θ2, ∇g_τ)``,
    ``M`` the 3 × 3 matrix of rows ``A1, A2, n``, and ``u_f = ∇g_f + c × u_m``; ``M`` is
    inverted by its adjugate (vectorised, no per-sample LAPACK call). Leading axes of
    ``grad`` (several functions of the same ``n`` estimates) broadcast.
    """
    R = np.empty((len(J), 3, 3))  # rows r1, r2, r3 = A1, A2, n
    R[:, :2] = np.swapaxes(J[:, 3:, :2], 1, 2)
    R[:, 2] = J[:, 3:, 5]
    adj = _cross(R.take(_NEXT3, axis=1), R.take(_PREV3, axis=1))  # rows r2 × r3, r3 × r1, r1 × r2: columns of M⁻¹·det
    det = np.einsum("ij,ij->i", J[:, 3:, 0], adj[:, 0])  # r1 · (r2 × r3)

    def var(grad, rows):
        with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
            k = grad.shape[-1]
            b = np.empty(grad.shape[:-1] + (3,))
            b[..., :2] = grad[..., :2]
            b[..., 2] = grad[..., 5] if k == 6 else 0.0
            um = np.einsum("...nk,nkj->...nj", b, adj[rows])
            um /= det[rows][:, None]
            u = np.empty(grad.shape[:-1] + (6,))
            u[..., 3:] = um
            u[..., :3] = (grad[..., 2:5] if k >= 5 else 0.0) + _cross(c[rows], um)
            if S.ndim == 2:
                return ((u.reshape(-1, 6) @ S) * u.reshape(-1, 6)).sum(axis=1).reshape(u.shape[:-1])
            return np.einsum("...ni,nij,...nj->...n", u, S[rows], u)
    return var


def _z(g, var):
    """``g / σ_g``; ±inf for a zero σ, 0 for an unbounded one (a degenerate estimate), −inf where NaN."""
    with np.errstate(invalid="ignore", divide="ignore"):
        z = g / np.sqrt(np.maximum(var, 0.0))
    nan = np.isnan(z)
    if nan.any():  # degenerate rows only (rare): sort them out
        z = np.where(nan & np.isfinite(g), np.where(g >= 0, np.inf, -np.inf), z)
        z = np.where(np.isnan(z) & ~np.isnan(var), 0.0, z)
        z[np.isnan(z)] = -np.inf  # e.g. behind a central projection's apex
    return z


#: reason codes of the four limits, columns of ``p_all``
_LIMIT_CODES = np.array([SingleContactReason.PULLING, SingleContactReason.FRICTION,
                         SingleContactReason.OUTSIDE, SingleContactReason.RESIDUAL], dtype=np.int8)


def _decide(p_all, z, finite, shear, alpha, point_contact):
    """``single, p, reason`` from the per-limit p-values ``p_all (N, 4)`` (see the module docstring).

    ``shear``: the friction limit's shear share on the ``finite`` rows (None if none).
    """
    worst = np.argmin(p_all, axis=1)
    p = p_all.min(axis=1)  # = p_all[row, worst]
    if point_contact:  # two families (the limits, the residual): Bonferroni keeps false alarms ≤ alpha
        p = np.minimum(1.0, 2.0 * p)
    single = p >= alpha
    if single.all():  # every estimate plausible (the usual case): nothing to name
        return single, p, np.zeros(len(p), np.int8)
    reason = _LIMIT_CODES[worst]
    all_finite = finite.all()
    if shear is not None:  # the friction limit fails mostly by twist: name it torsion
        if all_finite:
            torsion_worst = ~shear
        else:
            torsion_worst = finite.copy()
            torsion_worst[finite] = ~shear
        reason[(worst == 1) & torsion_worst] = SingleContactReason.TORSION
    # pushing is the first thing a friction limit needs: a pulling force is named as such
    # (p_all[:, 0] is Φ(z[:, 0]) on the finite rows)
    pulling = finite & (z[:, 0] < 0) & ~single
    reason[pulling & (p_all[:, 0] < alpha)] = SingleContactReason.PULLING
    if not all_finite:
        reason[~finite] = SingleContactReason.NO_SOLUTION
    reason[single] = SingleContactReason.NONE
    return single, p, reason


def single_contact_test(c, n, f, tau, w, variance, T, shape_op, W=None, *,
                        boundary=None, mu=DEFAULT_FRICTION, torsion_radius=DEFAULT_TORSION_RADIUS,
                        alpha=SINGLE_CONTACT_ALPHA, point_contact=False) -> SingleContactTest:
    """Single-contact test of ``N`` solved contacts (rows with a force above threshold).

    Parameters
    ----------
    c, n, f : ndarray, shape (N, 3)
        Estimated point (m), outward normal, force (N); NaN rows: no solution on the surface.
    tau : ndarray, shape (N,)
        Estimated torsion, N·m (0 for point contact).
    w : ndarray, shape (N, 6)
        Measured wrenches ``[fx, fy, fz, tx, ty, tz]``, N and N·m.
    variance : callable
        ``(grad (..., n, k), rows) -> (..., n)``: the variance of a function of the estimate
        with gradient ``grad`` over ``[θ1, θ2, fx, fy, fz(, τ)]`` at ``rows``, leading axes
        broadcast (:func:`soft_finger_variance`, :func:`param_variance`).
    T : ndarray, shape (N, 3, 2)
        Tangent basis of the coordinates ``θ``.
    shape_op : ndarray, shape (N, 3, 3)
        Shape operator at ``c`` (1/m).
    W : ndarray, shape (6, 6) or (N, 6, 6), optional
        Inverse wrench covariance (point contact's χ² residual).
    boundary : PatchBoundary, or list of (PatchBoundary or None, slice), optional
        The patch's boundary, or (rows of several patches side by side) each block's.
    mu, torsion_radius : float or ndarray, shape (N,)
        Friction coefficient, effective torsional radius (m): one, or per estimate.
    alpha : float
        Significance level.
    point_contact : bool

    Returns
    -------
    SingleContactTest
    """
    # deferred: scipy.special takes 0.2 CPU s to import; a process that loads patches without testing
    # contacts (pito-app's window: docs/app.md, "Start-up") never pays it
    from scipy.special import chdtrc, ndtr

    N = len(c)
    finite = np.isfinite(c).all(axis=1) & np.isfinite(T).all(axis=(1, 2))
    nf = np.count_nonzero(finite)
    z = np.full((N, 4), np.inf)
    z[:, 3] = 0.0
    p_all = np.ones((N, 4))
    shear = None
    if nf:
        i = slice(None) if nf == N else np.flatnonzero(finite)  # a slice: views, no copies
        Ti = T[i]
        D = shape_op[i] @ Ti
        mu_i, e_i = (x if np.ndim(x) == 0 else x[i] for x in (mu, torsion_radius))
        g, grad, shear = _friction_margin(f[i], n[i], D, tau[i], mu_i, e_i, point_contact)
        zi = np.empty((nf, 3))
        zi[:, :2] = _z(g, variance(grad, i)).T  # pushing and friction: one variance call
        zi[:, 2] = np.inf
        for b, rows in boundary if isinstance(boundary, list) else [(boundary, slice(0, N))]:
            if b is None:
                continue
            at = rows if nf == N else np.flatnonzero((i >= rows.start) & (i < rows.stop))  # rows among the finite
            rows = rows if nf == N else i[at]
            if len(c[rows]) == 0:
                continue
            gb, grad_b = _boundary_margin(b, c[rows], T[rows])
            zi[at, 2] = _z(gb, variance(grad_b, rows))
        z[i, :3] = zi
        p_all[i, :3] = ndtr(zi)
        if point_contact and W is not None:
            e = w[i].copy()
            e[:, :3] -= f[i]
            e[:, 3:] -= _cross(c[i], f[i])
            r2 = ((e @ W) * e).sum(axis=1) if W.ndim == 2 else np.einsum("ni,nij,nj->n", e, W[i], e)
            z[i, 3] = np.sqrt(np.maximum(r2, 0.0))
            p_all[i, 3] = chdtrc(1, r2)
    if nf < N:
        p_all[~finite] = 0.0
    single, p, reason = _decide(p_all, z, finite, shear, alpha, point_contact)
    return SingleContactTest(single, p, reason, z)

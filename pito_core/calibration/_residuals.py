"""The error model behind a calibration's covariance: passes 3 and 4 over the training data.

Pass 3 computes every usable training sample's residual with the fitted matrix and
accumulates (a) each output's squared residual against ``load_features`` (the variance a
new sample brings itself), (b) the residuals' correlation between a face's six axes, and
(c) the scores ``Aᵀ E`` of clusters of consecutive samples (the cluster-robust inflation of
the coefficients' variance). Pass 4 scales each output's variance so that ±1.96 σ holds
95 % of its loaded training samples' residuals, and at rest 95 % of the residuals at rest (the
errors are not Gaussian). See docs/calibration.md,
"Uncertainty".
"""

from __future__ import annotations

import numpy as np
import scipy.linalg
import scipy.optimize

from ..io import SessionBlock
from ._reference_noise import ReferenceLeverage, is_range
from ._targets import block_targets
from ._uncertainty import FULL_SCALE, N_FEATURES, own_load, q_features

__all__ = ["fit_error_model", "own_q", "N_CLUSTERS"]

#: Clusters of consecutive samples for the cluster-robust variance of the coefficients:
#: few and long, so that errors correlated over a loading gesture stay within one.
N_CLUSTERS = 16
#: The error model reads about this many samples (every n-th of each block beyond it, so 1–2×
#: this many): its figures are averages over the data, which a uniform subsample estimates
#: closely. Not fewer: where errors hold together over a gesture, a sparser subsample covers less
#: (``pito_core.sim``'s cube, ``total``, sessions of 19,098 samples: mean coverage 91.4 % read whole,
#: 90.0 % every 2nd, 89.4 % every 3rd), though 8,000 would take 3 ms off a fit of 10⁵ samples.
ERROR_MODEL_SAMPLES = 10_000
#: Bins of |residual| / σ for the coverage calibration of the error model (pass 4): width, count.
_Z_WIDTH, _Z_N = 0.005, 4000
#: Pass 4 reads the loaded samples alone where their weights (each a share of information on the
#: error, 1 without reference noise) add up to this many samples (20 beyond the 95 % point) and
#: to :data:`_MIN_SHARE` of their number: where the reference's noise ``v`` swamps most of them,
#: each one's need moves by ``v``'s own error (±8 % from 300 samples) times ``v / var``.
_MIN_INFORMED = 400
_MIN_SHARE = 0.5
#: A corrected face of a joint fit keeps its own model (scaled as its crosstalk's) where its own samples'
#: weights add up to this many, short of :data:`_MIN_INFORMED` (see :func:`fit_error_model`).
_MIN_OWN_WEIGHT = 20.0
#: Where the reference's noise swamps a face's own error, its own model is the mean excess this many
#: standard errors above (:func:`_own_bound`).
_BOUND_Z = 3.0
#: Pass 4 scales the variance at rest by the samples at rest alone where they weigh this many
#: (10 beyond the 95 % point); else by the loaded samples' scale.
_MIN_REST = 200
#: Reweighting steps of the error model against the reference's noise (each: weights from the last fit).
_REWEIGHT = 3
#: A term of the excess variance is kept only above this many standard errors of what the
#: uncertainty of the reference's noise (measured at rest) can put into it.
_SIGNIFICANT = 3.0


def _reference_variance(mount, ref_cov, output_frame, carries, idx) -> np.ndarray:
    """``(n, F, 6)`` variance the reference's own noise puts into each target (0 where a face carries nothing)."""
    if ref_cov is None:
        return np.zeros((carries.shape[0], len(idx), 6))
    if output_frame == "face":
        V = np.einsum("fij,jk,fik->fi", mount.X_face_ati, ref_cov, mount.X_face_ati)  # (6, 6)
    else:
        V = np.broadcast_to(np.diag(ref_cov), (6, 6))
    return carries[:, idx, None] * V[idx][None]


def _reference_cov(mount, ref_cov, output_frame, idx) -> np.ndarray:
    """``(F, 6, 6)`` covariance the reference's own noise puts into each output face's target when it carries."""
    if ref_cov is None:
        return np.zeros((len(idx), 6, 6))
    if output_frame == "face":
        return np.einsum("fij,jk,flk->fil", mount.X_face_ati[idx], ref_cov, mount.X_face_ati[idx])
    return np.broadcast_to(ref_cov, (len(idx), 6, 6)).copy()


def nnls_rows(PtP, Pte2):
    """Per output ``a``, non-negative ``c`` minimising ``‖Φ c − e2‖²`` from ``PtP (..., 5, 5)`` and ``Pte2 (..., 5)``."""
    c = np.zeros(Pte2.size)
    on = np.diag(PtP) > 0  # a feature 0 on every sample has coefficient 0 (its scale would divide by 10⁻³⁰⁰)
    if not on.any():
        return c
    PtP, Pte2 = PtP[np.ix_(on, on)], Pte2[on]
    scale = np.sqrt(np.diag(PtP))
    G = PtP / np.outer(scale, scale)
    w, V = np.linalg.eigh(G)
    keep = w > 1e-10 * w[-1]
    if w[-1] <= 0 or not keep.any():
        return c
    R = (V[:, keep] * np.sqrt(w[keep])).T  # G = Rᵀ R
    rhs = (V[:, keep].T @ (Pte2 / scale)) / np.sqrt(w[keep])
    c[on] = scipy.optimize.nnls(R, rhs)[0] / scale
    return c


def _significant_nnls(PtWP, PtWe, PtWv, rel_var) -> np.ndarray:
    """Weighted least squares of the excess variance on the features, non-negative, keeping a
    feature only where the reference's noise cannot explain it.

    ``E² − v`` subtracts the reference's variance ``v``, known only to ``rel_var`` (relative
    variance, ``2/(n − 1)`` from ``n`` samples at rest): an error of ``v`` shifts every row it
    enters and fits as a load-dependent term. A coefficient is kept only above ``_SIGNIFICANT``
    standard errors of that (``PtWP⁻¹ PtWv`` per session), dropped one at a time, the weakest
    first (``q`` and ``q²`` are collinear: they share an excess neither shows alone, and dropping
    every weak term at once dropped both). Without reference noise: the plain fit.
    (The rows' own scatter is not counted: pruning real terms on it left intervals too short
    on nonlinear cubes.) Rows with a polynomial correction are not pruned at all
    (:func:`_corrected_rows`, :func:`_significant_rows`' ``unpruned``).
    """
    active = np.ones(PtWe.size, dtype=bool)
    c = np.zeros(PtWe.size)
    if not (np.all(np.isfinite(PtWP)) and np.all(np.isfinite(PtWe))):
        return c
    if not np.any(PtWv):  # no reference noise in these rows: nothing was subtracted, keep the fit
        return nnls_rows(PtWP, PtWe)
    while active.any():
        ix = np.ix_(active, active)
        c = np.zeros(PtWe.size)
        c[active] = nnls_rows(PtWP[ix], PtWe[active])
        active &= c > 0  # the standard errors of the features in use (collinear unused ones would swell them)
        if not active.any():
            break
        ix = np.ix_(active, active)
        sc = np.sqrt(np.clip(np.diag(PtWP)[active], 1e-300, None))  # the pinv of the scaled matrix
        Pinv = np.linalg.pinv(PtWP[ix] / np.outer(sc, sc), hermitian=True)
        var = np.zeros(int(active.sum()))
        for j, rv in enumerate(rel_var):
            var = var + rv * (Pinv @ (PtWv[j][active] / sc)) ** 2
        z = np.full(active.size, np.inf)
        with np.errstate(over="ignore"):  # a term the reference's noise cannot move: z is inf, kept
            z[active] = c[active] * sc / np.maximum(np.sqrt(var), 1e-300)
        if z.min() >= _SIGNIFICANT:
            break
        active[np.argmin(z)] = False  # the weakest alone: collinear features share what one would show
        c = np.zeros(PtWe.size)
    return c


#: Every support of the five features (rows of booleans), for the NNLS by enumeration.
_SUPPORTS = ((np.arange(2**N_FEATURES)[:, None] >> np.arange(N_FEATURES)) & 1).astype(bool)
#: Scaled normal matrices better conditioned than this are solved in a batch (the others one by one).
_BATCH_COND = 1e8


def _masked(G, m) -> np.ndarray:
    """``G (..., 5, 5)`` on the features ``m (..., 5)``, identity elsewhere (the sub-problem, padded)."""
    mm = m[..., :, None] & m[..., None, :]
    return np.where(mm, G, np.eye(N_FEATURES))


def _nnls_batch(Gs, bs, active) -> np.ndarray:
    """Per row, the non-negative ``c`` on ``active (R, 5)`` minimising ``½ cᵀ Gs c − bsᵀ c`` (scaled,
    positive definite ``Gs (R, 5, 5)``): the best of the 32 supports' unconstrained solutions
    that are not negative (the minimum of a strictly convex problem is one of them)."""
    m = _SUPPORTS[None] & active[:, None]  # (R, 32, 5)
    c = np.linalg.solve(_masked(Gs[:, None], m), np.where(m, bs[:, None], 0.0)[..., None])[..., 0]
    obj = 0.5 * np.einsum("rsi,rsi->rs", c, np.einsum("rij,rsj->rsi", Gs, c)) - np.einsum("rsi,ri->rs", c, bs)
    obj[~np.all(c >= 0, axis=-1)] = np.inf
    return c[np.arange(c.shape[0]), np.argmin(obj, axis=1)]


def _significant_rows(PtWP, PtWe, PtWv, rel_var, unpruned=None) -> np.ndarray:
    """:func:`_significant_nnls` of every row ``(R, 5)`` at once (rows of well-conditioned ``PtWP``;
    the others one by one); rows where ``unpruned (R,)`` is True keep every term the NNLS fits."""
    unpruned = np.zeros(PtWe.shape[0], dtype=bool) if unpruned is None else np.asarray(unpruned, dtype=bool)
    R = PtWe.shape[0]
    coef = np.zeros((R, N_FEATURES))
    finite = np.all(np.isfinite(PtWP), axis=(1, 2)) & np.all(np.isfinite(PtWe), axis=1)
    scale = np.sqrt(np.clip(np.diagonal(PtWP, axis1=1, axis2=2), 1e-300, None))
    Gs = PtWP / (scale[:, :, None] * scale[:, None, :])
    w = np.linalg.eigvalsh(np.where(finite[:, None, None], Gs, np.eye(N_FEATURES)))
    batch = finite & (w[:, 0] > w[:, -1] / _BATCH_COND)
    for r in np.flatnonzero(finite & ~batch):
        coef[r] = nnls_rows(PtWP[r], PtWe[r]) if unpruned[r] else _significant_nnls(PtWP[r], PtWe[r], PtWv[:, r], rel_var)
    rows = np.flatnonzero(batch)
    Gs, bs, sc, P, Vs = Gs[rows], PtWe[rows] / scale[rows], scale[rows], PtWP[rows], PtWv[:, rows]
    active = np.ones((rows.size, N_FEATURES), dtype=bool)
    prune = np.any(Vs != 0, axis=(0, 2)) & ~unpruned[rows]  # no reference noise in these rows: nothing was subtracted, keep the fit
    todo = np.ones(rows.size, dtype=bool)
    c = np.zeros((rows.size, N_FEATURES))
    while todo.any():
        t = np.flatnonzero(todo)
        c[t] = _nnls_batch(Gs[t], bs[t], active[t])
        active[t] &= c[t] > 0  # the standard errors of the features in use
        todo &= prune & active.any(axis=1)
        if not todo.any():  # the usual case without reference noise: nothing to prune
            break
        t = np.flatnonzero(todo)
        mm = active[t][:, :, None] & active[t][:, None, :]  # pinv of the scaled sub-matrix (features of unlike sizes)
        Pinv = np.linalg.pinv(np.where(mm, Gs[t], 0.0), hermitian=True)
        var = sum(rv * np.einsum("rij,rj->ri", Pinv, np.where(active[t], V[t] / sc[t], 0.0)) ** 2
                  for rv, V in zip(rel_var, Vs))  # of the scaled coefficients c · scale
        with np.errstate(over="ignore"):  # a term the reference's noise cannot move: z is inf, kept
            z = np.where(active[t], c[t] / np.maximum(np.sqrt(var), 1e-300), np.inf)
        weakest = np.argmin(z, axis=1)
        more = z[np.arange(t.size), weakest] < _SIGNIFICANT
        active[t[more], weakest[more]] = False  # the weakest alone: collinear features share what one would show
        c[t[more]] = 0.0
        todo[t[~more]] = False
    coef[rows] = c / sc
    return coef


def _psd(M) -> np.ndarray:
    """The nearest positive semi-definite matrix (negative eigenvalues set to 0)."""
    w, V = np.linalg.eigh(0.5 * (M + M.T))
    return (V * np.clip(w, 0, None)) @ V.T


def fit_error_model(cal, sessions, mounts, offsets, tare_means, spec, groups, block_size, ref_covs=None,
                    gauge_cov=None, samples=None, ref_n=None, poly_parts=()):
    """Per matrix row, non-negative coefficients of the residual variance on ``load_features``.

    Residuals of every usable training sample (all faces' rows, also those a method
    does not model, e.g. crosstalk for ``face_to_face``), in the matrix's output frame.
    They hold the reference's noise too (the targets come from it): with ``ref_covs`` (the
    reference's covariance at rest of each session, from its tare) that part is taken out,
    so the variance is that of the true wrench's error. With ``gauge_cov`` (the gauge noise
    at rest), its propagation ``diag(C Σ_g Cᵀ)`` is the variance's floor (measured directly,
    it does not suffer from subtracting a large reference noise).
    Also sets each group's ``inflation`` from the scores ``Aᵀ E`` of clusters of
    consecutive samples (cluster-robust covariance against ``Σ_r ⊗ P``).
    ``samples`` (per session, a list of ``SessionBlock`` of every ``stride``-th sample, kept
    by the fit's own pass) spares the two passes over the sessions. ``ref_n`` (samples at rest
    behind each ``ref_covs``) sets how uncertain that noise is; an excess of the residuals over
    it is kept only where it exceeds that uncertainty (``_significant_nnls``). With a noisy
    reference, its noise in the coefficients goes, face by face, to the samples where the face
    carries (``_reference_noise.py``: sets each group's ``reference_leverage``, ``reference_cov``
    and replaces its ``residual_cov`` by the error model's). ``poly_parts`` (the polynomial
    correction's ``PolyAccumulator.reference_parts``) give the correction's rows their own
    coefficients' share instead.

    The residuals are taken as a tare leaves them (:func:`_retared`).

    Returns ``(variance_coef (6F, 5), residual_corr (F, 6, 6), poly_reference, error_frame,
    rest_bias (6F,))``: ``poly_reference`` a list of ``PolyReferenceBlock`` (empty without reference
    noise or correction), ``error_frame`` the frame of the first two and of ``rest_bias`` ("output",
    or "face" for a fit in S_A), ``rest_bias`` the fitted offset's error at rest (:func:`_retared`).
    """
    F = len(cal.output_faces)
    idx = [f - 1 for f in cal.output_faces]
    stride = max(1, sum(len(s) for s in sessions) // ERROR_MODEL_SAMPLES)
    ref_covs = [None] * len(sessions) if ref_covs is None else ref_covs
    # the error model's frame: each face's own (a fit in S_A is mapped there, see _error_frame)
    X = _error_frame(cal)
    C = cal.matrix.reshape(F, 6, 36)
    if X is not None:
        C = X @ C
    floor_m = np.zeros((F, 6, 6)) if gauge_cov is None else C @ gauge_cov @ C.transpose(0, 2, 1)
    floor = np.diagonal(floor_m, axis1=1, axis2=2).reshape(-1).copy()
    noisy = any(np.any(rc) for rc in ref_covs if rc is not None)
    lev = ReferenceLeverage(groups, cal.output_faces, len(sessions)) if noisy else None
    masked = _split_faces(cal, groups)
    PtP, Pte2, EtE, kept, clusters, qraw, phi_one = _first_pass(cal, sessions, mounts, offsets, tare_means, spec,
                                                                groups, block_size, ref_covs, floor, samples, stride,
                                                                lev, X, masked)
    _set_inflation(groups, clusters, stride)
    kept, rest_means = _retared(kept, len(sessions))
    # a face fitted on its own rows only (face_to_face) reads the crosstalk as a prediction its fit never saw:
    # there its own error and the crosstalk's are two models (own_q); so does a face of a joint fit with a
    # correction (its q is masked where it carries nothing: _split_faces); the others have one (a joint fit's
    # crosstalk is in its residuals, and with a noisy reference q is 0 there: _features)
    own_fit = np.isin(cal.output_faces, [cal.output_faces[int(g.rows[0]) // 6] for g in groups if g.inputs.size == 6])
    q_own = own_q(qraw, [k[2] for k in kept], [k[1][:, 0, 1] > 0 for k in kept], own_fit | masked)
    # the first weights (an exact reference: weights 1 whatever the coefficients, which the one step sets);
    # coef[0] where a face reads no load of its own, coef[1] where it does (own_load)
    coef = np.stack([_nnls_coefficients(PtP, Pte2) if noisy else np.zeros((6 * F, N_FEATURES))] * 2)
    vref_full = [_reference_cov(m, rc, spec.output_frame, idx) for m, rc in zip(mounts, ref_covs)]
    vref_em = vref_full if X is None else [_reference_cov(m, rc, "face", idx) for m, rc in zip(mounts, ref_covs)]
    poly_ref = []
    if noisy:  # the reference's noise in the coefficients, face by face, over the rows where the face carries
        lev.finish(stride, vref_full)
        if poly_parts:
            lev.set_poly(poly_parts, cal.correction)
            poly_ref = lev.poly_blocks(vref_full)
        kept = [(*k, *v) for k, v in zip(kept, lev.in_sample(F, vref_full, X, gauge_cov))]
    else:
        kept = [(*k, None, None) for k in kept]
    # Where the reference's noise v is large against the error itself, E² − v says little about
    # the error: refit with each row weighted by 1 / (var + v)² (the inverse variance of E² − v),
    # so the model is that of the true wrench's error and not of noise left over from the
    # subtraction (a weight (var / (var + v))² let rows that carry nothing but crosstalk set the
    # load term of the rows that carry: face_to_face at 3 % reference noise covered 18 %).
    vdiag = [np.diagonal(V, axis1=-2, axis2=-1) for V in vref_em]  # (F, 6) per session
    rel_var = [0.0 if n is None else 2.0 / max(n - 1, 1) for n in (ref_n or [None] * len(sessions))]
    b = _stacked(kept, vdiag, F, noisy)
    b["unpruned"] = _corrected_rows(cal, X is not None)
    phT_one = None if phi_one is None else np.ascontiguousarray(np.concatenate(phi_one).transpose(1, 2, 0), dtype=float)
    del phi_one
    _one_model_features(b, phT_one, masked & ~np.isfinite(q_own))
    rho = np.zeros(b["carr"].shape, dtype=bool)
    if np.isfinite(q_own).any():  # in training L is the loaded flag
        rho = own_load(np.concatenate(qraw).T, q_own[:, None], np.concatenate([k[1][:, 0, 1] for k in kept])) > 0
    del qraw
    _set_own_samples(b, rho)
    first = coef.copy()
    while True:
        for _ in range(_REWEIGHT - 1 if noisy else 1):  # exact reference: the weights do not change
            _reweighted(b, coef, floor, rel_var, noisy)
        corr = _correlation(b, coef, floor, floor_m, vref_em, EtE)  # weighted by the last step's variances
        if noisy:
            _reweighted(b, coef, floor, rel_var, noisy)
        coef[:, :, 0] += floor
        s_load, s_own, s_rest, own_weight = _coverage_scales(b, coef)
        # where the reference's noise swamps a face's own error, E² − v cannot tell it from the gauge noise
        # (face_to_face, linear cube, 0.1 %: a fitted own model missed an error 60× the floor on one axis, 84 %
        # coverage; the crosstalk's model on that row alone made the mean error of the design rows 10⁴× theirs).
        # A face fitted on its own rows keeps its two models, the own one a bound on those rows (_own_bound): its
        # crosstalk is another face's load read as its own, and one model set its intervals where it carried at
        # 10–200× the error (linear cube, 0.1 %). A corrected face of a joint fit keeps its own model (its scale
        # the crosstalk's) down to _MIN_OWN_WEIGHT, below it one model, wide where it carries but not short: its
        # one model's q term is the crosstalk's identity read at full load (nonlinear cube, wizard's tare,
        # 0.1 · 0.33 %: intervals up to 3–6× the error where the face carried, 1.7× with its own)
        informed = own_weight.reshape(F, 6) >= np.where(masked, _MIN_OWN_WEIGHT, np.inf)[:, None]
        bounded = np.isfinite(q_own) & ~masked & ~informed.all(axis=1)
        swamped = np.isfinite(q_own) & masked & ~informed.all(axis=1)
        if not swamped.any():
            break
        q_own[swamped] = np.inf
        rho[swamped] = False
        _one_model_features(b, phT_one, masked & swamped)
        _set_own_samples(b, rho)
        coef = first.copy()
    c0 = coef[0, :, 0].copy()  # at rest (L = 0) the constant alone: its own scale there, the loaded one at L = 1
    coef[0] *= s_load[:, None]
    coef[0, :, 0] = s_rest * c0
    coef[0, :, 1] += (s_load - s_rest) * c0
    coef[1] *= s_own[:, None]
    one = np.repeat(~np.isfinite(q_own), 6)  # faces with one model: the same coefficients
    coef[1, one] = coef[0, one]
    rows = np.flatnonzero(np.repeat(bounded, 6) & ~informed.reshape(-1))
    if rows.size:
        coef[1, rows] = 0.0
        coef[1, rows, 0] = _own_bound(b, floor, rows)
    if noisy:  # Σ_r → Σ_e: the reference's share is now in the groups' own term
        # each design row's error by the model of what it is: the face's own where it carries (the flags; the
        # crosstalk's model at a small own load of a face_to_face fit made the mean 10× the carrying rows')
        ends = np.cumsum([0] + [k[0].shape[0] for k in kept])
        lev.set_error_cov(lambda i: _variances(b["phT"][:, :, ends[i] : ends[i + 1]], coef,
                                               rho=b["carr"][:, ends[i] : ends[i + 1]]).reshape(6 * F, -1).T, corr, X)
    # the fitted offset's own error at rest beyond the reference's noise through it (the groups' term)
    off_var = lev.offset_var(F, X) if noisy else [0.0] * len(sessions)
    rest_bias = np.mean([np.maximum(m * m - v, 0.0) for m, v in zip(rest_means, off_var)], axis=0)
    return coef, q_own, corr, poly_ref, "output" if X is None else "face", rest_bias


def _own_bound(b, floor, rows) -> np.ndarray:
    """``(rows.size,)`` the variance of a face's own error where the reference's noise swamps it (rows of the
    own model, ``(6F,)`` indices): the mean of ``E² − v − floor`` over the samples where the face reads its own
    load and carries, :data:`_BOUND_Z` standard errors above (not below 0), plus the floor. A bound, not a fit:
    each sample's ``E² − v`` has the reference's noise's spread, ``√2 v``, so a model of the own load's terms
    could not be told from 0 (``face_to_face``, linear cube, 0.1 %: fitted, an axis whose error was 60× the
    floor covered 84 %)."""
    out = np.empty(rows.size)
    for f in np.unique(rows // 6):
        own = b["own"][f]
        c = dict(ET=b["ET"][f : f + 1, :, own], vT=0.0 if b["vT"] is None else b["vT"][f : f + 1, :, own])
        e2 = _squares_less(c, floor[6 * f : 6 * f + 6])[0]  # (6, n)
        se = e2.std(axis=1, ddof=1) / np.sqrt(e2.shape[1]) if e2.shape[1] > 1 else np.full(6, np.inf)
        bound = np.maximum(e2.mean(axis=1) + _BOUND_Z * se, 0.0) + floor[6 * f : 6 * f + 6]
        at = rows // 6 == f
        out[at] = bound[rows[at] % 6]
    return out


def _set_own_samples(b, rho) -> None:
    """Set ``b["rho"]`` (``(F, n)`` bool: where each face reads a load of its own, :func:`own_load`) and
    what follows from it: ``b["own"]``, those where it also carries (the own model learns from them: the
    crosstalk that reaches ``own_q``, 0.5 % of it, is read by it in use, but its errors set a fit of the
    face's own, ``face_to_face``, linear cube: its ``q_other`` term 10⁴ × the error where the face
    carried), ``b["split"]`` (some face has a model of its own) and ``b["support"]``."""
    b["rho"] = rho
    b["own"] = rho & b["carr"]
    b["split"] = bool(rho.any())
    b["support"] = _support(b)


def _split_faces(cal, groups) -> np.ndarray:
    """``(F,)`` bool: the output faces of a joint fit with a polynomial correction. Each may have two models,
    its own load's and the crosstalk's (:func:`own_q`), and for the crosstalk's its ``q`` is 0 where it carries
    nothing (:func:`_features`' ``carries``), with an exact reference too: there its predicted wrench is its
    in-sample error, and a ``q`` term fitted to that identity set the intervals by the error itself
    (``loaded_frame``, nonlinear cube, exact reference: pooled 94.4–99.3 % with it, 93.9–95.5 % without).
    A face left with one model reads the features of :func:`_first_pass`'s ``phi_one`` (its ``q`` kept
    there, as before the split: ``quasi_total``, 0.33 %, where the face carries: 88.1 % on the weakest axis
    with it masked, 93.2 % kept)."""
    own_gauge = [cal.output_faces[int(g.rows[0]) // 6] for g in groups if g.inputs.size == 6]
    return _corrected(cal) & ~np.isin(cal.output_faces, own_gauge)


def _one_model_features(b, phT_one, faces) -> None:
    """Faces ``faces (F,)`` bool with one model read the features ``phT_one (F, 5, n)`` (their ``q`` not masked
    where they carry nothing: :func:`_split_faces`) instead of the split's."""
    if phT_one is not None and faces.any():
        b["phT"][faces] = phT_one[faces]


def own_q(qraw, carries, loaded, faces=None) -> np.ndarray:
    """``(F,)`` per output face, the ``q`` from which it reads a load of its own (``own_load``): the
    99.5th percentile of its ``q`` on the loaded samples where it carried nothing (its crosstalk, as
    read in use). ``inf`` (one model) where fewer than :data:`_MIN_INFORMED` samples are on either side.

    ``qraw``, ``carries`` (the faces that carry) and ``loaded`` (some face does), per kept block,
    ``(n, F)``, ``(n, F)``, ``(n,)``; ``faces (F,)`` bool, those to split (None: all; the others ``inf``).
    (Where a face carries, its error is its own load's; where another face does, the crosstalk's. One
    model of both set the one by the other: ``face_to_face``'s
    ``q`` term, fitted where the crosstalk is its own prediction (``q = E²``), made its intervals 18×
    the error where the face carried, linear cube.)"""
    out = np.full(qraw[0].shape[1], np.inf)
    if faces is not None and not np.any(faces):
        return out
    q, c, ld = np.concatenate(qraw).T, np.concatenate(carries).T, np.concatenate(loaded)  # (F, n): rows contiguous
    for f in (range(q.shape[0]) if faces is None else np.flatnonzero(faces)):
        cross = q[f][ld & ~c[f]]
        if cross.size < _MIN_INFORMED:
            continue
        k = int(np.ceil(0.995 * (cross.size - 1)))  # the 99.5th percentile, rounded up to a sample
        q0 = np.partition(cross, k)[k]
        if q0 > 0 and np.count_nonzero(q[f][ld] >= q0) >= _MIN_INFORMED:
            out[f] = q0
    return out


def _retared(kept, n_int):
    """``(kept, means)``: the residuals as a tare leaves them, and each session's mean residual at rest
    ``(6F,)`` that it took out.

    A tare sets the offset so that the wrench at rest is 0: a sample's error after it is its residual
    at the fitted offset less the session's mean residual at rest (exactly, for the affine rows). The
    error model is of that error, as the calibration is used (the wizard, the live view, the recorder
    and every evaluation tare). Where the fitted offset is in use, the mean's square beyond the
    reference's noise through the offset (``CalibrationCovariance.rest_bias``) is added. (A linear
    fit of a nonlinear cube reads a bias at rest: ``face_to_face``'s connected face on a cube with
    15 % saturation, 0.2 N on fx; in the error model's constant it made the intervals at rest 500×
    too wide after a tare.) The samples at rest are those with ``L`` 0 (the session's flags: :func:`_features`).
    """
    sums, counts = np.zeros((n_int, kept[0][0].shape[1])), np.zeros(n_int)
    for E, phi, _, j in kept:
        rest = phi[:, 0, 1] == 0
        sums[j] += E[rest].sum(axis=0, dtype=float)
        counts[j] += np.count_nonzero(rest)
    means = sums / np.maximum(counts, 1)[:, None]
    return [(E - means[j].astype(E.dtype), phi, carr, j) for E, phi, carr, j in kept], list(means)


def _error_frame(cal):
    """``(F, 6, 6)`` output frame → face frame of each output face for a fit in S_A (the reference's
    frame), else None: the error model is fitted where the errors are read.

    In S_A a face's force and torque errors are correlated at ±0.99 and cancel in its frame to
    1/50 of the variance; a variance per S_A axis, each scaled to its own coverage, and a
    correlation estimated beside them do not cancel so (``loaded_frame``, linear cube, 0.1 %
    reference noise: face-frame torque intervals covering 98–99 %)."""
    if cal.output_frame != "reference":
        return None
    return cal._face_from_output[[f - 1 for f in cal.output_faces]]


def _first_pass(cal, sessions, mounts, offsets, tare_means, spec, groups, block_size, ref_covs, floor, samples,
                stride, lev, X=None, split=None):
    """One pass over every ``stride``-th usable sample: the sums the error model is fitted from.

    Returns ``PtP (F, 5, 5)``, ``Pte2 (F, 5, 6)``: per output face, the normal equations of the
    squared residuals less the reference's variance and ``floor (6F,)`` on ``load_features``;
    ``EtE (F, 6, 6)``, the residuals' sums of products; ``kept``, per block ``(E (n, 6F) float32,
    phi (n, F, 5) float32, carries (n, F) bool, session index)`` for the later passes; the
    groups' cluster scores (see :func:`_add_cluster_scores`); per block each face's ``q (n, F)``
    as read in use (:func:`_features`); and ``phi_one``, per block the features with the
    :func:`_split_faces`' ``q`` kept where they carry nothing (float32; None without such faces).
    """
    F = len(cal.output_faces)
    idx = [f - 1 for f in cal.output_faces]
    n_int = len(sessions)
    own_face = {id(g): (cal.output_faces[int(g.rows[0]) // 6] if g.inputs.size == 6 else None) for g in groups}
    # faces that keep their q where they carry nothing (see _features): fitted on their own rows only,
    # or with a polynomial correction
    keep_q = np.isin(cal.output_faces, [f for f in own_face.values() if f is not None]) | _corrected(cal)
    split = _split_faces(cal, groups) if split is None else split  # q masked where they carry nothing, also exact
    phi_one = [] if split.any() else None  # their features with q kept (one model: see _split_faces)
    clusters = {id(g): dict(score=np.zeros((g.design_pinv.shape[0], g.rows.size)), n=0,
                            meat=np.zeros(g.rows.size), length=max(50, -(-g.dof // (N_CLUSTERS * stride)))) for g in groups}
    PtP = np.zeros((F, N_FEATURES, N_FEATURES))
    Pte2 = np.zeros((F, N_FEATURES, 6))
    EtE = np.zeros((F, 6, 6))
    kept = []  # per block: E, phi (float32), which faces carry, session: the data are read once
    qraw = []  # per block: each face's q as read in use (not masked where it carries nothing)
    # to the error model's frame: one product with the block-diagonal map (an einsum over the faces
    # took 6 ms of a 60-ms fit of 10⁵ samples)
    XT = None if X is None else scipy.linalg.block_diag(*X).T
    for j, (s, mount, o, rc) in enumerate(zip(sessions, mounts, offsets, ref_covs)):
        for b in (_strided(s.iter_blocks(block_size), stride) if samples is None else samples[j]):
            targets, carries, usable, _ = block_targets(b.reference, b.loaded, mount, spec.output_frame)
            if usable.all():  # the usual case: no copies
                usable = slice(None)
            counts = b.counts[usable]
            x = counts - o
            xC, Y = _predict(cal, x)
            E_out = np.take(targets[usable], idx, axis=1) - Y.reshape(-1, F, 6)  # take, not [:, idx]: C-ordered, 8× faster
            E = E_out if X is None else (E_out.reshape(-1, 6 * F) @ XT).reshape(-1, F, 6)  # the error model's frame
            # in the face frame, the faces' wrenches are the matrix's rows: the product is reused (and consumed)
            # with a noisy reference, a face of a joint fit has no load where it carries nothing (see _features)
            unloaded = (b.loaded[usable].view(np.uint8) @ np.ones(6, np.uint8)) == 0  # ~any(axis=1), 4× faster
            # the features at the offset a tare sets, as the residuals are (_retared) and as in use: at the fitted
            # offset of a nonlinear cube's linear fit the crosstalk's q held the bias at rest (face_to_face, exact
            # reference: the crosstalk's intervals 94.0–99.2 % with a model of its own)
            shift = tare_means[j] - o
            xA = xC - shift @ cal.matrix.T if cal.output_frame == "face" else None
            carr = carries[usable][:, idx]
            phi, q = _features(cal, x - shift, idx, xA,
                               _q_mask(carr, keep_q, split, lev is not None), unloaded)  # (n, F, 5)
            if phi_one is not None:  # the same q, kept as before the split
                phi_one.append(_load_phi(q, None if lev is None else carr | keep_q, unloaded).astype(np.float32))
            qraw.append(q)
            kept.append((E.reshape(-1, 6 * F).astype(np.float32), phi.astype(np.float32), carries[usable][:, idx], j))
            EF = np.ascontiguousarray(E.transpose(1, 0, 2))  # (F, n, 6): products batched over faces
            EtE += np.matmul(EF.transpose(0, 2, 1), EF)  # the diagonal blocks of Eᵀ E only
            if lev is not None:  # the reweighting's first weights (with an exact reference, 1 whatever they are)
                v_ref = _reference_variance(mount, rc, spec.output_frame if X is None else "face", carries[usable], idx)
                EF *= EF
                EF -= v_ref.transpose(1, 0, 2)
                EF -= floor.reshape(F, 1, 6)
                phF = np.ascontiguousarray(phi.transpose(1, 0, 2))
                PtP += np.matmul(phF.transpose(0, 2, 1), phF)
                Pte2 += np.matmul(phF.transpose(0, 2, 1), EF)
            if lev is not None:  # a noisy reference: its noise in the coefficients, face by face
                lev.add(counts, carries[usable][:, idx], unloaded, j, tare_means[j])
            _add_cluster_scores(groups, clusters, own_face, counts, E_out.reshape(-1, 6 * F), carries[usable], unloaded,
                                tare_means[j], j, n_int)
    return PtP, Pte2, EtE, kept, clusters, qraw, phi_one


def _q_mask(carr, keep_q, split, noisy):
    """:func:`_features`' ``carries``: where each face's ``q`` counts. With a ``noisy`` reference where it carries
    or keeps it (``keep_q``, not ``split``); with an exact one everywhere (None) but where a ``split`` face carries
    nothing (see :func:`_split_faces`)."""
    if noisy:
        return carr | (keep_q & ~split)
    return carr | ~split if split.any() else None


def _add_cluster_scores(groups, clusters, own_face, counts, Eflat, carries, unloaded, tare_mean, j, n_int):
    """Add one block's scores ``Aᵀ E`` to each group's current cluster of consecutive samples.

    ``A`` is the group's design (session intercepts, then its input counts less the tare mean);
    a group of one face takes only the samples where that face carries or nothing loads the
    cube. A cluster full at ``length`` samples adds ``scoreᵀ design_pinv score`` to its ``meat``.
    ``counts (n, 36)``, ``Eflat (n, 6F)`` residuals, ``carries (n, 6)`` and ``unloaded (n,)``
    of the block's usable samples; ``j`` is the session's index among ``n_int``.
    """
    for g in groups:
        cl = clusters[id(g)]
        f = own_face[id(g)]
        rows = None if f is None else np.flatnonzero(carries[:, f - 1] | unloaded)
        # views where all are taken, else one C-ordered copy ([rows][:, inputs] gave a column-major one)
        Xg = counts if f is None and is_range(g.inputs, 36) else _rows_cols(counts, rows, g.inputs)
        # A in a buffer kept with the cluster, not one a block (face_to_face, 10⁵ samples: with the copies by
        # slices, 3.3 against 3.6 ms a fit)
        if cl.get("A") is None or cl["A"].shape[0] < Xg.shape[0]:
            cl["A"] = np.empty((Xg.shape[0], n_int + g.inputs.size))
        A = cl["A"][: Xg.shape[0]]
        A[:, :n_int] = 0.0
        A[:, j] = 1.0
        np.subtract(Xg, tare_mean[g.inputs], out=A[:, n_int:])
        Eg = Eflat if f is None and is_range(g.rows, Eflat.shape[1]) else _rows_cols(Eflat, rows, g.rows)
        a = 0
        while a < A.shape[0]:  # clusters of consecutive samples, across blocks
            take = min(A.shape[0] - a, cl["length"] - cl["n"])
            cl["score"] += A[a : a + take].T @ Eg[a : a + take]
            cl["n"] += take
            a += take
            if cl["n"] >= cl["length"]:
                sc = cl["score"]
                cl["meat"] += _quadratic(sc, g.design_pinv)
                sc[...] = 0.0  # the next cluster's, in place
                cl["n"] = 0


def _rows_cols(M, rows, cols) -> np.ndarray:
    """``M[np.ix_(rows, cols)]`` (C-ordered; ``rows`` None: all), by a slice where ``cols`` are consecutive
    (a group's own gauges or rows): 41 against 70 µs for 1,700 of 2,000 rows and 6 of 36 columns."""
    if cols.size and np.all(np.diff(cols) == 1):
        sl = slice(int(cols[0]), int(cols[-1]) + 1)
        return np.ascontiguousarray(M[:, sl]) if rows is None else M[rows, sl]
    return M[np.ix_(np.arange(M.shape[0]) if rows is None else rows, cols)]


def _quadratic(sc, P) -> np.ndarray:
    """``(j,)`` the quadratic forms ``sc[:, j]ᵀ P sc[:, j]`` (one product, not a three-operand ``einsum``)."""
    return np.einsum("pj,pj->j", P @ sc, sc)


def _set_inflation(groups, clusters, stride) -> None:
    """Each group's ``inflation (rows,)``: cluster-robust variance over that of ``Σ_r ⊗ P``, at least 1."""
    for g in groups:
        cl = clusters[id(g)]
        sc = cl["score"]
        cl["meat"] += _quadratic(sc, g.design_pinv)
        rank = max(int(np.linalg.matrix_rank(g.design_pinv, hermitian=True)), 1)
        var = np.clip(np.diag(g.residual_cov), 1e-300, None)
        # the scores are sums over every stride-th sample: × stride for the full data's (independent errors)
        g.inflation = np.maximum(1.0, stride * cl["meat"] / (rank * var))


def _nnls_coefficients(PtP, Pte2) -> np.ndarray:
    """``(6F, 5)`` non-negative variance coefficients of each row from the first pass's sums, unweighted."""
    F = PtP.shape[0]
    # no reference-noise response (PtWv = 0): the plain fit of every row, batched
    return _significant_rows(np.repeat(PtP, 6, axis=0), Pte2.transpose(0, 2, 1).reshape(6 * F, N_FEATURES),
                             np.zeros((1, 6 * F, N_FEATURES)), [0.0])


#: The distinct products ``φ_i φ_j`` (i ≤ j) of the features; the first four are ``φ`` itself (``φ_0 = 1``).
_PAIRS = np.triu_indices(N_FEATURES)
#: The reweighting steps and pass 4 read the kept samples in chunks of at most this many (bounded memory).
_CHUNK = 2048


def _stacked(kept, vdiag, F, noisy) -> dict:
    """Every kept block at once, face-major, as the reweighting steps and pass 4 read them (made
    once: none of it depends on the variance coefficients).

    ``ET (F, 6, n)`` residuals and ``phT (F, 5, n)`` features (float64 from the float32 kept: each
    later pass reads them without a conversion of its own), ``carr (F, n)``,
    ``vT (F, 6, n)`` the reference's variance in each residual (its own where the face carries, times
    the kept factor there, else its share through the fitted coefficients; None without reference
    noise: 0), and ``sessions``, ``(j, slice)`` of each session's (consecutive) samples.
    """
    sessions, start = [], 0
    for _, _, carr, j, *_ in kept:
        if sessions and sessions[-1][0] == j:
            sessions[-1][2] += carr.shape[0]
        else:
            sessions.append([j, start, start + carr.shape[0]])
        start += carr.shape[0]
    n = start
    carr = np.concatenate([k[2] for k in kept]).T  # (F, n)
    vT = None
    if noisy:
        vT = np.empty((F, 6, n))
        for j, a, b in sessions:
            np.multiply(carr[None, :, a:b], vdiag[j].T[:, :, None], out=vT.transpose(1, 0, 2)[:, :, a:b])
        if kept[0][5] is not None:  # the fit absorbs part of its rows' own noise
            vT *= np.concatenate([k[5] for k in kept]).T.reshape(F, 6, n)
        if kept[0][4] is not None:
            np.copyto(vT, np.concatenate([k[4] for k in kept]).T.reshape(F, 6, n), where=~carr[:, None, :])
    return dict(ET=np.ascontiguousarray(np.concatenate([k[0] for k in kept]).T, dtype=float).reshape(F, 6, n),
                phT=np.ascontiguousarray(np.concatenate([k[1] for k in kept]).transpose(1, 2, 0), dtype=float), carr=carr, vT=vT,
                sessions=[(j, slice(a, b)) for j, a, b in sessions])


def _chunks(b, floor=None):
    """Per chunk of one session's consecutive samples: ``(j, c)``, ``c`` the chunk's float64 ``ET``,
    ``phT``, ``vT`` (0 without reference noise), ``carr``, ``cols`` (its slice of the samples) and,
    with ``floor (6F,)``, ``E2T``: the residuals' squares less the reference's variance and the floor."""
    F = b["ET"].shape[0]
    for j, sl in b["sessions"]:
        for s in _slices(sl):
            c = dict(ET=b["ET"][:, :, s], phT=b["phT"][:, :, s], carr=b["carr"][:, s],
                     vT=0.0 if b["vT"] is None else b["vT"][:, :, s], cols=s, rho=b["rho"][:, s] if b["split"] else None,
                     own=b["own"][:, s])
            if floor is not None:
                c["E2T"] = _squares_less(c, floor)
            yield j, c


def _squares_less(c, floor, out=None) -> np.ndarray:
    """``E2T (F, 6, n)`` of chunk ``c``: the residuals' squares less the reference's variance and ``floor (6F,)``."""
    E2 = np.multiply(c["ET"], c["ET"], out=out)
    if not np.isscalar(c["vT"]):  # else 0: no pass
        E2 -= c["vT"]
    E2 -= floor.reshape(E2.shape[0], 6, 1)
    return E2


def _slices(sl):
    """The chunks (slices of at most ``_CHUNK`` samples) of the samples ``sl``."""
    return [slice(a, min(a + _CHUNK, sl.stop)) for a in range(sl.start, sl.stop, _CHUNK)]


def _variances(phT, coef, floor=None, out=None, rho=None) -> np.ndarray:
    """``(F, 6, n)`` each row's modelled variance at samples of features ``phT (F, 5, n)``: ``coef[0]``'s
    where the face reads no load of its own, ``coef[1]``'s where it does (``rho (F, n)`` bool);
    with ``floor (6F,)`` added and not below 0."""
    F = phT.shape[0]
    C = coef.reshape(2, F, 6, N_FEATURES)
    if floor is not None:
        C = C.copy()
        C[..., 0] += floor.reshape(F, 6)  # φ_0 = 1
    var = np.matmul(C[0], phT, out=out)
    if rho is not None and (C[1] != C[0]).any():  # (coef[1] is coef[0] for the faces of one model)
        # np.where, not copyto(where=) with the mask broadcast over the rows: 70 against 210 µs for 6 faces
        # of 2048 samples, the same values
        own = np.where(rho[:, None, :], np.matmul(C[1], phT), var)
        if out is None:
            var = own
        else:
            np.copyto(var, own)
    return var if floor is None else np.maximum(var, 0, out=var)


def _weighted_sums(b, coef, floor, n_s, noisy) -> np.ndarray:
    """``(n_s, F, 18, 15 m)``: per session, the sums over the samples of ``w``, ``w (E² − v)`` and ``w v``
    (rows, 6 each) times the features' distinct products (:data:`_PAIRS`), ``w = 1 / (var + v)²``
    with a ``noisy`` reference, else 1 (then ``w v`` is 0 and not summed); with ``m = 2`` models
    (``b["rho"]`` has a face of its own) the last axis's first 15 over the samples where the face
    reads no load of its own, its last 15 where it does and carries, else ``m = 1``."""
    F = b["ET"].shape[0]
    P = len(_PAIRS[0])
    split = b["split"]
    M = np.zeros((n_s, F, 18, (1 + split) * P))
    # the rows (L) and the products (PP) of every chunk in two buffers, E² − v made in place in L (no chunk's
    # own arrays, no copy): face_to_face's fit of 10⁵ samples 51.8 against 53.1 ms, the others 0–0.5 % faster
    Lbuf, PPbuf = np.empty((F, 18 if noisy else 7, _CHUNK)), np.empty((F, P, _CHUNK))
    for j, c in _chunks(b):
        n = c["ET"].shape[2]
        L = Lbuf[:, :, :n]
        if noisy:
            w = L[:, :6]
            tot = _variances(c["phT"], coef, floor, out=w, rho=c["rho"])  # in place: w = 1 / tot², tot = max(var + v, 1e-300)
            tot += c["vT"]
            np.maximum(tot, 1e-300, out=tot)
            np.multiply(tot, tot, out=w)
            np.divide(1.0, w, out=w)
            np.multiply(w, _squares_less(c, floor, out=L[:, 6:12]), out=L[:, 6:12])
            np.multiply(w, c["vT"], out=L[:, 12:])
        else:  # w = 1: the sums of 1 (one row for the six) and of E² − v
            L[:, 0] = 1.0
            _squares_less(c, floor, out=L[:, 1:])
        PP = _feature_products(c["phT"], PPbuf[:, :, :n])
        S = np.matmul(L, PP.transpose(0, 2, 1))
        if split:  # each face's own model: its few samples (the crosstalk's: the rest), not a product of all
            S = np.concatenate([S, np.zeros_like(S)], axis=2)
            for f in np.flatnonzero(c["rho"].any(axis=1)):
                o, x = c["own"][f], c["rho"][f] & ~c["carr"][f]  # its own samples; the crosstalk it reads as its own
                # rows of the transposes by index: the same operands as L[f][:, o] (column-major) and the same
                # products, 23 against 33 µs each
                o = np.flatnonzero(o)
                S[f, :, P:] = L[f].T[o].T @ PP[f].T[o]
                S[f, :, :P] -= S[f, :, P:]
                if x.any():
                    x = np.flatnonzero(x)
                    S[f, :, :P] -= L[f].T[x].T @ PP[f].T[x]
        if noisy:
            M[j] += S
        else:
            M[j, :, :6] += S[:, :1]
            M[j, :, 6:12] += S[:, 1:]
    return M


def _feature_products(phT, out=None) -> np.ndarray:
    """``(F, 15, n)`` the features' distinct products :data:`_PAIRS` at samples ``phT (F, 5, n)`` (into ``out``)."""
    F, _, n = phT.shape
    PP = np.empty((F, len(_PAIRS[0]), n)) if out is None else out
    PP[:, :N_FEATURES] = phT  # φ_0 φ_j = φ_j
    p = N_FEATURES
    for i in range(1, N_FEATURES):  # φ_i φ_j, j ≥ i, in one product each (_PAIRS' order): 4 against 10 calls
        np.multiply(phT[:, i : i + 1], phT[:, i:], out=PP[:, p : p + N_FEATURES - i])
        p += N_FEATURES - i
    return PP


def _reweighted(b, coef, floor, rel_var, noisy=True) -> None:
    """One reweighting step of the error model's variance (updates ``coef`` in place).

    With a ``noisy`` reference the variance fit weighs rows by ``1 / (var + v)²``, the inverse
    variance of ``E² − v`` (the rows the reference's noise swamps count little, the rows it does not
    touch fully); with an exact one, all alike (and one step is all: the weights do not change).
    """
    F, n_s = b["ET"].shape[0], len(rel_var)
    M = _weighted_sums(b, coef, floor, n_s, noisy)
    P = len(_PAIRS[0])
    m = M.shape[-1] // P  # models fitted: the crosstalk's (and every face's with one), and the faces' own
    M = np.concatenate([M[..., :P], M[..., P:]], axis=1) if m == 2 else M  # the models' rows: (n_s, mF, 18, 15)
    PtWP = np.empty((m * F, 6, N_FEATURES, N_FEATURES))
    PtWP[..., _PAIRS[0], _PAIRS[1]] = M[:, :, :6].sum(axis=0)
    PtWP[..., _PAIRS[1], _PAIRS[0]] = PtWP[..., _PAIRS[0], _PAIRS[1]]
    PtWe = M[:, :, 6:12, :N_FEATURES].sum(axis=0)
    PtWv = M[:, :, 12:, :N_FEATURES].copy()  # per session: response to a relative error of its v
    # a model's feature that too few of its samples have is left out (its coefficient 0): where a face reads
    # a load of its own L is 1 (the constant's), and in a joint fit with a noisy reference q is 0 where the
    # face carries nothing (_features), so the crosstalk's model has only its few smallest own loads for it
    # (its coefficient came out at 10¹⁶⁵)
    off = ~b["support"][:m].reshape(m * F, N_FEATURES)  # (mF, 5)
    PtWP[np.broadcast_to(off[:, None, :, None], PtWP.shape) | np.broadcast_to(off[:, None, None, :], PtWP.shape)] = 0.0
    PtWP[..., np.arange(N_FEATURES), np.arange(N_FEATURES)] += np.broadcast_to(off[:, None, :], PtWe.shape)
    PtWe[np.broadcast_to(off[:, None, :], PtWe.shape)] = 0.0
    PtWv[np.broadcast_to(off[None, :, None, :], PtWv.shape)] = 0.0
    PtWP = PtWP.reshape(6 * m * F, N_FEATURES, N_FEATURES)
    PtWe = PtWe.reshape(6 * m * F, N_FEATURES)
    PtWv = PtWv.reshape(n_s, 6 * m * F, N_FEATURES)
    flat = coef[:m].reshape(6 * m * F, N_FEATURES)  # a view: the fit updates coef
    fit = PtWP[:, 0, 0] > 0
    flat[fit] = _significant_rows(PtWP[fit], PtWe[fit], PtWv[:, fit], rel_var, np.tile(b["unpruned"], m)[fit])


def _correlation(b, coef, floor, floor_m, vref_full, EtE) -> np.ndarray:
    """``corr (F, 6, 6)``: the error's correlation between a face's axes, rows weighted by
    ``(var / (var + v))²``, each row's share of information on the error (1 where the reference
    adds nothing): the residuals' less the reference's (where that is not positive, the gauge noise
    through the matrix where it is), the true wrench's error's.

    With a noisy reference the gauge noise's part ``floor_m`` (measured at rest, exact) keeps its
    own correlation and only the excess over it takes the residuals': the covariance is
    ``floor_m + D^½ R D^½``, ``D`` the modelled variance's mean excess over the floor, ``R`` the
    correlation of the residuals' covariance less the floor. The residuals' own is blurred by the
    reference's noise taken out of them (known to ±8 % from 300 samples at rest): ``loaded_frame``'s
    errors in S_A, forces and torques correlated at ±0.99 that cancel in a face's frame, came out at
    ±0.97, and its face-frame torque intervals covered 98–99 % at 0.1 % reference noise."""
    F = b["ET"].shape[0]
    S, w_sum, V = np.zeros((F, 6, 6)), np.zeros(F), np.zeros((F, 6))
    for j, c in _chunks(b):
        var0 = _variances(c["phT"], coef, floor, rho=c["rho"])
        if b["vT"] is None and np.all(var0 >= 1e-300):  # an exact reference: every weight is 1 (var0 / var0)
            S += np.matmul(c["ET"].copy(), c["ET"].transpose(0, 2, 1))  # a copy: not syrk, the same sums as E · 1
            if np.any(vref_full[j]):
                S -= c["carr"].sum(axis=1)[:, None, None] * vref_full[j]
            w_sum += c["ET"].shape[2]
            continue
        tot = np.maximum(var0 + c["vT"], 1e-300)
        wf = np.divide(var0, tot)
        wf *= wf
        wf = wf.mean(axis=1)  # (F, n)
        S += np.matmul(c["ET"] * wf[:, None, :], c["ET"].transpose(0, 2, 1))
        S -= (wf * c["carr"]).sum(axis=1)[:, None, None] * vref_full[j]
        V += np.einsum("fn,fan->fa", wf, var0)
        w_sum += wf.sum(axis=1)
    corr = np.zeros((F, 6, 6))
    for k in range(F):
        Sk = S[k] / max(w_sum[k], 1e-300)
        if b["vT"] is not None and np.all(np.isfinite(Sk)):  # the floor's own correlation, the excess's (see above)
            ex = _psd(Sk - floor_m[k])
            de = np.sqrt(np.clip(np.diag(ex), 1e-300, None))
            d = np.sqrt(np.clip(V[k] / max(w_sum[k], 1e-300) - np.diag(floor_m[k]), 0.0, None))
            Sk = floor_m[k] + np.outer(d, d) * ex / np.outer(de, de)
        elif np.all(np.isfinite(Sk)) and np.linalg.eigvalsh(0.5 * (Sk + Sk.T))[0] < 0:
            Sk = _psd(Sk - floor_m[k]) + floor_m[k]
        d = np.sqrt(np.clip(np.diag(Sk), 1e-300, None))
        corr[k] = Sk / np.outer(d, d)
        if not np.all(np.isfinite(corr[k])) or np.any(np.diag(Sk) <= 0):
            d = np.sqrt(np.clip(np.diag(EtE[k]), 1e-300, None))
            corr[k] = EtE[k] / np.outer(d, d)
    return corr


def _coverage_scales(b, coef):
    """``(s_load, s_own, s_rest, own_weight)``, each ``(6F,)``: factors on each row's variance so that ±1.96 σ holds
    95 % of its training residuals under load (``coef[0]``'s, where the face reads no load of its own,
    and ``coef[1]``'s, where it does and carries: ``b["own"]``) and at rest.

    Errors are not Gaussian (nonlinearity, drift): the interval, with the reference's noise
    (``b["vT"]``) added, is scaled to cover 95 % of the rows, weighted as in the reweighting:
    the 95 % point of a histogram of ``|E| / σ`` (bins of ``_Z_WIDTH``). With an exact reference
    every weight is 1 (where ``var ≥ 1e-300``): the bin is then that of an order statistic, found
    face by face by a partial sort (:func:`_order_bins`: the same bin, monotone in ``E² / var``).

    ``s_load`` is the loaded samples' (some output face carries a load; the face reads none of its
    own) if their weights add up to :data:`_MIN_INFORMED` rows and :data:`_MIN_SHARE` of their
    number; else every sample's where it reads none (a face that carries on every loaded sample,
    under a reference noise that swamps its error, learns its scale at rest: ``total``'s connected
    face on a random linear sensor, 0.3 %, 200-sample tare, weights 9–804 of about 10,000 rows,
    covered 87.8 % on one axis from its loaded rows, 93.0 % from every row). ``s_own`` is the samples'
    where it reads its own, so informed (``own_weight`` inf; else ``s_load``, and ``own_weight`` the sum of those
    samples' weights). ``s_rest`` is the samples at rest's, where
    their weights add up to :data:`_MIN_REST` rows (else ``s_load``): the errors at rest are the gauge
    noise's, and one scale for both set the intervals at rest by the loaded samples' errors (nonlinear
    cube, exact reference, ``total``: at rest 100 % on every axis).
    """
    q = _order_bins(b, coef) if b["vT"] is None else None
    q_load, q_own, q_rest, own_weight = _hist_bins(b, coef) if q is None else q
    return (*((q * _Z_WIDTH / 1.959964) ** 2 for q in (q_load, q_own, q_rest)), own_weight)


def _support(b) -> np.ndarray:
    """``(2, F, 5)`` bool: the features that :data:`_MIN_INFORMED` or more samples of each model have (not 0):
    the crosstalk's (``ρ = 0``), the face's own (``b["own"]``), L only in the first."""
    phT = b["phT"]
    if not b["split"]:  # one model: every feature as before the split
        out = np.ones((2,) + phT.shape[:2], dtype=bool)
        out[1] = False
        return out
    nz = (phT != 0).astype(np.float32)  # counts by a product: (F, 5, n) @ (F, n, 2)
    out = np.matmul(nz, np.stack([~b["rho"], b["own"]], axis=2).astype(np.float32)).transpose(2, 0, 1) >= _MIN_INFORMED
    out[1, :, 1] = False
    out[:, :, 0] = True
    return out


def _loaded(b) -> np.ndarray:
    """``(n,)`` bool: the kept samples where some output face carries a load."""
    return b["carr"].any(axis=0)


def _classes(b, loaded, cols=slice(None)) -> np.ndarray:
    """``(3, F, n)`` bool of the samples ``cols``: loaded where the face reads no load of its own, at
    rest, loaded where it reads its own and carries (``b["own"]``; the crosstalk it reads as its own
    is in neither)."""
    ld = loaded[cols]
    own = b["own"][:, cols] & ld
    return np.stack([ld & ~b["rho"][:, cols], np.broadcast_to(~ld, own.shape), own])


def _hist_bins(b, coef):
    """``(q_load, q_own, q_rest, own_weight)``, each ``(6F,)``: per row, one more than the first bin of ``|E| / σ``
    where the weighted histogram's cumulative share reaches 95 % (see :func:`_coverage_scales`: each
    class's where it weighs :data:`_MIN_INFORMED` rows and :data:`_MIN_SHARE` of its number, else the
    fallback named there; the samples at rest's where they weigh :data:`_MIN_REST`, else ``q_load``),
    and the own samples' weight where it is short of that (inf where it is not)."""
    F = b["ET"].shape[0]
    R = 6 * F
    hist = np.zeros((3, R * (_Z_N + 1)))  # per class of _classes
    offset = np.arange(R)[:, None] * (_Z_N + 1)
    loaded = _loaded(b)
    for _, c in _chunks(b):
        var = _variances(c["phT"], coef, rho=c["rho"]).reshape(R, -1)  # (6F, n)
        v_ref = c["vT"] if b["vT"] is None else c["vT"].reshape(R, -1)
        w = np.maximum(var + v_ref, 1e-300)
        np.divide(var, w, out=w)
        w *= w  # each row's share of information on the error
        # the scale s with |E| ≤ 1.96·√(s·var + v_ref) on 95 % of rows (E holds the reference's
        # noise, the interval is of the true wrench): each row needs s ≥ z²/1.96² with
        E = c["ET"].reshape(R, -1)
        z = E * E
        z -= 1.959964**2 * v_ref
        np.maximum(z, 0, out=z)
        z /= np.maximum(var, 1e-300, out=var)
        bins = _z_bins(z)
        bins += offset
        for i, cls in enumerate(_classes(b, loaded, c["cols"])):
            if i == 2 and not cls.any():  # no face reads a load of its own here
                continue
            hist[i] += np.bincount(bins.ravel(), weights=(w * np.repeat(cls, 6, axis=0)).ravel(), minlength=hist.shape[1])
    hist = hist.reshape(3, R, _Z_N + 1)
    w_sum = hist.sum(axis=2)
    n_cls = np.repeat(_classes(b, loaded).sum(axis=2), 6, axis=1)  # (3, 6F)
    informed = (w_sum >= _MIN_INFORMED) & (w_sum >= _MIN_SHARE * n_cls)
    q_load = _first_bin(np.where(informed[0][:, None], hist[0], hist[0] + hist[1]))
    q_own = np.where(informed[2], _first_bin(hist[2]), q_load)
    # the own samples' weight where they inform the scale (inf), else their weight
    own_weight = np.where(informed[2], np.inf, w_sum[2])
    return q_load, q_own, np.where(w_sum[1] >= _MIN_REST, _first_bin(hist[1]), q_load), own_weight


def _first_bin(hist) -> np.ndarray:
    """Per row of ``hist (R, _Z_N + 1)``, one more than the first bin where the cumulative share reaches 95 %."""
    cdf = np.cumsum(hist, axis=1) / np.clip(hist.sum(axis=1, keepdims=True), 1, None)
    return np.argmax(cdf >= 0.95, axis=1) + 1


def _z_bins(z2) -> np.ndarray:
    """The histogram bin (0.._Z_N) of each ``z² = E² / var``: ``⌊√z² / _Z_WIDTH⌋``, at most ``_Z_N``."""
    z = np.sqrt(z2)
    z /= _Z_WIDTH
    np.minimum(z, _Z_N, out=z)
    return z.astype(np.int64)


def _order_bins(b, coef):
    """:func:`_hist_bins` with every weight 1 (an exact reference; None where some ``var < 1e-300``
    gives a weight below 1): ``(q_load, q_own, q_rest, own_weight)``, per row the bin of the ``m``-th smallest
    ``z² = E² / var`` of each class's samples (with the fallbacks of :func:`_coverage_scales`), ``m``
    the least count whose share ``m / n`` (as the histogram computes it) reaches 95 %. Face by face,
    each over all its samples at once (in chunks, 6.7 of a fit's 81 ms)."""
    F, _, n = b["ET"].shape
    loaded = _loaded(b)
    rest = ~loaded
    n_rest = int(rest.sum())
    C = coef.reshape(2, F, 6, N_FEATURES)
    out = np.empty((3, F, 6), dtype=np.int64)
    z2 = np.empty((6, n))
    for f in range(F):  # a face at a time: the working memory of one face's rows
        var = C[0, f] @ b["phT"][f]  # (6, n)
        rho = b["rho"][f]
        split = rho.any()
        if split:
            var[:, rho] = C[1, f] @ b["phT"][f].compress(rho, axis=1)  # C-ordered (not [:, rho]): 23 against 63 µs, the same
        if not np.all(var >= 1e-300):
            return None
        other = loaded & ~rho if split else loaded
        own = loaded & b["own"][f] if split else None
        uses = [other if other.sum() >= _MIN_INFORMED else other | rest,
                own if split and own.sum() >= _MIN_INFORMED else None,
                rest if n_rest >= _MIN_REST else None]
        if uses[0].sum() == 0:
            return None
        np.multiply(b["ET"][f], b["ET"][f], out=z2)
        z2 /= var
        for i, use in enumerate(uses):
            if use is None:
                out[i, f] = out[0, f]
                continue
            k = int(use.sum())
            m = _order_count(k)
            # compress, not z2[:, use] (a column-major copy, partitioned along its strided rows), and partitioned
            # in place: 106 against 315 µs for a face's 6 rows of 9,300 of 10⁴ samples, the same values
            sel = z2.compress(use, axis=1) if k < n else z2.copy()
            sel.partition(m - 1, axis=1)
            out[i, f] = _z_bins(sel[:, m - 1]) + 1
    q = out.reshape(3, -1)
    return q[0], q[1], q[2], np.full(q.shape[1], np.inf)


def _order_count(n) -> int:
    """The least ``m`` with ``m / n`` ≥ 95 % as the histogram's cumulative share computes it."""
    m = int(np.ceil(0.95 * n))
    while m > 1 and (m - 1) / n >= 0.95:
        m -= 1
    while m / n < 0.95:
        m += 1
    return m


def _strided(blocks, stride):
    """Every ``stride``-th sample of each block (the blocks themselves when ``stride`` is 1)."""
    for b in blocks:
        yield b if stride == 1 else SessionBlock(b.start, b.counts[::stride], b.reference[::stride], b.loaded[::stride])


def _predict(cal, x):
    """``(x Cᵀ, rows)``, both ``(n, 6F)``: the linear part and the calibration's rows (output frame) for
    offset-free counts ``x (n, 36)`` (the same array without a correction)."""
    xC = x @ cal.matrix.T
    return xC, (xC if cal.correction is None else xC + cal.correction(x))


def _features(cal, x, idx, xA=None, carries=None, unloaded=None):
    """``(phi, q)``: ``load_features`` of the output faces ``idx`` (0-based) for offset-free counts ``x (n, 36)``:
    (n, F, 5) (the faces without output count 0 in ``q_other``, as NaN faces there), and each face's ``q (n, F)``
    as read in use (not masked by ``carries``; 0 where ``unloaded``). ``xA`` (overwritten), if
    given, is the product ``x Aᵀ`` of the output faces' maps ``A`` (the matrix itself in the face frame).

    ``carries (n, F)``, if given: a face where it is False counts 0. Where a face carries nothing
    its predicted wrench is its error (the target is 0), so ``q`` is ``E²`` itself; with a noisy
    reference those rows (no reference noise) outweigh the carrying ones by ``(v / var)²`` in the
    fit, and where the fit had those rows (a joint fit: the residual is in-sample, at the gauge
    noise) the ``q`` term fitted to that identity went to the loaded samples (``loaded_frame``,
    linear cube, 3 %: face 6's fz interval 18× the error). Faces fitted on their own rows only
    (``face_to_face``) keep it: there the predicted wrench is the crosstalk the fit never saw. So do
    faces with a polynomial correction (``quasi_total``, nonlinear cube, 3 %: 25 of 30 axes outside
    93–97 % with it, 28 without, all too short).

    ``unloaded (n,)``, if given: the samples no face was loaded in (the session's flags), where
    every load feature is 0 (``L`` 1 elsewhere), as after a tare. From the predicted load they are
    not: at the fitted offset of a nonlinear cube's fit the wrench at rest is not 0
    (``face_to_face``, a cube with 15 % saturation: ``L`` up to 0.07 at rest, and ``q`` ~10⁻³, whose
    terms then set the scale at rest, read after a tare without them: intervals 0.2× the error)."""
    if xA is None:
        A = cal._apply.reshape(6, 6, 36)[idx].reshape(-1, 36)  # rows: the output faces' wrench components
        xA = x @ A.T
    np.multiply(xA, xA, out=xA)
    q = xA @ np.kron(np.eye(len(idx)), FULL_SCALE[:, None] ** -2.0)  # Σ (w / FS)² per face: one product, 4× an einsum
    if unloaded is not None:
        q[unloaded] = 0.0
    return _load_phi(q, carries, unloaded), q


def _load_phi(q, carries=None, unloaded=None) -> np.ndarray:
    """``(n, F, 5)`` :func:`_features`' features from each face's ``q (n, F)`` as read in use (0 where ``unloaded``),
    ``q`` counted where ``carries`` (None: everywhere) and ``L`` the flags' where ``unloaded`` is given."""
    phi = q_features(q if carries is None else q * carries)
    if unloaded is not None:
        phi[..., 1] = ~unloaded[:, None]
    return phi


def _corrected_rows(cal, by_face: bool = False) -> np.ndarray:
    """``(6F,)`` bool: the matrix rows with a polynomial correction (with ``by_face``, every row of a
    face that has one: the error model of a fit in S_A is in the faces' frames, where each row mixes
    the face's S_A rows). Their load terms are not pruned (:func:`_significant_nnls`): the correction
    absorbs part of its rows' misfit in training, and where the face carries the excess left hid
    under the 3-σ test (``quasi_total``, nonlinear cube, 0.33 % reference noise, 2000-sample tare:
    75.8–84.1 % coverage on the weakest axis of four faces where they carry, 95 % elsewhere)."""
    F = len(cal.output_faces)
    if cal.correction is None:
        return np.zeros(6 * F, dtype=bool)
    rows = np.any(cal.correction.coef != 0, axis=1)
    return np.repeat(rows.reshape(F, 6).any(axis=1), 6) if by_face else rows


def _corrected(cal) -> np.ndarray:
    """``(F,)`` bool: the output faces with a polynomial correction."""
    return _corrected_rows(cal).reshape(-1, 6).any(axis=1)

"""The error model behind a calibration's covariance: passes 3 and 4 over the training data.

Pass 3 computes every usable training sample's residual with the fitted matrix and
accumulates (a) each output's squared residual against ``load_features`` (the variance a
new sample brings itself), (b) the residuals' correlation between a face's six axes, and
(c) the scores ``Aᵀ E`` of clusters of consecutive samples (the cluster-robust inflation of
the coefficients' variance). Pass 4 scales each output's variance so that ±1.96 σ holds
95 % of its training residuals (the errors are not Gaussian). See docs/calibration.md,
"Uncertainty".
"""

from __future__ import annotations

import numpy as np
import scipy.optimize

from ..io import SessionBlock
from ._targets import block_targets
from ._uncertainty import N_FEATURES, load_features

__all__ = ["fit_error_model", "N_CLUSTERS"]

#: Clusters of consecutive samples for the cluster-robust variance of the coefficients:
#: few and long, so that errors correlated over a loading gesture stay within one.
N_CLUSTERS = 16
#: The error model reads about this many samples (every n-th of each block beyond it): its
#: figures are averages over the data, which a uniform subsample estimates closely.
ERROR_MODEL_SAMPLES = 10_000
#: Bins of |residual| / σ for the coverage calibration of the error model (pass 4): width, count.
_Z_WIDTH, _Z_N = 0.005, 4000


def _reference_variance(mount, ref_cov, output_frame, carries, idx) -> np.ndarray:
    """``(n, F, 6)`` variance the reference's own noise puts into each target (0 where a face carries nothing)."""
    if ref_cov is None:
        return np.zeros((carries.shape[0], len(idx), 6))
    if output_frame == "face":
        V = np.einsum("fij,jk,fik->fi", mount.X_face_ati, ref_cov, mount.X_face_ati)  # (6, 6)
    else:
        V = np.broadcast_to(np.diag(ref_cov), (6, 6))
    return carries[:, idx, None] * V[idx][None]


def fit_error_model(cal, sessions, mounts, offsets, tare_means, spec, groups, block_size, ref_covs=None,
                    gauge_cov=None, samples=None):
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
    by the fit's own pass) spares the two passes over the sessions.
    """
    F = len(cal.output_faces)
    idx = [f - 1 for f in cal.output_faces]
    n_int = len(sessions)
    stride = max(1, sum(len(s) for s in sessions) // ERROR_MODEL_SAMPLES)
    own_face = {id(g): (cal.output_faces[int(g.rows[0]) // 6] if g.inputs.size == 6 else None) for g in groups}
    clusters = {id(g): dict(score=np.zeros((g.design_pinv.shape[0], g.rows.size)), n=0,
                            meat=np.zeros(g.rows.size), length=max(50, -(-g.dof // (N_CLUSTERS * stride)))) for g in groups}
    PtP = np.zeros((F, N_FEATURES, N_FEATURES))
    Pte2 = np.zeros((F, N_FEATURES, 6))
    EtE = np.zeros((F, 6, 6))
    ref_covs = [None] * len(sessions) if ref_covs is None else ref_covs
    floor = np.zeros(6 * F) if gauge_cov is None else np.einsum("ia,ab,ib->i", cal.matrix, gauge_cov, cal.matrix)
    for j, (s, mount, o, rc) in enumerate(zip(sessions, mounts, offsets, ref_covs)):
        for b in (_strided(s.iter_blocks(block_size), stride) if samples is None else samples[j]):
            targets, carries, usable, _ = block_targets(b.reference, b.loaded, mount, spec.output_frame)
            x = b.counts[usable] - o
            Y = _predict(cal, x).reshape(-1, F, 6)
            E = targets[usable][:, idx] - Y
            phi = _features(cal, x, idx)  # (n, F, 4)
            E2 = E * E - _reference_variance(mount, rc, spec.output_frame, carries[usable], idx) - floor.reshape(F, 6)
            for k in range(F):
                PtP[k] += phi[:, k].T @ phi[:, k]
                Pte2[k] += phi[:, k].T @ E2[:, k]
                EtE[k] += E[:, k].T @ E[:, k]
            Eflat = E.reshape(-1, 6 * F)
            unloaded = ~b.loaded[usable].any(axis=1)
            for g in groups:
                cl = clusters[id(g)]
                f = own_face[id(g)]
                rows = slice(None) if f is None else (carries[usable][:, f - 1] | unloaded)
                A = np.zeros((x[rows].shape[0], n_int + g.inputs.size))
                A[:, j] = 1.0
                A[:, n_int:] = b.counts[usable][rows][:, g.inputs] - tare_means[j][g.inputs]
                Eg = Eflat[rows][:, g.rows]
                a = 0
                while a < A.shape[0]:  # clusters of consecutive samples, across blocks
                    take = min(A.shape[0] - a, cl["length"] - cl["n"])
                    cl["score"] += A[a : a + take].T @ Eg[a : a + take]
                    cl["n"] += take
                    a += take
                    if cl["n"] >= cl["length"]:
                        sc = cl["score"]
                        cl["meat"] += np.einsum("pj,pq,qj->j", sc, g.design_pinv, sc)
                        cl["score"] = np.zeros_like(sc)
                        cl["n"] = 0
    for g in groups:
        cl = clusters[id(g)]
        sc = cl["score"]
        cl["meat"] += np.einsum("pj,pq,qj->j", sc, g.design_pinv, sc)
        rank = max(int(np.linalg.matrix_rank(g.design_pinv, hermitian=True)), 1)
        var = np.clip(np.diag(g.residual_cov), 1e-300, None)
        # the scores are sums over every stride-th sample: × stride for the full data's (independent errors)
        g.inflation = np.maximum(1.0, stride * cl["meat"] / (rank * var))
    coef = np.zeros((6 * F, N_FEATURES))
    corr = np.zeros((F, 6, 6))
    for k in range(F):
        scale = np.sqrt(np.clip(np.diag(PtP[k]), 1e-300, None))
        G = PtP[k] / np.outer(scale, scale)
        w, V = np.linalg.eigh(G)
        keep = w > 1e-10 * w[-1]
        R = (V[:, keep] * np.sqrt(w[keep])).T  # G = Rᵀ R
        for a in range(6):
            rhs = (V[:, keep].T @ (Pte2[k, :, a] / scale)) / np.sqrt(w[keep])
            c, _ = scipy.optimize.nnls(R, rhs)
            coef[6 * k + a] = c / scale
        d = np.sqrt(np.clip(np.diag(EtE[k]), 1e-300, None))
        corr[k] = EtE[k] / np.outer(d, d)
    coef[:, 0] += floor
    # pass 4: errors are not Gaussian (nonlinearity, drift): scale each row's variance so
    # that ±1.96 σ (with the reference's noise added) holds 95 % of its training residuals
    hist = np.zeros((6 * F, _Z_N + 1))
    rows = np.arange(6 * F)
    for j, (s, mount, o, rc) in enumerate(zip(sessions, mounts, offsets, ref_covs)):
        for b in (_strided(s.iter_blocks(block_size), stride) if samples is None else samples[j]):
            targets, carries, usable, _ = block_targets(b.reference, b.loaded, mount, spec.output_frame)
            x = b.counts[usable] - o
            E = (targets[usable][:, idx] - _predict(cal, x).reshape(-1, F, 6)).reshape(-1, 6 * F)
            v_ref = _reference_variance(mount, rc, spec.output_frame, carries[usable], idx).reshape(-1, 6 * F)
            phi = _features(cal, x, idx)
            var = np.concatenate([phi[:, k] @ coef[6 * k : 6 * k + 6].T for k in range(F)], axis=1)  # (n, 6F)
            # the scale s with |E| ≤ 1.96·√(s·var + v_ref) on 95 % of rows (E holds the reference's
            # noise, the interval is of the true wrench): each row needs s ≥ z²/1.96² with
            z = np.sqrt(np.clip(E * E - 1.959964**2 * v_ref, 0, None) / np.clip(var, 1e-300, None))
            bins = np.minimum(z / _Z_WIDTH, _Z_N).astype(np.int64) + rows * (_Z_N + 1)
            hist += np.bincount(bins.ravel(), minlength=hist.size).reshape(hist.shape)
    cdf = np.cumsum(hist, axis=1) / np.clip(hist.sum(axis=1, keepdims=True), 1, None)
    q95 = (np.argmax(cdf >= 0.95, axis=1) + 1) * _Z_WIDTH
    coef *= ((q95 / 1.959964) ** 2)[:, None]
    return coef, corr


def _strided(blocks, stride):
    """Every ``stride``-th sample of each block (the blocks themselves when ``stride`` is 1)."""
    for b in blocks:
        yield b if stride == 1 else SessionBlock(b.start, b.counts[::stride], b.reference[::stride], b.loaded[::stride])


def _predict(cal, x) -> np.ndarray:
    """``(n, 6F)`` the calibration's rows (output frame) for offset-free counts ``x (n, 36)``."""
    Y = x @ cal.matrix.T
    if cal.correction is not None:
        Y += cal.correction(x)
    return Y


def _features(cal, x, idx) -> np.ndarray:
    """``load_features`` of the output faces ``idx`` (0-based) for offset-free counts ``x (n, 36)``: (n, F, 4)."""
    A = cal._apply.reshape(36, 36)  # rows: face-major wrench components
    Wf = np.full((x.shape[0], 6, 6), np.nan)
    Wf[:, idx] = (x @ A.T).reshape(-1, 6, 6)[:, idx]
    return load_features(Wf)[:, idx]

"""The reference's noise in the fitted coefficients, face by face (part of the error model).

Face k's targets hold the reference's noise only on the samples where face k carries the
reference's load (the carrying rows); elsewhere its target is an exact zero. The fit's
residual covariance ``Σ_r`` spreads that noise over every row of the design, so the
coefficients' term ``(x̃ᵀ P x̃) Σ_r`` gave it to every sample alike: too little where face k
carries, too much where it does not. Here it is taken apart: the reference's share,
``(x̃ᵀ P M_k P x̃) Σ_ref,k`` with ``M_k = Σ x̃ x̃ᵀ`` over face k's carrying rows, is stored with
each group (large where face k carries, small elsewhere: the load features could not tell
the two apart), and the groups' own term keeps ``Σ_e``, the error model's (``Σ_r`` less the
reference's share is no estimate of it: the difference is far below the share's uncertainty).
The error model takes the share out of the training residuals where the face carries nothing
(:meth:`ReferenceLeverage.in_sample`; the offsets' share goes with each session's mean residual
at rest, ``_residuals._retared``). See docs/calibration.md, "Uncertainty".
"""

from __future__ import annotations

import warnings

import numpy as np

from ..defaults import TARE_STILL_FORCE_STD_N, TARE_STILL_TORQUE_STD_NM
from ._uncertainty import PolyReferenceBlock

__all__ = ["ReferenceLeverage", "is_range", "NoisyReferenceWarning", "reference_noise_at_rest"]


class ReferenceLeverage:
    """Sums ``M_k`` of the design over each face's carrying rows, fed block by block.

    Parameters
    ----------
    groups : list of CovarianceGroup
    output_faces : tuple of int
    n_int : int
        Sessions (offset columns of the design).
    """

    def __init__(self, groups, output_faces, n_int):
        self.groups, self.n_int = groups, n_int
        self.out = {f: k for k, f in enumerate(output_faces)}
        self.own = [output_faces[int(g.rows[0]) // 6] if g.inputs.size == 6 else None for g in groups]
        self.kk = [[int(g.rows[6 * b]) // 6 for b in range(g.rows.size // 6)] for g in groups]
        self.M = [np.zeros((len(kk), n_int + g.inputs.size, n_int + g.inputs.size)) for g, kk in zip(groups, self.kk)]
        self.n = [np.zeros((len(kk), n_int)) for kk in self.kk]
        self.rows = []  # per block: counts (n, 36) float32, session, its tare mean, carries (n, F), unloaded (n,)
        self.poly, self.correction = [], None

    def set_poly(self, parts, correction) -> None:
        """The polynomial correction's parts (``PolyAccumulator.reference_parts``): its rows take
        their coefficients' share from it, not from the affine design."""
        self.poly, self.correction = list(parts), correction

    def poly_blocks(self, vref_full) -> list:
        """The correction's :class:`PolyReferenceBlock` of each corrected face, ``Σ_ref`` pooled over
        the sessions by its carrying rows (after :meth:`finish`)."""
        out = []
        for p in self.poly:
            w = p["carry_n"] / max(p["carry_n"].sum(), 1)
            S = sum(w[j] * vref_full[j][p["block"]] for j in range(self.n_int))
            out.append(PolyReferenceBlock(p["block"], p["rows"], p["cols"], p["leverage"], S))
        return out

    def add(self, counts, carries, unloaded, j, tare_mean) -> None:
        """One block's usable samples: ``counts (n, 36)``, ``carries (n, F)`` of the output faces, ``unloaded (n,)``."""
        for g, own, kk, M, n in zip(self.groups, self.own, self.kk, self.M, self.n):
            rows = slice(None) if own is None else carries[:, self.out[own]] | unloaded
            A = self._design(g, counts[rows], j, tare_mean)
            for b, k in enumerate(kk):
                c = carries[rows, k]
                if c.any():
                    M[b] += A[c].T @ A[c]
                    n[b, j] += np.count_nonzero(c)
        self.rows.append((counts.astype(np.float32), j, tare_mean, carries, unloaded))

    def _design(self, g, counts, j, tare_mean) -> np.ndarray:
        """The group's design rows ``[session indicator | counts − tare mean]`` (as in the fit)."""
        A = np.zeros((counts.shape[0], self.n_int + g.inputs.size))
        A[:, j] = 1.0
        if is_range(g.inputs, counts.shape[1]):  # all gauges: no copies
            np.subtract(counts, tare_mean, out=A[:, self.n_int :])
        else:
            A[:, self.n_int :] = counts[:, g.inputs] - tare_mean[g.inputs]
        return A

    def pooled(self, vref_full) -> list:
        """Per group, ``(B, 6, 6)``: each face block's reference covariance, pooled over the sessions by carrying rows."""
        out = []
        for kk, n in zip(self.kk, self.n):
            w = n / np.clip(n.sum(axis=1, keepdims=True), 1, None)
            out.append(np.stack([sum(w[b, j] * vref_full[j][k] for j in range(self.n_int)) for b, k in enumerate(kk)]))
        return out

    def set_error_cov(self, variances, corr, X=None) -> None:
        """``Σ_r → Σ_e``: each group's residual covariance (its face blocks) becomes the mean, over the
        group's design rows, of the error model's covariance (``variances(i)``, of block ``i`` of :meth:`add`,
        ``(n, 6F)`` each row's modelled variance; ``corr (F, 6, 6)``): the error that is not the
        reference's. ``X (F, 6, 6)``: the error model is in the faces' frames, mapped back to the
        output frame by ``X⁻¹``."""
        for g, own, kk in zip(self.groups, self.own, self.kk):
            R = g.residual_cov.copy()
            for b, k in enumerate(kk):
                acc, n = np.zeros((6, 6)), 0
                for i, (_, _, _, carries, unloaded) in enumerate(self.rows):
                    rows = slice(None) if own is None else carries[:, self.out[own]] | unloaded
                    sd = np.sqrt(np.clip(variances(i)[rows, 6 * k : 6 * k + 6], 0, None))
                    acc += sd.T @ sd
                    n += sd.shape[0]
                S = corr[k] * acc / max(n, 1)
                if X is not None:
                    Xi = np.linalg.inv(X[k])
                    S = Xi @ S @ Xi.T
                R[6 * b : 6 * b + 6, 6 * b : 6 * b + 6] = S
            g.residual_cov = R

    def finish(self, stride, vref_full) -> None:
        """Give each group the reference's share of its coefficients' covariance, face block by face block.

        ``reference_leverage (B, p, p) = P M_k P`` (``M_k`` over the full data: the subsample's
        sums × ``stride``) and ``reference_cov (B, 6, 6)``, the reference's covariance in each
        block's output frame pooled over the sessions by carrying rows: a sample's share is
        ``(x̃ᵀ P M_k P x̃) Σ_ref,k`` (:meth:`CovarianceGroup.reference_leverages`).
        """
        for g, M, S in zip(self.groups, self.M, self.pooled(vref_full)):
            P = g.design_pinv
            g.reference_leverage = stride * (P @ M @ P)
            g.reference_cov = S

    def offset_var(self, F, X=None) -> list:
        """Per session, ``(6F,)`` the variance of its fitted offsets' error from the reference's noise
        (after :meth:`finish`): the offset's diagonal of each block's ``reference_leverage`` times the
        reference's variance, in the faces' frames with ``X (F, 6, 6)``."""
        out = []
        for j in range(self.n_int):
            var = np.zeros((F, 6))
            for g, kk in zip(self.groups, self.kk):
                for b, k in enumerate(kk):
                    Xk = np.eye(6) if X is None else X[k]
                    var[k] = g.reference_leverage[b, j, j] * np.diagonal(Xk @ g.reference_cov[b] @ Xk.T)
            out.append(var.reshape(-1))
        return out

    def in_sample(self, F, vref_full, X=None, gauge_cov=None) -> list:
        """Per block of :meth:`add`, ``(share, own)``, both ``(n, 6F)`` float32 (after :meth:`finish`).

        ``share``: the reference's share of the coefficients' variance at each training sample,
        ``(x̃ᵀ P M_k P x̃) diag Σ_ref,k``. A sample where face k carries nothing has it in its
        residual all the same (the fitted slopes hold the noise of the other rows): the error
        model takes it out there as it takes the reference's own noise out where the face carries.
        (The offsets' share is one number per session and output, taken out of every residual with
        the session's mean residual at rest: ``_residuals._retared``.)

        ``own``: where face k carries, the factor on the reference's own variance ``v`` in the
        residual: ``1`` for the affine rows; ``1 − 2h + q`` for the correction's (``h`` the fit's
        hat, ``q`` the share's leverage): a fit with many features absorbs its rows' own noise,
        ``E[E²] = e² + v (1 − 2h) + q v``.

        With ``gauge_cov (36, 36)`` the share leaves out what the samples' gauge noise brings to ``x̃ᵀ
        P M_k P x̃`` (:meth:`CovarianceGroup.noise_leverages`; at least 0): the residuals hold that part
        in the gauge noise through the fitted matrix, the error model's floor (at rest, ``quasi_total``
        on a linear cube at 0.33 %, face 5's tx: a share 2× the residuals' whole mean square).

        ``X (F, 6, 6)``: both in the faces' frames (the error model's for a fit in S_A): the share's
        covariance and the carrying rows' ``(1 − 2h + q)``-scaled one mapped by ``X``, ``own`` as the
        ratio of the latter's diagonal to ``v``'s.
        """
        out = []
        cov = np.zeros((F, 6, 6))  # each face block's (pooled) covariance of the reference's noise
        for g, kk in zip(self.groups, self.kk):
            cov[kk] = g.reference_cov
        poly = {p["block"]: p for p in self.poly}
        for counts, j, tare_mean, _, _ in self.rows:
            n = counts.shape[0]
            h = np.zeros((n, F))  # the affine design's leverage x̃ᵀ P M_k P x̃ of each face block
            x = counts.astype(float)
            for g, kk in zip(self.groups, self.kk):
                # slopes: the offsets' share is taken out apart
                B = x - tare_mean if is_range(g.inputs, x.shape[1]) else x[:, g.inputs] - tare_mean[g.inputs]
                Q = g.reference_leverage[:, self.n_int :, self.n_int :]  # (nb, m, m)
                nb, m = Q.shape[0], Q.shape[1]
                BQ = (B @ Q.transpose(1, 0, 2).reshape(m, nb * m)).reshape(-1, nb, m)  # every face block in one product
                BQ *= B[:, None, :]
                h[:, kk] = BQ.sum(axis=2)
                if gauge_cov is not None:
                    h[:, kk] = np.maximum(h[:, kk] - g.noise_leverages(gauge_cov), 0.0)
            z = None
            if poly:
                xt = x - tare_mean
                z = np.concatenate([xt / self.correction.scale, self.correction.features(xt)], axis=1)
            v, own = np.zeros((n, F, 6)), np.ones((n, F, 6))
            for k in range(F):
                p = poly.get(k)
                r = np.zeros(6, dtype=bool) if p is None else p["rows"]
                S = np.where(np.outer(~r, ~r), cov[k], 0.0)  # the affine rows' share (the correction's: below)
                Xk = np.eye(6) if X is None else X[k]
                v[:, k] = h[:, k, None] * np.diagonal(Xk @ S @ Xk.T)[None]
                if p is not None:
                    self._poly_rows(p, z, vref_full[j][k], Xk, v[:, k], own[:, k])
            out.append((v.reshape(-1, 6 * F).astype(np.float32), own.reshape(-1, 6 * F).astype(np.float32)))
        return out

    @staticmethod
    def _poly_rows(p, z, V, Xk, v, own) -> None:
        """The correction's rows of a face block, in the frame ``Xk (6, 6)`` maps to: its share
        into ``v (n, 6)`` and ``own (n, 6)`` (see :meth:`in_sample`); ``z (n, 198)`` the samples'
        design, ``V (6, 6)`` the reference's noise. A row group's ``q`` and ``1 − 2h + q`` scale its
        rows of ``V`` (forces–torques by the geometric mean)."""
        zc = z[:, p["cols"]]
        q, keep = np.zeros((zc.shape[0], 6)), np.ones((zc.shape[0], 6))
        for g, rows in ((0, slice(0, 3)), (1, slice(3, 6))):
            if p["rows"][3 * g]:
                q[:, rows] = np.einsum("ni,ni->n", zc @ p["leverage"][g], zc)[:, None]
                h = np.einsum("ni,ni->n", zc @ p["hat"][g], zc)
                keep[:, rows] = np.maximum(1.0 - 2.0 * h + q[:, 3 * g], 0.0)[:, None]
        r = p["rows"]
        a, b = np.sqrt(q), np.sqrt(keep)
        Vr = np.where(np.outer(r, r), V, 0.0)
        d = np.clip(np.diagonal(Xk @ V @ Xk.T), 1e-300, None)
        for i in range(Xk.shape[0]):  # row i of Xk T Xkᵀ, T = V ∘ (a aᵀ): the quadratic form a (x_i x_iᵀ ∘ V) aᵀ
            xx = np.outer(Xk[i], Xk[i])
            v[:, i] += np.einsum("nj,nj->n", a @ (xx * Vr), a)
            own[:, i] = np.einsum("nj,nj->n", b @ (xx * V), b) / d[i]


def is_range(ix, n) -> bool:
    """Whether the indices ``ix`` are ``0, 1, …, n − 1`` (then a view replaces the copy they would take)."""
    return ix.size == n and bool(np.all(ix == np.arange(n)))


class NoisyReferenceWarning(UserWarning):
    """The reference's noise at rest is above the limits the 95 % intervals were checked within."""


def reference_noise_at_rest(ref_covs, ref_n) -> dict:
    """The reference's noise at rest in the calibration's ``meta``, with a :class:`NoisyReferenceWarning` where
    it is above the tare's stillness limits (``pito_core.defaults``; 0.33 % and 0.5 % of the simulated cubes'
    full scale, 15 N and 0.1 N·m). The intervals' coverage was checked up to those: the wizard refuses a tare
    above them, a session recorded elsewhere is fitted all the same. Above them the reference's noise swamps
    the calibration's own error and the training data cannot tell its shape: at 1–3 % some axes' intervals
    fall short where the face carries (docs/calibration.md, "Uncertainty").

    ``ref_covs``: per session, the reference's covariance at rest ``(6, 6)`` (N², N²·m, N²·m²) from ``ref_n``
    samples. Returns ``{"force_std_N": [...], "torque_std_Nm": [...], "within_limits": bool}``, per session the
    largest standard deviation of its force and torque axes (as the tare's check reads them); a session is
    above a limit when its figure is, less 3 of its standard errors (``σ / √(2(n − 1))``): a reference at
    0.33 % of 15 N (0.0495 N) measured 0.0500 N in some of 2000 samples at rest.
    """
    sd = [np.sqrt(np.clip(np.diagonal(np.asarray(c, float)), 0.0, None)) for c in ref_covs]
    force, torque = [float(d[:3].max()) for d in sd], [float(d[3:].max()) for d in sd]
    low = [1.0 - 3.0 / np.sqrt(2.0 * max(n - 1, 1)) for n in ref_n]  # the figures' lower bounds, relative
    over = [k for k, (f, t, a) in enumerate(zip(force, torque, low))
            if a * f >= TARE_STILL_FORCE_STD_N or a * t >= TARE_STILL_TORQUE_STD_NM]
    for k in over:
        warnings.warn(
            f"sessions[{k}].reference: its noise at rest is {force[k]:.3f} N, {torque[k] * 1000:.2f} mN·m (largest axis "
            f"standard deviation), above the tare's stillness limits ({TARE_STILL_FORCE_STD_N} N, "
            f"{TARE_STILL_TORQUE_STD_NM * 1000:g} mN·m) that the 95 % intervals were checked within; the fit is "
            "made, but where a face carries its intervals may be short (docs/calibration.md, \"Uncertainty\")",
            NoisyReferenceWarning, stacklevel=5)
    return {"force_std_N": force, "torque_std_Nm": torque, "within_limits": not over}

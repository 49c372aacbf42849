"""Uncertainty of a fitted calibration, and its propagation to each sample's face wrenches.

The fit is a linear regression of the targets on the design ``x̃ = [a; s − m]`` (one
offset column per session, ``a`` its weights, then the counts ``s`` less a centring
``m``), solved by least squares. With the residual covariance ``Σ_r`` of the outputs
(from the residuals ``E`` of the fit, ``EᵀE / (n − p)``) and ``P = (XᵀX)⁺`` of the
design, the fitted coefficients have ``Cov(vec C) = Σ_r ⊗ P`` and a prediction
``ŵ = C x̃`` has

    Cov(ŵ) = (x̃ᵀ P x̃) Λ^½ Σ_r Λ^½  +  Σ_e(load)

The first term is the calibration's own error (the coefficients' covariance; ``Λ`` ≥ 1
per output corrects it for residuals that are correlated over consecutive samples, by
a cluster-robust estimate). The
second is the error a new sample brings itself — its gauge noise, and whatever the
linear model misses (nonlinearity, drift), which grows with the load: a sample's
residual holds exactly these, so ``Σ_e`` is fitted to the residuals of the training
samples (a second pass over the data): each output's variance as a combination of
``[1, L, q, q², q_other]`` — ``q = ‖ŵ_face / full scale‖²`` the face's own predicted load,
``q_other`` that of the other faces (crosstalk a method does not model), ``L`` 0 at rest and 1
under any load (:data:`LOAD_Q`) — with the residuals' correlation between the six axes of a face. After
:meth:`Calibration.tare` with n samples the offset is no longer the fitted one: ``x̃``
is the counts less the new offset (slopes only) and the tare's own noise
``G / n = C Σ_g Cᵀ / n`` is added (``Σ_g`` the gauge noise at rest). Outputs fitted in
the reference frame S_A are mapped to each face's frame by the wrench adjoint.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["CovarianceGroup", "PolyReferenceBlock", "CalibrationCovariance", "load_features", "q_features", "N_FEATURES",
           "LOAD_Q", "upgraded_variance_coef", "own_load",
           "FULL_SCALE"]

#: Full-scale loads that make a wrench dimensionless, ``[fx … tz]`` in N and N·m.
FULL_SCALE = np.array([15.0, 15.0, 15.0, 0.1, 0.1, 0.1])
#: Features of the error-variance model: ``[1, L, q, q², q_other]``.
N_FEATURES = 5
#: The load ``Q`` (sum of every face's ``q``) at which ``L = 1 − exp(−(Q / LOAD_Q)³)`` is 63 %: 5 % of
#: full scale on one axis (0.75 N, 5 mN·m). The gauge noise's ``Q`` at rest is ~10⁻⁶ of it, so ``L``
#: there is ~10⁻¹⁸: with ``Q`` itself (``L`` ~10⁻³ at rest), an error of 0.2 N² under load still made
#: the intervals at rest 100× too wide (nonlinear cube, ``total``).
LOAD_Q = 0.05**2


def load_features(face_wrenches: np.ndarray) -> np.ndarray:
    """``(N, 6, 5)`` features ``[1, L, q, q², q_other]`` of each face from ``face_wrenches (N, 6, 6)``.

    ``q = Σ (w / FULL_SCALE)²`` of the face's own predicted wrench (NaN faces count 0),
    ``q_other`` the sum of the other faces' ``q``, ``L = 1 − exp(−((q + q_other) / LOAD_Q)³)``: 0 at
    rest, 1 under load (the error a load brings whatever its size is not the error at rest); the last
    three times ``L`` (0 at rest, as the training samples at rest have them).
    """
    u = np.nan_to_num(face_wrenches / FULL_SCALE)
    phi = q_features(np.einsum("nfi,nfi->nf", u, u))
    # the load terms are the load's, as in training, where the samples at rest have q 0: at rest after a tare
    # the predicted wrench is the gauge noise, and a q term fitted where a face's q is its crosstalk error
    # (q = E²) read it as that much error again (face_to_face, nonlinear cube: intervals at rest covering 98 %)
    phi[..., 2:] *= phi[..., 1:2]
    return phi


def q_features(q: np.ndarray) -> np.ndarray:
    """``(N, F, 5)`` :func:`load_features` from each face's ``q (N, F)`` (the faces left out count 0)."""
    out = np.empty(q.shape + (N_FEATURES,))
    total = q.sum(axis=1, keepdims=True)
    out[..., 0] = 1.0
    out[..., 1] = -np.expm1(-((total / LOAD_Q) ** 3))
    out[..., 2] = q
    np.multiply(q, q, out=out[..., 3])  # into out, no temporaries: 1.07 against 1.19 ms a fit of 10⁵ samples
    np.subtract(total, q, out=out[..., 4])
    return out


def own_load(q, own_q, L=1.0) -> np.ndarray:
    """Whether each face reads a load of its own: 1 where its ``q (..., F)`` reaches ``own_q (F,)`` (what
    its crosstalk reached in training: :func:`pito_core.calibration._residuals.own_q`), else 0; times
    the load indicator ``L`` (0 at rest). A switch, not a blend: a variance between the two models' is
    the rarer one's where they differ by orders (``face_to_face``, linear cube: at ``ρ = 0.94`` the
    crosstalk model's share was 10⁴ × the face's own error)."""
    return (np.asarray(q) >= own_q) * np.asarray(L, dtype=float)


def upgraded_variance_coef(coef: np.ndarray) -> np.ndarray:
    """Coefficients on ``[1, q, q², q_other]`` (files before version 4) on :func:`load_features`'
    ``[1, L, q, q², q_other]``: ``L``'s 0, the same variance everywhere."""
    coef = np.asarray(coef, dtype=float)
    if coef.ndim == 2 and coef.shape[1] == N_FEATURES - 1:
        return np.insert(coef, 1, 0.0, axis=1)
    return coef


@dataclass
class CovarianceGroup:
    """One least-squares problem of a fit (six for ``face_to_face``, one otherwise).

    Attributes
    ----------
    inputs : ndarray of int, shape (m,)
        Gauge columns (0..35) of the design.
    rows : ndarray of int, shape (q,)
        Rows of ``Calibration.matrix`` this problem fitted.
    design_pinv : ndarray, shape (n_int + m, n_int + m)
        ``P = (XᵀX)⁺`` of the design ``[offset columns | counts − center]``, per counts².
    residual_cov : ndarray, shape (q, q)
        ``Σ_r``: covariance of the fit's residuals, in the matrix's output frame (N², N²·m, N²·m²).
    center : ndarray, shape (m,)
        Counts subtracted from the inputs in the design (mean of the sessions' tares).
    weights : ndarray, shape (n_int,)
        Weights of the offset columns that reproduce ``Calibration.offset`` (1/sessions each).
    dof : int
        Residual degrees of freedom ``n − rank``.
    inflation : ndarray, shape (q,)
        Per output, how much more the coefficients vary than independent residuals would
        make them (≥ 1): residuals that drift together over consecutive samples (held
        loads, hysteresis, temperature) inform the fit less. Estimated by clusters of
        consecutive samples (a cluster-robust "sandwich" covariance, in ratio to ``Σ_r ⊗ P``).
    reference_leverage : ndarray, shape (q // 6, n_int + m, n_int + m), or None
        Per face block, ``P M_k P`` with ``M_k`` the design's ``Σ x̃ x̃ᵀ`` over the samples where
        that face carries the reference's load: with ``reference_cov`` the reference's noise in
        the coefficients, ``(x̃ᵀ P M_k P x̃) Σ_ref,k`` (docs/calibration.md, "Uncertainty"). None
        (an exact reference, or files written before) when ``Σ_r`` holds it, spread over all rows.
    reference_cov : ndarray, shape (q // 6, 6, 6), or None
        ``Σ_ref,k``: the reference's noise at rest (from the tares) in each face block's output frame.
    """

    inputs: np.ndarray
    rows: np.ndarray
    design_pinv: np.ndarray
    residual_cov: np.ndarray
    center: np.ndarray
    weights: np.ndarray
    dof: int = 0
    inflation: np.ndarray | None = None
    reference_leverage: np.ndarray | None = None
    reference_cov: np.ndarray | None = None

    def __post_init__(self):
        self.inputs = np.asarray(self.inputs, dtype=np.int64).reshape(-1)
        self.rows = np.asarray(self.rows, dtype=np.int64).reshape(-1)
        self.design_pinv = np.asarray(self.design_pinv, dtype=float)
        self.residual_cov = np.asarray(self.residual_cov, dtype=float)
        self.center = np.asarray(self.center, dtype=float).reshape(-1)
        self.weights = np.asarray(self.weights, dtype=float).reshape(-1)
        m, q, n_int = self.inputs.size, self.rows.size, self.weights.size
        self.inflation = np.ones(q) if self.inflation is None else np.asarray(self.inflation, dtype=float).reshape(-1)
        if self.inflation.shape != (q,) or not np.all(self.inflation >= 1.0):
            raise ValueError(f"inflation: expected {q} values ≥ 1, got {self.inflation!r}")
        if self.design_pinv.shape != (n_int + m, n_int + m):
            raise ValueError(f"design_pinv: expected shape ({n_int + m}, {n_int + m}), got {self.design_pinv.shape}")
        if self.residual_cov.shape != (q, q):
            raise ValueError(f"residual_cov: expected shape ({q}, {q}), got {self.residual_cov.shape}")
        if self.center.shape != (m,):
            raise ValueError(f"center: expected shape ({m},), got {self.center.shape}")
        for name in ("design_pinv", "residual_cov", "center", "weights"):
            if not np.all(np.isfinite(getattr(self, name))):
                raise ValueError(f"{name}: expected finite values")
        self._check_reference(n_int + m, q // 6)

    def _check_reference(self, p: int, blocks: int) -> None:
        """``reference_leverage`` and ``reference_cov``: both or neither, finite, of their shapes."""
        if (self.reference_leverage is None) != (self.reference_cov is None):
            raise ValueError("reference_leverage, reference_cov: expected both or neither")
        if self.reference_leverage is None:
            return
        self.reference_leverage = np.asarray(self.reference_leverage, dtype=float)
        self.reference_cov = np.asarray(self.reference_cov, dtype=float)
        for name, shape in (("reference_leverage", (blocks, p, p)), ("reference_cov", (blocks, 6, 6))):
            a = getattr(self, name)
            if a.shape != shape or not np.all(np.isfinite(a)):
                raise ValueError(f"{name}: expected finite values of shape {shape}, got {a.shape}")

    def _design(self, counts: np.ndarray, offset: np.ndarray | None):
        """``(x̃ (N, p'), slice of the design)``: the fitted offset if ``offset`` is None, else slopes only."""
        n_int = self.weights.size
        if offset is None:
            x = counts[:, self.inputs] - self.center
            return np.concatenate([np.broadcast_to(self.weights, (x.shape[0], n_int)), x], axis=1), slice(None)
        return counts[:, self.inputs] - offset[self.inputs], slice(n_int, None)

    def leverage(self, counts: np.ndarray, offset: np.ndarray | None) -> np.ndarray:
        """``x̃ᵀ P x̃`` per sample ``(N,)``: the fitted offset if ``offset`` is None, else slopes only."""
        xt, s = self._design(counts, offset)
        return np.einsum("ni,ij,nj->n", xt, self.design_pinv[s, s], xt)

    def reference_leverages(self, counts: np.ndarray, offset: np.ndarray | None, gauge_cov=None) -> np.ndarray:
        """``x̃ᵀ P M_k P x̃`` per sample and face block ``(N, q // 6)`` (zeros without ``reference_leverage``).

        With ``gauge_cov (36, 36)``, less the part the counts' own noise brings, :meth:`noise_leverages`
        (at least 0): the reference's noise in the slopes acting on the gauge noise is in the gauge noise
        through the fitted matrix already, which the error model has (its floor, measured with that matrix).
        """
        if self.reference_leverage is None:
            return np.zeros((counts.shape[0], self.rows.size // 6))
        xt, s = self._design(counts, offset)
        h = np.einsum("ni,bij,nj->nb", xt, self.reference_leverage[:, s, s], xt)
        if gauge_cov is not None:
            h -= self.noise_leverages(gauge_cov)
            np.maximum(h, 0.0, out=h)
        return h

    def noise_leverages(self, gauge_cov) -> np.ndarray:
        """``tr(Q_k Σ_g)`` per face block ``(q // 6,)``: the mean of ``x̃ᵀ Q_k x̃`` that gauge noise of
        covariance ``gauge_cov (36, 36)`` adds, ``Q_k`` the slopes' block of ``P M_k P``."""
        n_int = self.weights.size
        S = np.asarray(gauge_cov, dtype=float)[np.ix_(self.inputs, self.inputs)]
        return np.einsum("bij,ji->b", self.reference_leverage[:, n_int:, n_int:], S)


#: The three products of a face block's row groups (forces 0–2, torques 3–5) in ``PolyReferenceBlock.leverage``.
_GROUP_PAIRS = ((0, 0), (1, 1), (0, 1))


@dataclass
class PolyReferenceBlock:
    """The reference's noise through a polynomial correction's coefficients, for one output face.

    The correction's coefficients absorb part of the reference's noise (in every target where
    the face carries): with a ridge fit's solution operator ``M_g`` of a row group and ``M_k``
    the Gram of its design over the carrying rows, their covariance is ``M_g M_k M_g' ⊗ Σ_ref``,
    and a sample of design ``z = [u; φ(u)]`` (slopes: counts less the offset in use, over the
    correction's scale, and its features) has ``(zᵀ Q z) Σ_ref`` of it. It replaces the affine
    design's reference term on the rows with the correction (docs/calibration.md, "Uncertainty").

    Attributes
    ----------
    block : int
        Output row block (the face's index in ``output_faces``).
    rows : ndarray of bool, shape (6,)
        The block's rows with the correction (the others keep the affine term).
    cols : ndarray of int, shape (c,)
        Entries of ``z`` used, indices into ``[u (36) | φ (162)]``.
    leverage : ndarray, shape (3, c, c)
        ``Q`` for forces–forces, torques–torques and forces–torques (dimensionless).
    reference_cov : ndarray, shape (6, 6)
        ``Σ_ref``: the reference's noise in the block's output frame (N², N²·m, N²·m²).
    """

    block: int
    rows: np.ndarray
    cols: np.ndarray
    leverage: np.ndarray
    reference_cov: np.ndarray

    def __post_init__(self):
        self.block = int(self.block)
        self.rows = np.asarray(self.rows, dtype=bool).reshape(-1)
        self.cols = np.asarray(self.cols, dtype=np.int64).reshape(-1)
        self.leverage = np.asarray(self.leverage, dtype=float)
        self.reference_cov = np.asarray(self.reference_cov, dtype=float)
        c = self.cols.size
        if self.rows.shape != (6,):
            raise ValueError(f"rows: expected 6 booleans, got {self.rows.shape}")
        for name, shape in (("leverage", (3, c, c)), ("reference_cov", (6, 6))):
            a = getattr(self, name)
            if a.shape != shape or not np.all(np.isfinite(a)):
                raise ValueError(f"{name}: expected finite values of shape {shape}, got {a.shape}")

    def variances(self, z: np.ndarray) -> np.ndarray:
        """``(N, 6, 6)`` the term at samples of design ``z (N, 198)`` (zero on the rows without the correction)."""
        zc = z[:, self.cols]
        q = np.stack([np.einsum("ni,ni->n", zc @ Q, zc) for Q in self.leverage], axis=1)  # (N, 3)
        g = np.repeat([0, 1], 3)
        pair = np.array([[0, 2], [2, 1]])[g[:, None], g[None, :]]  # (6, 6) index into the three products
        out = q[:, pair] * self.reference_cov
        out[:, ~self.rows] = 0.0
        out[:, :, ~self.rows] = 0.0
        return out


@dataclass(kw_only=True)
class CalibrationCovariance:
    """Everything needed to give each sample's face wrenches a covariance.

    Attributes
    ----------
    groups : list of CovarianceGroup
    gauge_cov : ndarray, shape (36, 36)
        Gauge noise at rest ``Σ_g``, counts² (pooled over the sessions' unloaded samples).
    n_tare : int or None
        None: the calibration's offset is the fitted one. n: it was re-tared on n samples.
    variance_coef : ndarray, shape (6F, 5)
        Per matrix row, the coefficients of its error variance on ``load_features``
        ``[1, L, q, q², q_other]`` (output frame units², N² or N²·m²): non-negative, but for
        ``L``'s, not below minus the constant's. Coefficients on ``[1, q, q², q_other]`` (6F, 4),
        of files before version 4, are read with ``L``'s 0.
    residual_corr : ndarray, shape (F, 6, 6)
        Correlation of the residuals between the six outputs of each output face.
    poly_reference : list of PolyReferenceBlock
        With a noisy reference and a polynomial correction: its coefficients' share of the
        reference's noise, per corrected output face (empty otherwise, and for older files).
    error_frame : {"output", "face"}
        Frame of ``variance_coef``, ``residual_corr`` and ``rest_bias``: the matrix's output frame,
        or each face's own (fits in S_A since the error model is fitted where the errors are read).
    rest_bias : ndarray, shape (6F,)
        Per row, the square of the fitted offset's error at rest (the training sessions' mean
        residual at rest, less the reference's noise through the offset), output units². The error
        model is of a tared calibration; this is added where the fitted offset is in use (zeros for
        older files, whose ``variance_coef`` holds it).
    own_variance_coef : ndarray, shape (6F, 5)
        The same as ``variance_coef`` where the face reads a load of its own (:func:`own_load`):
        a face's error where it carries is not its error where another face does, whatever one
        model of both gives them (``face_to_face``, linear cube: intervals 18× the error where
        the face carried, right where it did not). Files before version 5: ``variance_coef``.
    own_q : ndarray, shape (F,)
        Per output face, the ``q`` from which :func:`own_load` reads it as its own (``inf``: one
        model, files before version 5).
    """

    groups: list = field(default_factory=list)
    gauge_cov: np.ndarray = field(default_factory=lambda: np.zeros((36, 36)))
    n_tare: int | None = None
    variance_coef: np.ndarray | None = None
    residual_corr: np.ndarray | None = None
    poly_reference: list = field(default_factory=list)
    error_frame: str = "output"
    rest_bias: np.ndarray | None = None
    own_variance_coef: np.ndarray | None = None
    own_q: np.ndarray | None = None

    def __post_init__(self):
        self.gauge_cov = np.asarray(self.gauge_cov, dtype=float)
        if self.gauge_cov.shape != (36, 36) or not np.all(np.isfinite(self.gauge_cov)):
            raise ValueError(f"gauge_cov: expected finite values of shape (36, 36), got {self.gauge_cov.shape}")
        if self.error_frame not in ("output", "face"):
            raise ValueError(f"error_frame: expected 'output' or 'face', got {self.error_frame!r}")
        if self.n_tare is not None and int(self.n_tare) < 1:
            raise ValueError(f"n_tare: expected a number of samples ≥ 1, got {self.n_tare!r}")
        q = sum(g.rows.size for g in self.groups)
        if self.variance_coef is None:  # the pooled residual covariance, whatever the load
            self.variance_coef = np.zeros((q, N_FEATURES))
            self.residual_corr = np.zeros((q // 6, 6, 6))
            for g in self.groups:
                d = np.sqrt(np.clip(np.diag(g.residual_cov), 0, None))
                self.variance_coef[g.rows, 0] = d**2
                for k in range(g.rows.size // 6):
                    blk = slice(6 * k, 6 * k + 6)
                    dk = np.where(d[blk] > 0, d[blk], 1.0)
                    self.residual_corr[int(g.rows[6 * k]) // 6] = g.residual_cov[blk, blk] / np.outer(dk, dk)
        self.variance_coef = upgraded_variance_coef(self.variance_coef)
        self.residual_corr = np.asarray(self.residual_corr, dtype=float)
        c = self.variance_coef
        # L's coefficient may be negative (an error at rest larger than under load), not the variance
        if (c.shape != (q, N_FEATURES) or not np.all(np.isfinite(c)) or np.any(np.delete(c, 1, axis=1) < 0)
                or np.any(c[:, 0] + c[:, 1] < 0)):
            raise ValueError(f"variance_coef: expected finite values of shape ({q}, {N_FEATURES}), non-negative "
                             "(L's column: not below minus the constant's)")
        if self.residual_corr.shape != (q // 6, 6, 6) or not np.all(np.isfinite(self.residual_corr)):
            raise ValueError(f"residual_corr: expected finite values of shape ({q // 6}, 6, 6)")
        self.rest_bias = np.zeros(q) if self.rest_bias is None else np.asarray(self.rest_bias, dtype=float)
        if self.rest_bias.shape != (q,) or not np.all(np.isfinite(self.rest_bias)) or np.any(self.rest_bias < 0):
            raise ValueError(f"rest_bias: expected {q} finite non-negative values, got shape {self.rest_bias.shape}")
        if (self.own_variance_coef is None) != (self.own_q is None):
            raise ValueError("own_variance_coef, own_q: expected both or neither")
        if self.own_q is None:  # one model whatever the load (files before version 5)
            self.own_variance_coef, self.own_q = self.variance_coef, np.full(q // 6, np.inf)
        self.own_variance_coef = np.asarray(self.own_variance_coef, dtype=float)
        self.own_q = np.asarray(self.own_q, dtype=float).reshape(-1)
        c = self.own_variance_coef
        if c.shape != (q, N_FEATURES) or not np.all(np.isfinite(c)) or np.any(np.delete(c, 1, axis=1) < 0) \
                or np.any(c[:, 0] + c[:, 1] < 0):
            raise ValueError(f"own_variance_coef: expected finite values of shape ({q}, {N_FEATURES}), as variance_coef's")
        if self.own_q.shape != (q // 6,) or np.any(np.isnan(self.own_q)) or np.any(self.own_q <= 0):
            raise ValueError(f"own_q: expected {q // 6} positive values (inf: none), got {self.own_q!r}")

    def variances(self, feats) -> np.ndarray:
        """``(N, 6F)`` each row's error variance at the samples' ``load_features`` of its face ``feats (N, F, 5)``:
        ``variance_coef``'s where the face reads no load of its own, ``own_variance_coef``'s where it does."""
        F = feats.shape[1]
        rho = own_load(feats[..., 2], self.own_q, feats[..., 1])  # (N, F)
        v = np.einsum("nfk,fik->nfi", feats, self.variance_coef.reshape(F, 6, N_FEATURES))
        v_own = np.einsum("nfk,fik->nfi", feats, self.own_variance_coef.reshape(F, 6, N_FEATURES))
        return (v + rho[..., None] * (v_own - v)).reshape(-1, 6 * F)

    def _copy(self, **changes) -> "CalibrationCovariance":
        kw = dict(groups=self.groups, gauge_cov=self.gauge_cov, n_tare=self.n_tare, variance_coef=self.variance_coef,
                  residual_corr=self.residual_corr, poly_reference=self.poly_reference, error_frame=self.error_frame,
                  rest_bias=self.rest_bias, own_variance_coef=self.own_variance_coef, own_q=self.own_q)
        kw.update(changes)
        return CalibrationCovariance(**kw)

    def retared(self, n: int) -> "CalibrationCovariance":
        """The same, for an offset taken as the mean of ``n`` unloaded samples."""
        return self._copy(n_tare=int(n))

    def linear(self) -> "CalibrationCovariance":
        """The same for the affine rows alone (the papers' linear alternative: no correction's term)."""
        return self._copy(poly_reference=[])

    def face_covariances(self, counts, offset, apply, face_from_output, output_faces, explicit_offset: bool,
                         poly_z=None):
        """``(N, 6, 6, 6)`` covariance of each face's wrench in its frame (NaN where no output).

        Parameters
        ----------
        counts : ndarray, shape (N, 36)
        offset : ndarray, shape (36,)
            The offset the wrenches were computed with.
        apply : ndarray, shape (6, 6, 36)
            Counts → face wrench in face frames (``Calibration._apply``).
        face_from_output : ndarray, shape (6, 6, 6)
            Adjoint from each face's output frame to its face frame (identity for ``face``).
        output_faces : tuple of int
            Faces (1..6) of the matrix's row blocks, in row order.
        explicit_offset : bool
            The caller gave the offset: its uncertainty is not known (slopes only, no tare term).
        poly_z : ndarray, shape (N, 198), optional
            ``[u; φ(u)]`` of the samples (``Calibration.wrenches``): needed with ``poly_reference``.
        """
        N = counts.shape[0]
        out = np.full((N, 6, 6, 6), np.nan)
        fitted = self.n_tare is None and not explicit_offset
        poly = {b.block: b for b in self.poly_reference}
        if poly and poly_z is None:
            raise ValueError("poly_z: expected the samples' design [u; φ(u)] with a polynomial reference term")
        for g in self.groups:
            h = g.leverage(counts, None if fitted else offset)
            h_ref = g.reference_leverages(counts, None if fitted else offset, self.gauge_cov)
            for k in range(g.rows.size // 6):
                block = int(g.rows[6 * k]) // 6
                face = output_faces[block] - 1
                r = np.sqrt(g.inflation[6 * k : 6 * k + 6])
                Sr = g.residual_cov[6 * k : 6 * k + 6, 6 * k : 6 * k + 6] * np.outer(r, r)
                X = face_from_output[face]
                out[:, face] = h[:, None, None] * (X @ Sr @ X.T)
                if g.reference_cov is not None:  # the reference's noise in the coefficients, where this face carries
                    T = h_ref[:, k, None, None] * g.reference_cov[k]
                    pb = poly.get(block)
                    if pb is not None:  # the correction's rows: its own coefficients' term
                        T[:, pb.rows] = 0.0
                        T[:, :, pb.rows] = 0.0
                        T += pb.variances(poly_z)
                    out[:, face] += X @ T @ X.T
        W = np.einsum("fij,nj->nfi", apply, counts - offset)
        feats = load_features(np.where(np.isin(np.arange(6), np.asarray(output_faces) - 1)[None, :, None], W, np.nan))
        variances = self.variances(feats[:, np.asarray(output_faces) - 1])
        for k, f in enumerate(output_faces):
            var = variances[:, 6 * k : 6 * k + 6]  # (N, 6) output frame
            if fitted:  # the fitted offset's own error at rest (the error model is of a tared calibration)
                var += self.rest_bias[6 * k : 6 * k + 6]
            sd = np.sqrt(np.clip(var, 0, None))
            E = sd[:, :, None] * self.residual_corr[k] * sd[:, None, :]
            if self.error_frame == "face":  # fitted in the face's frame already
                out[:, f - 1] += E
                continue
            X = face_from_output[f - 1]
            out[:, f - 1] += np.einsum("ij,njk,lk->nil", X, E, X)
        if self.n_tare is not None and not explicit_offset:
            G = np.einsum("fia,ab,fjb->fij", apply, self.gauge_cov, apply)  # gauge noise per face (6, 6, 6)
            for f in output_faces:
                out[:, f - 1] += G[f - 1] / self.n_tare
        out = 0.5 * (out + np.swapaxes(out, -1, -2))
        return out

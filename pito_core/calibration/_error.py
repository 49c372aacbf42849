"""The calibration's error model: each sample's covariance of its face wrenches.

One estimator (docs/calibration.md, "Uncertainty"). A prediction's error has two parts:

* the coefficients' error: the fit is least squares on the design ``x̃ = [a; s − m]`` (an
  offset column per session, ``a`` its weights, then the counts ``s`` less a centre ``m``);
  with ``P = (XᵀX)⁺``, a sandwich (the residuals are not alike where a face carries, with the
  reference's noise in its targets, and where it carries nothing): per output face,
  ``h_c Σ_c + (h − h_c) Σ_free`` with ``h = x̃ᵀ P x̃``, ``h_c = x̃ᵀ P G_c P x̃``, ``G_c`` the Gram of
  the design's rows where the face carries and ``Σ_c``, ``Σ_free`` its residuals' covariance there
  and elsewhere, all from the training subsample (``CovarianceGroup.carry_pinv``, ``carry_cov``;
  ``h Σ_r`` for files without them), mapped to each face's frame;
* the error a sample brings itself (gauge noise, what the model misses): per face and axis, a
  variance ``c₀ + c₁ q + c₂ q² + c₃ q_other`` of the face's own load ``q = ‖ŵ_face / FULL_SCALE‖²``
  and of the other faces' (the sum of their ``q``), fitted by non-negative least squares to the
  squared residuals of the training subsample (each session tared on its samples at rest, as the
  calibration is used) less the reference's noise ``V`` that is left in them where the face
  carries, ``V (1 − h)``, and less the coefficients' error the other rows' noise put in them (the
  term above at that row, ``CV``; a free face's residuals are mostly that), its own row's share
  restored: ``E² (1 + 2h) − CV``; rows weighted by ``1 / (v̄ + V)`` (``v̄`` the axis's mean
  variance of an unweighted first fit: a squared residual's spread grows with the noise in it);
  ``c₀`` is at least
  the gauge noise through the matrix. The six axes of a face share the residuals' correlation;
* the reference's noise that the correction's coefficients kept: ``h V``, fitted to the same
  features, ``h`` the leverage the correction's features add to the sample in the fit's design,
  with each output row's ridge (:func:`correction_leverage`). A noisy reference is fitted in part
  (the in-sample residual keeps ``V (1 − h)``) and the part fitted moves the prediction by as much
  (``h V``): where the noise swamps the model's own error the residuals cannot show it.

The second and third terms are multiplied by ``scale²``, the factor that puts 95 % of the loaded
training residuals within ``±1.96`` standard deviations of them and the first (the reference's noise
added where the face carries; the errors are not Gaussian); the first is not (a file without the
sandwich scales its ``h Σ_r`` too, as when it was written). Held out, the model's own error (not
the ``h V`` term) is larger, and not alike where a face carries and where it carries nothing (a
joint fit's free face reads the other faces' features): the fit's own folds give each output row's
mean squares held out and in sample over the two kinds of rows (``ModelChoice.cv_split``), and per kind the held-out factor
``ρ²`` is the median over rows of their ratio, the carrying ones less the reference's noise in
them. The folds hold out whole loading segments: their fits saw a share ``t`` of each load's rows
(``ModelChoice.cv_train_share``), and an estimate's error goes as one over its rows, so a fit on
all of them is worse held out by ``t (ρ² − 1)``. Each training sample's in-sample error times
that excess of its kind (a ``face_to_face`` face: every sample as carrying, and not its ``c₃``: it
never fitted its crosstalk, whose residuals are held out already) is fitted to the same features,
so a new sample takes it from its predicted load alone. After
:meth:`CalibrationCovariance.retared` on ``n`` samples the tare's gauge noise ``A Σ_g Aᵀ / n`` is added.

Beyond the box the correction was trained in, none of that was measured: the correction continues
along its extension, then fades to the linear fit (``_poly.PolyCorrection``). Two terms, after the
scale: the extension's own held-out error, ``b K`` with ``b = ‖(P x − t P x) / scale‖²`` how far the
sample's counts lie beyond the box (``t`` its ray's factor into it) and ``K (F, 6, 6)``
(``beyond_cov``) the second moment of the chosen extension's errors on the training loads held out
beyond a shrunk box (``_cv.extension_errors``) per unit of their ``b``; and where the fade takes part
of the correction off, ``r rᵀ`` of that part ``r`` (:meth:`Calibration.wrenches`): the truth may
follow either.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np

from ..defaults import FULL_SCALE_FACE, TARE_STILL_FORCE_STD_N, TARE_STILL_TORQUE_STD_NM
from ..frames import N_GAUGES
from ._poly import MAX_ROWS
from ._targets import block_targets

__all__ = ["CovarianceGroup", "CalibrationCovariance", "ErrorModel", "fit_error_model", "load_features",
           "NoisyReferenceWarning", "reference_noise_at_rest", "correction_leverage", "FULL_SCALE", "N_FEATURES",
           "ERROR_MODEL_SAMPLES", "COVERAGE", "Z_COVERAGE"]

#: Full-scale loads that make a wrench dimensionless, ``[fx … tz]`` in N and N·m.
FULL_SCALE = np.asarray(FULL_SCALE_FACE)
#: Features of the error variance: ``[1, q, q², q_other]``.
N_FEATURES = 4
#: The error model reads about this many training samples (every n-th sample of the fit's pass); 10⁴ gave
#: the same coverage to ±0.3 points at twice the time (docs/calibration/coverage.md).
ERROR_MODEL_SAMPLES = 5_000
#: The nominal coverage the scale is set for, and its two-sided normal quantile.
COVERAGE = 0.95
Z_COVERAGE = 1.959964
#: Bounds of the coverage scale (a factor on standard deviations).
SCALE_BOUNDS = (0.05, 50.0)
#: A session's reference is above the tare's noise limits when its noise at rest is, less this many
#: of its standard errors (:func:`reference_noise_at_rest`).
NOISE_LIMIT_SE = 3.0
#: Directions of the correction's features (the affine part projected out) with eigenvalues below this
#: fraction of the largest are dropped (:func:`correction_leverage`).
LEVERAGE_RTOL = 1e-10


def load_features(q: np.ndarray) -> np.ndarray:
    """``(N, F, 4)`` features ``[1, q, q², q_other]`` from each output face's ``q (N, F)`` (dimensionless)."""
    q = np.nan_to_num(q)
    return np.stack([np.ones_like(q), q, q * q, q.sum(axis=1, keepdims=True) - q], axis=-1)


def face_q(face_wrenches: np.ndarray) -> np.ndarray:
    """``(N, F)`` each face's ``‖w / FULL_SCALE‖²`` from ``face_wrenches (N, F, 6)``."""
    u = face_wrenches / FULL_SCALE
    return np.einsum("nfi,nfi->nf", u, u)


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
        Counts subtracted from the inputs in the design.
    weights : ndarray, shape (n_int,)
        Weights of the offset columns that reproduce ``Calibration.offset``.
    dof : int
        Residual degrees of freedom ``n − rank``.
    carry_pinv : ndarray, shape (q / 6, n_int + m, n_int + m), optional
        Per output face of the problem, ``P G_c P`` with ``G_c`` the Gram of the design's rows where
        that face carries: with ``carry_cov``, the coefficients' covariance as a sandwich (module
        docstring); None: ``x̃ᵀ P x̃ Σ_r``.
    carry_cov : ndarray, shape (q / 6, 2, 6, 6), optional
        Per output face, the covariance of its residuals (output frame) over the rows where it carries
        and where it carries nothing.
    """

    inputs: np.ndarray
    rows: np.ndarray
    design_pinv: np.ndarray
    residual_cov: np.ndarray
    center: np.ndarray
    weights: np.ndarray
    dof: int = 0
    carry_pinv: np.ndarray | None = None
    carry_cov: np.ndarray | None = None

    def __post_init__(self):
        self.inputs = np.asarray(self.inputs, dtype=np.int64).reshape(-1)
        self.rows = np.asarray(self.rows, dtype=np.int64).reshape(-1)
        self.design_pinv = np.asarray(self.design_pinv, dtype=float)
        self.residual_cov = np.asarray(self.residual_cov, dtype=float)
        self.center = np.asarray(self.center, dtype=float).reshape(-1)
        self.weights = np.asarray(self.weights, dtype=float).reshape(-1)
        self.dof = int(self.dof)
        m, q, n_int = self.inputs.size, self.rows.size, self.weights.size
        for name, shape in (("design_pinv", (n_int + m, n_int + m)), ("residual_cov", (q, q)), ("center", (m,))):
            a = getattr(self, name)
            if a.shape != shape:
                raise ValueError(f"{name}: expected shape {shape}, got {a.shape}")
            if not np.all(np.isfinite(a)):
                raise ValueError(f"{name}: expected finite values")
        if q % 6:
            raise ValueError(f"rows: expected whole faces (a multiple of 6), got {q}")
        if (self.carry_pinv is None) != (self.carry_cov is None):
            raise ValueError("carry_pinv, carry_cov: expected both or neither")
        if self.carry_pinv is not None:
            d = n_int + m
            for name, shape in (("carry_pinv", (q // 6, d, d)), ("carry_cov", (q // 6, 2, 6, 6))):
                a = np.asarray(getattr(self, name), dtype=float)
                if a.shape != shape or not np.all(np.isfinite(a)):
                    raise ValueError(f"{name}: expected finite values of shape {shape}, got {a.shape}")
                setattr(self, name, a)

    def _design(self, counts: np.ndarray, offset: np.ndarray | None) -> tuple[np.ndarray, slice]:
        """``(x̃ (N, d'), block)``: the design rows of ``counts`` and the block of ``P`` they meet: the fitted
        offset if ``offset`` is None (``[weights | counts − center]``), else slopes only."""
        n_int = self.weights.size
        if offset is None:
            x = counts[:, self.inputs] - self.center
            return np.concatenate([np.broadcast_to(self.weights, (x.shape[0], n_int)), x], axis=1), slice(None)
        return counts[:, self.inputs] - offset[self.inputs], slice(n_int, None)

    def leverages(self, counts: np.ndarray, offset: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
        """``(h (N,), h_c (N, q / 6))``: ``x̃ᵀ P x̃`` and, per output face, ``x̃ᵀ P G_c P x̃`` (zeros without
        ``carry_pinv``); the coefficients' covariance of a face is ``h_c Σ_c + (h − h_c) Σ_free``
        (:meth:`residual_blocks`)."""
        return self._forms(*self._design(counts, offset))

    def _forms(self, xt: np.ndarray, b: slice = slice(None)) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`leverages` of design rows ``xt`` meeting block ``b`` of ``P`` (double precision: in single,
        ``h − h_c`` lost its digits on a session's offset column)."""
        h = np.einsum("nj,nj->n", xt @ self.design_pinv[b, b], xt)
        if self.carry_pinv is None:
            return h, np.zeros((len(h), self.rows.size // 6))
        return h, _quadratic_forms(xt, self.carry_pinv[:, b, b])

    def residual_blocks(self) -> np.ndarray:
        """``(q / 6, 2, 6, 6)``: per output face ``[Σ_c, Σ_free]`` (``carry_cov``), or ``Σ_r``'s block twice."""
        if self.carry_cov is not None:
            return self.carry_cov
        nf = self.rows.size // 6
        return np.stack([[self.residual_cov[6 * k : 6 * k + 6, 6 * k : 6 * k + 6]] * 2 for k in range(nf)])


@dataclass(kw_only=True)
class ErrorModel:
    """What :func:`fit_error_model` returns.

    Attributes
    ----------
    variance_coef : ndarray, shape (6F, 4)
        Per output face and axis (face frames), non-negative coefficients of the error variance on
        :func:`load_features` (N², N²·m²), the held-out factor and the reference's noise the
        correction kept included.
    residual_corr : ndarray, shape (F, 6, 6)
        Correlation of the residuals between each face's six axes.
    scale : float
        Factor on the standard deviations that makes the loaded training residuals' coverage nominal.
    groups : list of CovarianceGroup
        The fit's problems with the coefficients' sandwich (``carry_pinv``, ``carry_cov``).
    """

    variance_coef: np.ndarray
    residual_corr: np.ndarray
    scale: float
    groups: list = field(default_factory=list)


@dataclass(kw_only=True)
class CalibrationCovariance:
    """Everything needed to give each sample's face wrenches a covariance (module docstring).

    Attributes
    ----------
    groups : list of CovarianceGroup
    gauge_cov : ndarray, shape (36, 36)
        Gauge noise at rest ``Σ_g``, counts².
    variance_coef : ndarray, shape (6F, 4)
        :attr:`ErrorModel.variance_coef`.
    residual_corr : ndarray, shape (F, 6, 6)
        :attr:`ErrorModel.residual_corr`.
    scale : float
        :attr:`ErrorModel.scale`.
    n_tare : int or None
        None: the calibration's offset is the fitted one. n: it was re-tared on n samples.
    beyond_cov : ndarray, shape (F, 6, 6), optional
        Each output face's wrench error covariance (its frame) per unit of ``b``, how far a sample's
        counts lie beyond the correction's box (module docstring); zeros without a correction.
    """

    groups: list = field(default_factory=list)
    gauge_cov: np.ndarray = field(default_factory=lambda: np.zeros((N_GAUGES, N_GAUGES)))
    variance_coef: np.ndarray | None = None
    residual_corr: np.ndarray | None = None
    scale: float = 1.0
    n_tare: int | None = None
    beyond_cov: np.ndarray | None = None

    def __post_init__(self):
        self.gauge_cov = np.asarray(self.gauge_cov, dtype=float)
        if self.gauge_cov.shape != (N_GAUGES, N_GAUGES) or not np.all(np.isfinite(self.gauge_cov)):
            raise ValueError(f"gauge_cov: expected finite values of shape (36, 36), got {self.gauge_cov.shape}")
        q = sum(g.rows.size for g in self.groups)
        if self.variance_coef is None:
            self.variance_coef = np.zeros((q, N_FEATURES))
        if self.residual_corr is None:
            self.residual_corr = np.broadcast_to(np.eye(6), (q // 6, 6, 6)).copy()
        self.variance_coef = np.asarray(self.variance_coef, dtype=float)
        self.residual_corr = np.asarray(self.residual_corr, dtype=float)
        c = self.variance_coef
        if c.shape != (q, N_FEATURES) or not np.all(np.isfinite(c)) or np.any(c < 0):
            raise ValueError(f"variance_coef: expected finite non-negative values of shape ({q}, {N_FEATURES}), "
                             f"got shape {c.shape}")
        if self.residual_corr.shape != (q // 6, 6, 6) or not np.all(np.isfinite(self.residual_corr)):
            raise ValueError(f"residual_corr: expected finite values of shape ({q // 6}, 6, 6)")
        if self.beyond_cov is None:
            self.beyond_cov = np.zeros((q // 6, 6, 6))
        self.beyond_cov = np.asarray(self.beyond_cov, dtype=float)
        if self.beyond_cov.shape != (q // 6, 6, 6) or not np.all(np.isfinite(self.beyond_cov)):
            raise ValueError(f"beyond_cov: expected finite values of shape ({q // 6}, 6, 6), got {self.beyond_cov.shape}")
        self.scale = float(self.scale)
        if not (np.isfinite(self.scale) and self.scale > 0):
            raise ValueError(f"scale: expected a positive number, got {self.scale!r}")
        if self.n_tare is not None:
            if int(self.n_tare) < 1:
                raise ValueError(f"n_tare: expected a number of samples ≥ 1, got {self.n_tare!r}")
            self.n_tare = int(self.n_tare)

    def retared(self, n: int) -> "CalibrationCovariance":
        """The same, for an offset taken as the mean of ``n`` unloaded samples."""
        return CalibrationCovariance(groups=self.groups, gauge_cov=self.gauge_cov, variance_coef=self.variance_coef,
                                     residual_corr=self.residual_corr, scale=self.scale, n_tare=int(n),
                                     beyond_cov=self.beyond_cov)

    def face_covariances(self, counts, offset, face_wrenches, apply, face_from_output, output_faces,
                         explicit_offset: bool, beyond=None):
        """``(N, 6, 6, 6)`` covariance of each face's wrench in its frame (NaN where no output).

        Parameters
        ----------
        counts : ndarray, shape (N, 36)
        offset : ndarray, shape (36,)
            The offset the wrenches were computed with.
        face_wrenches : ndarray, shape (N, 6, 6)
            The predicted wrenches (``Calibration.wrenches``), N and N·m.
        apply : ndarray, shape (6, 6, 36)
            Counts → face wrench in face frames (``Calibration._apply``), for the tare's term.
        face_from_output : ndarray, shape (6, 6, 6)
            Adjoint from each face's output frame to its face frame (identity for ``face``).
        output_faces : tuple of int
            Faces (1..6) of the matrix's row blocks, in row order.
        explicit_offset : bool
            The caller gave the offset: its uncertainty is not known (slopes only, no tare term).
        beyond : ndarray, shape (N, F), optional
            Each sample's ``b`` per output face (``PolyCorrection.beyond_sq``), for ``beyond_cov``.
        """
        N, F = counts.shape[0], len(output_faces)
        idx = np.asarray(output_faces) - 1
        out = np.full((N, 6, 6, 6), np.nan)
        out[:, idx] = 0.0
        fitted = self.n_tare is None and not explicit_offset

        def coefficients(sandwich):  # the coefficients' error (the sandwich is not scaled: files before it were)
            for g in self.groups:
                if (g.carry_pinv is not None) != sandwich:
                    continue
                h, hc = g.leverages(counts, None if fitted else offset)
                blocks = g.residual_blocks()
                for k in range(g.rows.size // 6):
                    f = output_faces[int(g.rows[6 * k]) // 6] - 1
                    X = face_from_output[f]
                    out[:, f] += hc[:, k, None, None] * (X @ blocks[k, 0] @ X.T)
                    out[:, f] += (h - hc[:, k])[:, None, None] * (X @ blocks[k, 1] @ X.T)

        coefficients(False)
        phi = load_features(face_q(face_wrenches[:, idx]))  # the sample's own error
        var = np.einsum("nfk,fik->nfi", phi, self.variance_coef.reshape(F, 6, N_FEATURES))
        sd = np.sqrt(var)
        out[:, idx] += sd[..., :, None] * self.residual_corr * sd[..., None, :]
        out[:, idx] *= self.scale**2
        coefficients(True)
        if beyond is not None:  # past the trained box: the extension's held-out error per unit of distance²
            on = np.flatnonzero(np.any(beyond > 0, axis=1))
            if on.size:
                out[on[:, None], idx] += beyond[on][..., None, None] * self.beyond_cov
        if self.n_tare is not None and not explicit_offset:  # the tare's own noise
            A = apply[idx]
            out[:, idx] += np.einsum("fia,ab,fjb->fij", A, self.gauge_cov, A) / self.n_tare
        return out


def _quadratic_forms(x: np.ndarray, A: np.ndarray) -> np.ndarray:
    """``(N, k)``: every ``x_nᵀ A_k x_n`` of ``x (N, d)`` and ``A (k, d, d)``, one product ``(N, d) @ (d, k·d)``."""
    k, d = A.shape[0], A.shape[1]
    return np.einsum("nkj,nj->nk", (x @ A.transpose(1, 0, 2).reshape(d, k * d)).reshape(len(x), k, d), x)


def _with_sandwich(g: CovarianceGroup, cal, xo, sess, offsets, loaded, carries, E):
    """``(g, h, CV)``: ``g`` with ``carry_pinv`` and ``carry_cov`` from the training subsample, and on each of
    its rows the leverage ``h (n,)`` and the coefficients' variance ``CV (n, q / 6, 6)`` (face frames).

    From the counts less each session's tare ``xo (n, 36)`` (float32), each row's session ``sess (n,)``, the
    tares ``offsets``, ``loaded (n, 6)``, ``carries (n, F)`` and the residuals ``E (n, F, 6)`` (face frames).
    The problem's rows: a face fitted on its own (six inputs) has those where no other face is loaded; the
    subsample's Grams are scaled to the fit's rows."""
    n_int, out = g.weights.size, np.asarray(cal.output_faces)
    ks = np.unique(g.rows // 6)  # the problem's output faces (indices into cal.output_faces)
    xt = np.empty((len(xo), n_int + g.inputs.size))  # the design row of every subsample row
    xt[:, :n_int] = np.arange(n_int) == sess[:, None]  # the session's offset column
    shift = np.asarray(offsets, dtype=float)[:, g.inputs] - g.center  # each session's tare less the centre
    np.add(xo[:, g.inputs], shift[sess], out=xt[:, n_int:])
    rows = slice(None)
    if g.inputs.size == 6:  # a face on its own: its own loads and rests
        others = np.ones(6, dtype=bool)
        others[out[ks[0]] - 1] = False
        rows = ~loaded[:, others].any(axis=1)
    x, c, e = xt[rows], carries[rows][:, ks], E[rows][:, ks]
    if len(x) > x.shape[1]:
        scale = (g.dof + x.shape[1]) / len(x)  # the fit's rows per subsample row
        X_out = np.linalg.inv(cal._face_from_output[out[ks] - 1])  # face frame -> output frame
        # the Gram of each pattern of carrying faces once (a row has one), then summed per face
        codes, inverse = np.unique(c @ (1 << np.arange(ks.size)), return_inverse=True)
        order = np.argsort(inverse, kind="stable")
        grams = [x[i].T @ x[i] for i in np.split(order, np.cumsum(np.bincount(inverse))[:-1])]
        pinv, cov = np.zeros((ks.size,) + g.design_pinv.shape), np.zeros((ks.size, 2, 6, 6))
        for j in range(ks.size):
            on = c[:, j]
            G = sum((grams[u] for u in range(codes.size) if codes[u] >> j & 1), np.zeros(g.design_pinv.shape))
            pinv[j] = g.design_pinv @ (scale * G) @ g.design_pinv
            r = e[:, j] @ X_out[j].T
            for i, part in enumerate((on, ~on)):  # weights, not r[part]: no copies of the rows
                m = part.sum()
                cov[j, i] = (r * part[:, None]).T @ r / m if m > x.shape[1] else \
                    g.residual_cov[6 * j : 6 * j + 6, 6 * j : 6 * j + 6]
        g = CovarianceGroup(g.inputs, g.rows, g.design_pinv, g.residual_cov, g.center, g.weights, g.dof,
                            carry_pinv=pinv, carry_cov=cov)
    h, hc = g._forms(xt)  # every row's h and h_c
    Xf = cal._face_from_output[out[ks] - 1]
    d = np.einsum("jia,jkab,jib->kji", Xf, g.residual_blocks(), Xf)  # (2, q / 6, 6): Σ_c, Σ_free's diagonals
    # h_c Σ_c + (h − h_c) Σ_free
    CV = hc[:, :, None] * (d[0] - d[1]) + h[:, None, None] * d[1]
    return g, h, CV


def _nnls(Phi: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Non-negative ``c`` minimising ``‖Φ c − y‖²``, columns scaled to unit norm (``Φ (n, k)``); ``y (n,)``
    or ``(n, m)`` (then ``c (k, m)``, one fit per column). Solved on the ``k × k`` Cholesky factor of the
    Gram, ``‖Lᵀ c − L⁻¹ Φᵀ y‖²`` (the same minimiser: the rest of ``y`` is orthogonal to ``Φ``), on ``Φ``
    itself where the Gram is not positive definite."""
    import scipy.linalg
    import scipy.optimize  # deferred: 0.3 CPU s to import, for fits only (loading a calibration needs none)

    Y = y[:, None] if y.ndim == 1 else y
    s = np.sqrt(np.einsum("ij,ij->j", Phi, Phi))
    on = s > 0
    c = np.zeros((Phi.shape[1], Y.shape[1]))
    if on.any():
        A = Phi[:, on] / s[on]
        try:
            L = np.linalg.cholesky(A.T @ A)
            R, Z = L.T, scipy.linalg.solve_triangular(L, A.T @ Y, lower=True)
        except np.linalg.LinAlgError:
            R, Z = A, Y
        for j in range(Y.shape[1]):
            c[on, j] = scipy.optimize.nnls(R, Z[:, j])[0] / s[on]
    return c[:, 0] if y.ndim == 1 else c


def _standardised(e: np.ndarray, var: np.ndarray) -> np.ndarray:
    """``e / √var`` (0 where ``var`` is 0)."""
    sd = np.sqrt(var)
    return np.divide(e, sd, out=np.zeros_like(e), where=sd > 0)


def _ratio(num: np.ndarray, den: np.ndarray, kind: np.ndarray) -> np.ndarray:
    """``(F, 6)``: per row, the median of ``√(num / den)`` over the rows of its ``kind`` (where both are finite and
    ``den`` positive); at least 1."""
    ok = np.isfinite(num) & np.isfinite(den) & (den > 0)
    r = np.sqrt(np.maximum(np.where(ok, num, 0.0), 0.0) / np.where(ok, den, 1.0))
    out = np.ones(num.shape)
    for k in np.unique(kind):
        on = ok & (kind == k)
        out[kind == k] = max(float(np.median(r[on])), 1.0) if on.any() else 1.0
    return out


def held_out_ratio(cal, noise=None, kept=None, share=None) -> tuple[np.ndarray, np.ndarray]:
    """``(ρ carrying, ρ free)``, each ``(F, 6)`` per output row: the median over the rows of its kind (with
    the correction, or the affine fit's) of the chosen model's cross-validated RMSE over its in-sample RMSE,
    over the rows where the row's face carries and where it carries nothing (``cal.model.cv_split``). The
    carrying mean squares are less the reference's noise in them (the free rows' targets are zero, without
    noise): ``noise (F, 6)`` its mean variance in the row's targets (output frame) where the face carries,
    ``kept (F, 6)`` the mean of ``h V`` there (what the correction's coefficients kept of it: held out it
    adds, in sample it is missing); then ``ρ² − 1`` times the folds' training share
    (``cal.model.cv_train_share``: module docstring). A calibration without the split (a file that predates
    it) has one figure for both, of the pooled RMSEs (``cv_rmse["chosen"]`` over ``meta["fit_residual_rms"]``;
    the noise × ``share (F,)``, the share of the samples where the face carries). Rows whose in-sample figure
    is not positive are left out; at least 1; 1 where no cross-validation ran (``model="linear"``)."""
    F = len(cal.output_faces)
    v = np.zeros((F, 6)) if noise is None else noise
    hv = np.zeros((F, 6)) if kept is None else kept
    ra = list(cal.model.row_alpha or [])
    kind = np.array([a is not None for a in ra]).reshape(F, 6) if len(ra) == 6 * F else np.zeros((F, 6), dtype=bool)
    split = np.asarray(cal.model.cv_split or [], dtype=float)
    if split.shape == (6 * F, 2, 2):
        s, t = split.reshape(F, 6, 2, 2) ** 2, cal.model.cv_train_share or 1.0
        rho = _ratio(s[..., 0, 0] - v - hv, s[..., 0, 1] - v + hv, kind), _ratio(s[..., 1, 0], s[..., 1, 1], kind)
        return tuple(np.sqrt(1.0 + t * (r * r - 1.0)) for r in rho)
    cv = np.asarray((cal.model.cv_rmse or {}).get("chosen") or [], dtype=float)
    fit = np.asarray(cal.meta.get("fit_residual_rms", np.full((6, 6), np.nan)), dtype=float)[np.asarray(cal.output_faces) - 1]
    if cv.size != 6 * F:
        return np.ones((F, 6)), np.ones((F, 6))
    w = np.ones((F, 1)) if share is None else np.asarray(share, dtype=float).reshape(F, 1)
    r = _ratio(cv.reshape(F, 6) ** 2 - w * (v + hv), fit**2 - w * (v - hv), kind)
    return r, r


def correction_leverage(cal, groups, blocks, offsets, row_alpha=None) -> np.ndarray:
    """``(n, F, 6)`` the leverage the correction's features add to each sample, per output row.

    The design of a face's rows is the affine fit's (an offset column per session, the group's
    counts) beside the correction's features that its rows use. With the affine part projected out
    (``_cv.ridge_paths``: the Schur complement ``S = U diag(s²) Uᵀ`` of the features' Gram) a row
    fitted with the ridge ``α`` (its ``row_alpha``, relative to the mean of ``s²``) moves with the
    reference's noise at a sample with projected features ``r`` by ``Σ_k s²_k / (s²_k + α s̄²)² (u_kᵀ
    r)²`` times that noise (``α = 0``: the hat matrix's diagonal, whose sum is the number of features);
    on the ``n`` samples of ``blocks`` (the error model's subsample: a list of ``(x (m, 36), k)``, counts
    less session ``k``'s tare ``offsets[k]``), scaled from ``n`` to the rows the correction was fitted
    on. ``row_alpha`` ``(6F,)``: default the model's; rows without a correction 0. Zero for ``linear``.
    """
    from ._cv import _eliminate  # deferred: the error model needs it for fits only

    n, F, n_int = sum(len(x) for x, _ in blocks), len(cal.output_faces), len(offsets)
    H = np.zeros((n, F, 6))
    if cal.correction is None or n == 0:
        return H
    ra = cal.model.row_alpha if row_alpha is None else row_alpha
    ra = np.array([np.nan if a is None else float(a) for a in ra]) if ra is not None and len(ra) == 6 * F \
        else np.zeros(6 * F)
    n_fit = max(int(cal.meta.get("n_samples_fitted", n)), n)
    n_corr = n_fit / np.ceil(n_fit / MAX_ROWS)  # every stride-th sample (_nlfit.PolyAccumulator)
    faces = [(g, k, np.flatnonzero(np.any(cal.correction.coef[6 * k : 6 * k + 6] != 0, axis=0)))
             for g in groups for k in np.unique(g.rows // 6)]
    faces = [(g, k, used) for g, k, used in faces if used.size]
    # faces whose rows use the same features share one design (a joint fit's free faces often do)
    keys = list(dict.fromkeys((id(g), tuple(used)) for g, _, used in faces))

    def designs(x, k):  # per distinct feature set: the affine design and those features
        onehot = np.zeros((len(x), n_int))
        onehot[:, k] = 1.0
        phi = cal.correction.features(x + (offsets[k] - cal.offset))
        affine = {id(g): np.concatenate([onehot, x[:, g.inputs]], axis=1) for g in groups}
        return {key: np.concatenate([affine[key[0]], phi[:, list(key[1])]], axis=1) for key in keys}

    G, kept_designs = {}, []  # the designs are kept for the second pass (≤ ERROR_MODEL_SAMPLES rows)
    for x, k in blocks:
        full = designs(x, k)
        kept_designs.append(full)
        for key, D in full.items():
            G[key] = G.get(key, 0.0) + D.T @ D
    proj, maps = {}, {}  # per key: the features' regression on the affine part; per (key, α) the map to ‖·‖²
    for g, face, used in faces:
        key = (id(g), tuple(used))
        na = n_int + g.inputs.size
        if key not in proj:
            P, S = _eliminate(G[key], np.arange(na))
            s2, U = np.linalg.eigh(S[na:, na:])
            keep = s2 > LEVERAGE_RTOL * max(s2[-1], 0.0)
            proj[key] = (P @ G[key][:na, na:], s2[keep], U[:, keep], float(np.mean(np.clip(s2, 0.0, None))) or 1.0)
        _, s2, U, lam = proj[key]
        for a in np.unique(ra[6 * face : 6 * face + 6][np.isfinite(ra[6 * face : 6 * face + 6])]):
            maps.setdefault((key, a), U * (np.sqrt(s2) / (s2 + a * lam)))
    at = 0
    for (x, k), full in zip(blocks, kept_designs):
        rows = slice(at, at + len(x))
        at = rows.stop
        r, hs = {}, {}  # per key its projected features; per (key, α) the leverage (faces often share both)
        for g, face, used in faces:
            key = (id(g), tuple(used))
            if key not in r:
                na = n_int + g.inputs.size
                r[key] = full[key][:, na:] - full[key][:, :na] @ proj[key][0]
            ra_f = ra[6 * face : 6 * face + 6]
            for a in np.unique(ra_f[np.isfinite(ra_f)]):
                if (key, a) not in hs:
                    hs[(key, a)] = np.clip(_row_norms2(r[key], maps[(key, a)]), 0.0, 1.0) * n / n_corr
                H[rows, face][:, ra_f == a] = hs[(key, a)][:, None]
    return H


def _row_norms2(D: np.ndarray, M: np.ndarray) -> np.ndarray:
    Z = D @ M
    Z *= Z
    return Z.sum(axis=1)


def fit_error_model(cal, groups, subsample, mounts, offsets, ref_covs, gauge_cov) -> ErrorModel:
    """The sample's own error and the coverage scale, from the training subsample (module docstring).

    Parameters
    ----------
    cal : Calibration
        The fitted calibration (matrix, correction, output faces, model choice).
    groups : list of CovarianceGroup
        The fit's least-squares problems (a group of 6 inputs: a face fitted on its own rows).
    subsample : list of list of SessionBlock
        Per session, every n-th training sample (``GramPass.subsample``).
    mounts : list of MountGeometry
    offsets : ndarray, shape (n_sessions, 36)
        Each session's tare: the mean of its counts at rest.
    ref_covs : list of ndarray (6, 6) or None
        The reference's covariance at rest per session, in S_A (N², N²·m, N²·m²).
    gauge_cov : ndarray, shape (36, 36)
        Gauge noise at rest, counts².
    """
    idx = np.asarray(cal.output_faces) - 1
    F = idx.size
    own = np.zeros(F, dtype=bool)  # faces fitted on their own rows (carrying or at rest) alone
    for g in groups:
        if g.inputs.size == 6:
            own[g.rows // 6] = True
    n = sum(len(b.counts) for blocks in subsample for b in blocks)
    E, V = np.zeros((n, F, 6)), np.zeros((n, F, 6), dtype=np.float32)  # residuals, the reference's noise in them
    q, L, at = np.zeros((n, F)), np.zeros(n, dtype=bool), 0
    C, v_out = np.zeros((n, F), dtype=bool), np.zeros((len(offsets), F, 6))  # carries; the noise in the targets
    A_out = cal._apply[idx].reshape(6 * F, N_GAUGES).T
    X = []  # per block, counts less the session's tare (float32) and the session: the leverage, the sandwich
    loaded = []  # per block, the faces loaded
    spans = []  # each session's rows
    for k, (blocks, mount, off, rc) in enumerate(zip(subsample, mounts, offsets, ref_covs)):
        first = at
        v = None if rc is None else np.einsum("fij,jk,fik->fi", mount.X_face_ati, rc, mount.X_face_ati)[idx]
        if rc is not None:  # in the output frame
            v_out[k] = np.broadcast_to(np.diag(rc), (F, 6)) if cal.output_frame == "reference" else v
        for b in blocks:
            T, carries, usable, _ = block_targets(np.asarray(b.reference, float), b.loaded, mount, "face")
            rows = slice(at, at + int(usable.sum()))
            at = rows.stop
            counts = np.asarray(b.counts, float)[usable]
            if cal.correction is None:  # the matrix by a BLAS product: 0.4 against 4 ms (wrenches' einsum) a 10⁴
                W = ((counts - off) @ A_out).reshape(-1, F, 6)
            else:
                W = cal.wrenches(counts, offset=off)[:, idx]
            X.append(((counts - off).astype(np.float32), k))
            loaded.append(b.loaded[usable])
            C[rows] = carries[usable][:, idx]
            E[rows] = T[usable][:, idx] - W
            q[rows], L[rows] = face_q(W), b.loaded[usable].any(axis=1)
            if v is not None:
                V[rows] = carries[usable][:, idx, None] * v
        spans.append(slice(first, at))
    counts = None
    E, V, L, phi = E[:at], V[:at], L[:at], load_features(q[:at])  # (n, F, 6), (n, F, 6), (n,), (n, F, 4)
    del q
    H = correction_leverage(cal, groups, X, offsets) if cal.correction is not None else None
    CV, lev = np.zeros(E.shape), np.zeros(E.shape[:2])  # each row's coefficients' variance (face frames), leverage
    groups = list(groups)
    if X:  # the counts less the session's tare, and the session, of every subsample row
        xo, sess = np.concatenate([x for x, _ in X]), np.concatenate([np.full(len(x), k) for x, k in X])
        loaded = np.concatenate(loaded)
        for i, g in enumerate(groups):
            groups[i], h, cv = _with_sandwich(g, cal, xo, sess, offsets, loaded, C[:at], E)
            faces = np.unique(g.rows // 6)
            CV[:, faces], lev[:, faces] = cv, h[:, None]
        xo = None
    del X, loaded
    C = C[:at]
    n_carry = C.sum(axis=0)
    noise, kept = np.zeros((F, 6)), np.zeros((F, 6))  # means over the samples where the face carries, output frame
    for k, rows in enumerate(spans):
        noise += C[rows].sum(axis=0)[:, None] * v_out[k] / np.maximum(n_carry, 1)[:, None]
        if H is not None:
            kept += (H[rows] * C[rows][..., None]).sum(axis=0) * v_out[k] / np.maximum(n_carry, 1)[:, None]
    rho = held_out_ratio(cal, noise, kept, n_carry / max(at, 1))
    if at == 0:  # no usable sample in the subsample: the coefficients' term alone
        return ErrorModel(variance_coef=np.zeros((6 * F, N_FEATURES)), residual_corr=np.broadcast_to(np.eye(6), (F, 6, 6)),
                          scale=float(rho[0].max()), groups=groups)
    A = cal._apply[idx]
    floor = np.einsum("fia,ab,fib->fi", A, gauge_cov, A)  # gauge noise through the matrix (F, 6)
    coef, kept = np.zeros((F, 6, N_FEATURES)), np.zeros((F, 6, N_FEATURES))  # the model's error; h V
    # in sample a residual holds the coefficients' error the other rows' noise put there (CV) and lacks
    # its own row's share (2h): E² ≈ σ² (1 − 2h) + CV
    HV = V * H if H is not None else None
    Y = E**2
    Y *= 1.0 + 2.0 * lev[..., None]
    Y -= CV
    Y -= V
    if HV is not None:
        Y += HV
    for f in range(F):  # the six axes of a face share their features: one Gram for the unweighted fits
        coef[f] = _nnls(phi[:, f], Y[:, f]).T
        coef[f, :, 0] = np.maximum(coef[f, :, 0], floor[f])
        if HV is not None and HV[:, f].any():
            kept[f] = _nnls(phi[:, f], HV[:, f]).T
        for a in np.flatnonzero(V[:, f].any(axis=0)):  # weights 1 / (v̄ + V) (equal weights otherwise: the same fit)
            d = np.mean(phi[:, f] @ coef[f, a]) + V[:, f, a]
            if np.all(d > 0):
                coef[f, a] = _nnls(phi[:, f] / d[:, None], Y[:, f, a] / d)
                coef[f, a, 0] = max(coef[f, a, 0], floor[f, a])
    del Y, HV
    excess = np.zeros_like(coef)  # held out (module docstring): each sample's in-sample error × its part's ρ² − 1
    base = coef.copy()
    base[own, :, 3] = 0.0  # not an own-row fit's crosstalk: it never fitted it (held out already)
    part = C | own  # an own-row fit's cross-validation has no crosstalk rows: its samples count as carrying
    for f in range(F):
        grow = np.where(part[:, f, None], rho[0][f] ** 2 - 1.0, rho[1][f] ** 2 - 1.0)  # (n, 6)
        if np.all(grow == grow[0]):  # one factor: exactly on the coefficients
            excess[f] = base[f] * grow[0][:, None]
            continue
        excess[f] = _nnls(phi[:, f], (phi[:, f] @ base[f].T) * grow).T
    del H, C
    var = np.ascontiguousarray(np.matmul(phi.transpose(1, 0, 2), (coef + kept).transpose(0, 2, 1)).transpose(1, 0, 2))
    del phi
    if E.shape[0] > 2:  # each face's correlation of its six standardised residuals
        Z = np.ascontiguousarray(_standardised(E, var).transpose(1, 0, 2))  # (F, n, 6)
        Z -= Z.mean(axis=1, keepdims=True)
        cov = Z.transpose(0, 2, 1) @ Z
        del Z
        d = np.sqrt(np.einsum("fii->fi", cov))
        with np.errstate(divide="ignore", invalid="ignore"):  # an axis without error: NaN, replaced below
            corr = cov / (d[:, :, None] * d[:, None, :])
        corr = np.where(np.isfinite(corr), np.clip(corr, -1.0, 1.0), np.eye(6))
    else:
        corr = np.broadcast_to(np.eye(6), (F, 6, 6)).copy()
    # the scale: the 95 % quantile over the loaded residuals of each one's s², E² = Z² (s² var + CV + V)
    E **= 2
    E /= Z_COVERAGE**2
    E -= V + CV
    del V, CV
    zero = var <= 0
    np.divide(E, var, out=E, where=~zero)
    E[zero] = np.where(E[zero] > 0, np.inf, 0.0)
    del var
    t = E[L] if L.any() else E
    lo, hi = SCALE_BOUNDS
    scale = float(np.clip(np.sqrt(max(np.quantile(t, COVERAGE, overwrite_input=True), 0.0)), lo, hi))
    coef += excess + kept
    return ErrorModel(variance_coef=coef.reshape(6 * F, N_FEATURES), residual_corr=corr, scale=scale, groups=groups)


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
    low = [1.0 - NOISE_LIMIT_SE / np.sqrt(2.0 * max(n - 1, 1)) for n in ref_n]  # the figures' lower bounds, relative
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

"""``fit_sensor``: the model choice for any multi-axis sensor, in scikit-learn's manner.

Counts of ``m`` channels against a reference wrench: the affine least-squares fit, or
the same with a ridge-regularised polynomial correction (``_poly.py``), chosen by
cross-validation over whole loading segments (``_cv.py``). The cube's methods use the
same machinery (``_fit.py``); this is the entry point for any other sensor.
"""

from __future__ import annotations

import numpy as np
from threadpoolctl import threadpool_limits

from ._cv import ALPHAS, MODELS, N_FOLDS, FoldedGram, ModelChoice, Problem, choose_model, cross_validate, fold_bounds, \
    fold_of_segments, solve_problem, tangent_rows
from ._lstsq import StreamedQR
from ._poly import PolyCorrection, poly_features_t, poly_terms

__all__ = ["fit_sensor", "SensorFit"]

#: Channels up to which every pairwise product is a feature (beyond: squares and cubes only).
MAX_FULL_QUADRATIC = 12
#: Samples (every k-th) on which the extension beyond the range is chosen (``_cv.tangent_rows``).
MAX_EXTENSION_ROWS = 1 << 15
#: Contiguous segments a session is cut into when no ``groups`` are given.
DEFAULT_SEGMENTS = 40


class SensorFit:
    """A fitted sensor model: ``predict(counts) -> wrench``.

    Attributes
    ----------
    model : str
        ``linear`` (affine least squares) or ``poly`` (with the polynomial correction).
    choice : ModelChoice
        The cross-validated figures that chose it.
    coef_ : ndarray, shape (6, m)
        Linear part, N (and N·m) per count.
    intercept_ : ndarray, shape (6,)
        Wrench at ``center_`` counts, N and N·m.
    center_ : ndarray, shape (m,)
        Mean counts of the training data.
    correction_ : PolyCorrection or None
        The nonlinear part (of ``counts − center_``).
    """

    def __init__(self, choice, coef, intercept, center, correction=None):
        self.choice = choice
        self.coef_ = coef
        self.intercept_ = intercept
        self.center_ = center
        self.correction_ = correction

    @property
    def model(self) -> str:
        return self.choice.name

    @property
    def n_features_in_(self) -> int:
        return self.center_.size

    def predict(self, counts) -> np.ndarray:
        """``(N, q)`` wrench ``[fx, fy, fz, tx, ty, tz]`` (N, N·m) from ``counts (N, m)``."""
        c = np.asarray(counts, dtype=float)
        if c.ndim != 2 or c.shape[1] != self.center_.size:
            raise ValueError(f"counts: expected shape (N, {self.center_.size}), got {c.shape}")
        x = c - self.center_
        W = x @ self.coef_.T + self.intercept_
        if self.correction_ is not None:
            W += self.correction_(x)
        return W

    def __repr__(self) -> str:
        return f"SensorFit(model={self.model!r}, channels={self.center_.size})"


def _check(counts, wrench, groups):
    c = np.asarray(counts, dtype=float)
    w = np.asarray(wrench, dtype=float)
    if c.ndim != 2 or c.shape[0] < 2:
        raise ValueError(f"counts: expected shape (N, m) with N ≥ 2, got {c.shape}")
    if w.ndim != 2 or w.shape[0] != c.shape[0]:
        raise ValueError(f"wrench: expected shape ({c.shape[0]}, 6), got {w.shape}")
    if not (np.all(np.isfinite(c)) and np.all(np.isfinite(w))):
        raise ValueError("counts, wrench: expected finite values")
    if groups is None:
        g = np.minimum(np.arange(c.shape[0]) * DEFAULT_SEGMENTS // c.shape[0], DEFAULT_SEGMENTS - 1)
    else:
        g = np.asarray(groups).reshape(-1)
        if g.shape != (c.shape[0],):
            raise ValueError(f"groups: expected shape ({c.shape[0]},), got {g.shape}")
    return c, w, g


def fit_sensor(counts, wrench, groups=None, model: str = "auto", *, n_folds: int = N_FOLDS, alphas=ALPHAS,
               block_size: int = 65536) -> SensorFit:
    """Fit a sensor's counts → wrench, choosing the model by grouped cross-validation.

    Parameters
    ----------
    counts : array-like, shape (N, m)
        Raw channels, counts.
    wrench : array-like, shape (N, 6)
        Reference ``[fx, fy, fz, tx, ty, tz]``, N and N·m (any number of columns works).
    groups : array-like, shape (N,), optional
        Loading segment of each sample: folds hold whole segments, dealt round-robin so
        every fold spans the data. Default: ``DEFAULT_SEGMENTS`` contiguous pieces.
    model : {"auto", "linear", "poly"}
        ``auto`` scores, per output group (in threes: forces, torques), the affine fit and the
        correction along its ridge path by their mean held-out score over the folds, and takes the
        correction at its best ridge only where it beats the affine fit by more than ``_cv.N_SE``
        standard errors; ``linear`` is the
        plain affine least squares everywhere, ``poly`` the correction at its best ridge.
    n_folds : int
    alphas : sequence of float
        Relative ridge strengths tried for the polynomial features.

    Returns
    -------
    SensorFit
    """
    if model not in MODELS:
        raise ValueError(f"model: expected one of {MODELS}, got {model!r}")
    c, w, g = _check(counts, wrench, groups)
    n_groups = np.unique(g).size
    K = int(min(n_folds, n_groups))
    center = c.mean(axis=0)
    scale = c.std(axis=0)
    scale = np.where(scale > 0, scale, 1.0)
    m, q = c.shape[1], w.shape[1]
    blocks = [range(m)] if m <= MAX_FULL_QUADRATIC else [[i] for i in range(m)]
    pairs, cubes = poly_terms(blocks)
    r = pairs.shape[0] + cubes.size
    nl = model != "linear" and K >= 2
    qr = StreamedQR(1 + m, q)  # the affine fit, by QR: the rows that keep it are exactly least squares
    folded = FoldedGram(1 + m + r, q, K) if nl else None
    fold = fold_of_segments(g, K) if nl else None
    with threadpool_limits(limits=1):
        for s in range(0, c.shape[0], block_size):
            sl = slice(s, s + block_size)
            x = c[sl] - center
            qr.add(np.hstack([np.ones((x.shape[0], 1)), x / scale]), w[sl])
            if nl:
                order, bounds = fold_bounds(fold[sl], K)
                uT = x[order].T / scale[:, None]
                ZT = np.empty((1 + m + r + q, x.shape[0]))
                ZT[0] = 1.0
                ZT[1 : 1 + m] = uT
                poly_features_t(uT, pairs, cubes, out=ZT[1 + m : 1 + m + r])
                ZT[1 + m + r :] = w[sl][order].T
                folded.add_sorted(ZT, bounds)
        X = qr.solve().X  # (1 + m, q)
        X_lin = X.copy()
        D = np.zeros((q, r))
        if nl:
            prob = Problem(np.arange(1 + m), np.arange(1 + m, 1 + m + r), np.arange(q), 1.0 / w.std(axis=0).clip(1e-300))
            choice = choose_model([(cross_validate(folded, [prob], alphas), [prob.weight])], model, n_groups)
            ra = np.array([np.nan if a is None else a for a in (choice.row_alpha or [None] * q)])
            levels = np.unique(ra[np.isfinite(ra)])
            for a, Xp in zip(levels, solve_problem(folded, prob, levels) if levels.size else []):
                X[:, ra == a] = Xp[: 1 + m, ra == a]
                D[ra == a] = Xp[1 + m :, ra == a].T
        else:
            why = "the affine least squares, as requested" if model == "linear" else \
                f"the affine least squares: {n_groups} loading segment(s) are too few to cross-validate"
            choice = ModelChoice(name="linear", requested=model, n_segments=n_groups, reason=why)
    coef = (X[1 : 1 + m] / scale[:, None]).T
    u = (c - center) / scale  # the range fitted: the correction clamps its channels to it (_poly.py)
    edge = ((X[1 : 1 + m] - X_lin[1 : 1 + m]) / scale[:, None]).T  # beyond the range: the linear fit's slope
    correction = None
    if choice.name == "poly":
        lo, hi = u.min(axis=0), u.max(axis=0)
        sub = np.arange(0, c.shape[0], max(1, c.shape[0] // MAX_EXTENSION_ROWS))

        def build(idx, v):
            ZT = np.empty((1 + m + r + q, idx.size))
            ZT[0] = 1.0
            vT = np.ascontiguousarray(v.T)
            ZT[1 : 1 + m] = vT
            poly_features_t(vT, pairs, cubes, out=ZT[1 + m : 1 + m + r])
            ZT[1 + m + r :] = w[sub[idx]].T
            return ZT

        with threadpool_limits(limits=1):
            tangent = tangent_rows(build, 1 + m + r, u[sub], lo, hi, prob, ra, 1 + m + pairs.shape[0] + np.arange(cubes.size))
        correction = PolyCorrection(scale, pairs, cubes, D, lo, hi, edge, tangent=tangent)
    return SensorFit(choice, coef, X[0].copy(), center, correction)

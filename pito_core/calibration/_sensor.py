"""``fit_sensor``: the model choice for any multi-axis sensor, in scikit-learn's manner.

Counts of ``m`` channels against a reference wrench: the affine least-squares fit, or
the same with a ridge-regularised polynomial correction (``_poly.py``), chosen by
cross-validation over whole loading segments (``_cv.py``). The cube's methods use the
same machinery (``_fit.py``); this is the entry point for any other sensor.
"""

from __future__ import annotations

import numpy as np
from threadpoolctl import threadpool_limits

from ._cv import ALPHAS, MODELS, N_FOLDS, FoldedQR, ModelChoice, Problem, choose_model, cross_validate, fold_of_segments, solve_problem
from ._poly import PolyCorrection, poly_terms

__all__ = ["fit_sensor", "SensorFit"]

#: Channels up to which every pairwise product is a feature (beyond: squares and cubes only).
MAX_FULL_QUADRATIC = 12
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
        ``auto`` picks ``poly`` only where its held-out error beats the affine fit's
        (``_cv.MARGIN``); ``linear`` is the plain affine least squares.
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
    corr = PolyCorrection(scale, pairs, cubes, np.zeros((q, r)))
    folded = FoldedQR(1 + m + (r if nl else 0), q, K if nl else 1)
    fold = fold_of_segments(g, K) if nl else np.zeros(c.shape[0], dtype=np.int64)
    with threadpool_limits(limits=1):
        for s in range(0, c.shape[0], block_size):
            x = c[s : s + block_size] - center
            parts = [np.ones((x.shape[0], 1)), x / scale] + ([corr.features(x)] if nl else [])
            folded.add(np.hstack(parts), w[s : s + block_size], fold[s : s + block_size])
        a = np.arange(1 + m)
        prob = Problem(a, np.arange(1 + m, folded.p) if nl else np.zeros(0, np.int64), np.arange(q), 1.0 / w.std(axis=0).clip(1e-300))
        if nl:
            choice = choose_model([(cross_validate(folded, [prob], alphas), [prob.weight])], model, n_groups)
        else:
            why = "the affine least squares, as requested" if model == "linear" else \
                f"the affine least squares: {n_groups} loading segment(s) are too few to cross-validate"
            choice = ModelChoice(name="linear", requested=model, n_segments=n_groups, reason=why)
        X = solve_problem(folded, prob, np.inf if choice.name == "linear" else choice.alpha)
    coef = (X[1 : 1 + m] / scale[:, None]).T
    correction = PolyCorrection(scale, pairs, cubes, X[1 + m :].T) if choice.name == "poly" else None
    return SensorFit(choice, coef, X[0].copy(), center, correction)

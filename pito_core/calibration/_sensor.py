"""``fit_sensor``: the model choice for any multi-axis sensor, in scikit-learn's manner.

Counts of ``m`` channels against a reference wrench: the affine least-squares fit, or
the same with a ridge-regularised polynomial correction (``_poly.py``), chosen by
cross-validation over whole loading segments (``_cv.py``). The cube's methods use the
same machinery (``_fit.py``); this is the entry point for any other sensor.
"""

from __future__ import annotations

import numpy as np
from threadpoolctl import threadpool_limits

from ._cv import ALPHAS, MODELS, N_FOLDS, N_SE, SCORE_ATOL, FoldedGram, ModelChoice, Problem, ridge_paths, \
    cross_validate, fold_bounds, fold_of_segments, solve_problem
from ._lstsq import StreamedQR
from ._poly import PolyCorrection, ray_into, poly_features_t, poly_terms

__all__ = ["fit_sensor", "SensorFit"]

#: Channels up to which every pairwise product is a feature (beyond: squares and cubes only).
MAX_FULL_QUADRATIC = 12
#: Contiguous segments a session is cut into when no ``groups`` are given.
DEFAULT_SEGMENTS = 40
#: Groups up to which each is a fold of its own (leave one group out); beyond, ``n_folds`` folds.
MAX_LEAVE_ONE_OUT = 12
#: The corrections scored beside the affine fit, simplest first: each scaled channel's own square
#: and cube (no products: a new loading direction meets no untrained product); every square and
#: pairwise product (``MAX_FULL_QUADRATIC``); the same with each channel's cube.
FAMILIES = ("separable", "quadratic", "cubic")
#: Fewer folds than this: the affine fit (a standard error over fewer is itself too noisy, and each
#: held-out group then leaves a large part of the loads untrained).
MIN_FOLDS = 4
#: Outputs chosen together (forces, torques).
OUTPUT_GROUP = 3
#: How a correction continues beyond the range of its training channels (each sample drawn back
#: along its ray from the mean counts to the range's edge, ``x_c = t x``; ``_poly.py``), simplest
#: first: ``slope``, its value at the edge plus the linear fit's slope from there; ``tangent``, the
#: polynomial's tangent at the edge; ``fade``, the linear fit plus ``t`` times what the correction
#: adds at the edge (it fades to the affine fit as ``1/distance``). Chosen per output group on the
#: held-out groups that lie beyond their folds' range (``_choose``).
EXTENSIONS = ("slope", "tangent", "fade")


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
    row_model_ : list of str
        Per output: ``linear`` (the affine fit) or the correction's family (``FAMILIES``).
    extension_ : list of str
        Per output: how its correction continues beyond the trained range (``EXTENSIONS``), or ``""``.
    reach_ : float
        Multiple of the trained range (along a sample's ray from ``center_``) up to which the
        extensions hold, as far as held-out groups reached; beyond it every correction fades.
    """

    def __init__(self, choice, coef, intercept, center, correction=None, row_model=None, extension=None,
                 linear=None, reach=1.0):
        self.choice = choice
        self.row_model_ = list(row_model or ["linear"] * np.shape(intercept)[0])
        self.extension_ = list(extension or [""] * np.shape(intercept)[0])
        self.coef_ = coef
        self.intercept_ = intercept
        self.center_ = center
        self.correction_ = correction
        self._linear = linear  # (coef, intercept) of the affine fit, for the ``fade`` rows
        self.reach_ = float(reach)

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
        W = self._predict(x)
        if self.correction_ is None:
            return W
        _, t = self.correction_.ray(x)
        s = 1.0 / np.maximum(t, 1e-300)  # how far beyond the trained range, along the ray (1: inside)
        R = np.array([1.0 if e == "fade" else max(self.reach_, 1.0) for e in self.extension_])
        far = s[:, None] > R  # (N, q): beyond the reach the held-out groups tested: fade to the affine fit
        rows = np.flatnonzero(far.any(axis=1))
        if rows.size:
            for r in np.unique(R):
                cols = np.flatnonzero((R == r) & far[rows].any(axis=0))
                if cols.size == 0:
                    continue
                f = r / s[rows]  # x_R = f x: the reach on the ray
                xr = x[rows] * f[:, None]
                lin, lin_r = self._affine(x[rows])[:, cols], self._affine(xr)[:, cols]
                faded = lin + f[:, None] * (self._predict(xr)[:, cols] - lin_r)
                W[rows[:, None], cols] = np.where(far[rows][:, cols], faded, W[rows[:, None], cols])
        return W

    def _predict(self, x):
        W = x @ self.coef_.T + self.intercept_
        return W if self.correction_ is None else W + self.correction_(x)

    def _affine(self, x):
        return x @ self._linear[0].T + self._linear[1]

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


def _family_terms(family: str, pairs: np.ndarray, cubes: np.ndarray) -> np.ndarray:
    """Indices into the correction's terms (``pairs`` then ``cubes``, ``poly_terms``) of ``family``:
    ``separable`` each channel's own square and cube; ``quadratic`` every pair; ``cubic`` all."""
    P = pairs.shape[0]
    if family == "separable":
        return np.concatenate([np.flatnonzero(pairs[:, 0] == pairs[:, 1]), P + np.arange(cubes.size)])
    return np.arange(P if family == "quadratic" else P + cubes.size)


def _best(cv: dict, weight: np.ndarray):
    """Per output, ``(family, ridge index)`` of the best mean held-out score of the correction over the
    folds (the ridge path without its affine end), chosen per output group of ``OUTPUT_GROUP``."""
    ok = cv["n_rows"] > 0
    sse = np.nan_to_num(cv["sse"])[:, ok] * weight**2  # (A, K, J, q), outputs on one footing
    out = []
    for g in range(0, sse.shape[3], OUTPUT_GROUP):
        score = sse[..., g : g + OUTPUT_GROUP].sum(axis=3) / cv["n_rows"][ok][None, :, None]  # (A, K, J)
        mean = score.mean(axis=1)  # (A, J)
        a, j = np.unravel_index(np.argmin(mean[1:]), mean[1:].shape)
        out += [(int(j), int(a) + 1)] * min(OUTPUT_GROUP, sse.shape[3] - g)
    return out


def _fold_model(G, p, m, q, probs, picks, alphas):
    """``(X (1 + m, q), D (q, r), X_lin (1 + m, q))`` of the per-output ``picks`` (family, ridge index;
    family ``-1``: affine) solved from the Gram ``G``: linear part, correction, and the affine fit."""
    X_lin = ridge_paths(G, p, [probs[0]], [np.inf])[0][0][: 1 + m]
    X, D = X_lin.copy(), np.zeros((q, p - 1 - m))
    for j, pr in enumerate(probs):
        for a in sorted({a for jj, a in picks if jj == j}):
            rows = np.array([jj == j and aa == a for jj, aa in picks])
            Xp = ridge_paths(G, p, [pr], [alphas[a]])[0][0]
            X[:, rows] = Xp[: 1 + m, rows]
            D[np.ix_(rows, pr.b - 1 - m)] = Xp[1 + m :, rows].T
    return X, D, X_lin


def _correction(scale, pairs, cubes, D, lo, hi, edge, ext):
    """The correction of rows ``D`` drawn back into ``[lo, hi]``; the ``tangent`` rows of ``ext`` continue
    along the polynomial's tangent beyond (the others with the linear fit's slope; ``fade``: ``SensorFit``)."""
    return PolyCorrection(scale, pairs, cubes, D, lo, hi, edge, tangent=np.array([e == "tangent" for e in ext]))


def _held_out(c, w, center, scale, fold, folded, probs, picks, alphas, pairs, cubes):
    """``(E, K, q)`` held-out sums of squares of the corrections ``picks`` as they are used: each fold's
    model refitted without it (its Gram down-dated), its correction continued beyond the range of the
    other folds' channels by each of ``EXTENSIONS``; and the reach they tested: the largest factor by
    which a held-out sample lies beyond its training folds' range, along its ray (1: none beyond)."""
    m, q, K, p = c.shape[1], w.shape[1], folded.n_folds, folded.p
    u = (c - center) / scale
    sse = np.zeros((len(EXTENSIONS), K, q))
    reach = 1.0
    rows = [np.flatnonzero(fold == k) for k in range(K)]
    f_lo = np.array([u[r].min(axis=0) if r.size else np.full(m, np.inf) for r in rows])  # (K, m)
    f_hi = np.array([u[r].max(axis=0) if r.size else np.full(m, -np.inf) for r in rows])
    for k, te in enumerate(rows):
        if te.size == 0 or te.size == c.shape[0]:
            continue
        lo, hi = np.delete(f_lo, k, axis=0).min(axis=0), np.delete(f_hi, k, axis=0).max(axis=0)
        X, D, X_lin = _fold_model(folded.total(exclude=k), p, m, q, probs, picks, alphas)
        uk = u[te]
        t = ray_into(uk, lo, hi)
        out = t < 1.0
        pred = uk @ X[1:] + X[0]  # the fold's model, inside the range: its polynomial
        pred[~out] += poly_features_t(np.ascontiguousarray(uk[~out].T), pairs, cubes).T @ D.T
        res = ((pred[~out] - w[te][~out]) ** 2).sum(axis=0)
        sse[:, k] = res
        if not out.any():
            continue
        reach = max(reach, 1.0 / max(float(t[out].min()), 1e-300))
        edge = ((X[1:] - X_lin[1:]) / scale[:, None]).T
        corr = PolyCorrection(scale, pairs, cubes, D, lo, hi, edge, tangent=np.ones(q, dtype=bool))
        phi, back, (dphi, dray) = corr.all_terms(c[te][out] - center)
        slope = pred[out] + phi @ D.T + back @ edge.T  # beyond: the value at the edge, the linear fit's slope
        lin = uk[out] @ X_lin[1:] + X_lin[0]
        for e, name in enumerate(EXTENSIONS):
            if name == "slope":
                y = slope
            elif name == "tangent":
                y = slope + dphi @ D.T + dray @ edge.T
            else:  # fade
                y = lin + t[out][:, None] * (slope - lin)
            sse[e, k] += ((y - w[te][out]) ** 2).sum(axis=0)
    return sse, reach


def _choose(cv: dict, held: np.ndarray, weight: np.ndarray, requested: str, n_se: float = N_SE):
    """Per output, ``(use, extension)``: whether the correction is kept, and how it continues beyond.

    ``cv["sse"][0] (K, ·, q)`` the affine fit's held-out sums of squares, ``held (E, K, q)`` the
    correction's as used, under each extension (``_held_out``). A candidate's score on a fold (a group,
    or a deal of groups) is its mean weighted square over the fold, per output group of
    ``OUTPUT_GROUP``. The extension is the one of the best mean score over the folds (ties: the
    simplest); then the one-standard-error rule (Hastie et al.): the correction only where its mean
    beats the affine fit's by more than ``n_se`` standard errors (over folds) of its own.
    ``poly``: the correction, with the best extension.
    """
    ok = cv["n_rows"] > 0
    n = cv["n_rows"][ok]
    lin = np.nan_to_num(cv["sse"][0, :, 0])[ok] * weight**2  # (K, q)
    cor = held[:, ok] * weight**2  # (E, K, q)
    K = lin.shape[0]
    out = []
    for g in range(0, lin.shape[1], OUTPUT_GROUP):
        cols = slice(g, g + OUTPUT_GROUP)
        s_lin = lin[:, cols].sum(axis=1) / n  # (K,)
        s = cor[:, :, cols].sum(axis=2) / n  # (E, K)
        mean = s.mean(axis=1)
        e = int(np.flatnonzero(mean <= mean.min() + SCORE_ATOL)[0])
        se = float(np.std(s[e], ddof=1) / np.sqrt(K)) if K > 1 else np.inf
        use = requested == "poly" or s_lin.mean() - mean[e] > max(n_se * se, SCORE_ATOL)
        out += [(use, e)] * min(OUTPUT_GROUP, lin.shape[1] - g)
    return out


def _choice(cv: dict, held: np.ndarray, weight: np.ndarray, best, chosen, requested: str, n_segments: int,
            names) -> ModelChoice:
    """The :class:`ModelChoice` of the per-output ``best`` (family, ridge index) corrections and the
    ``chosen`` ``(use, extension)`` (``_choose``), with their cross-validated figures."""
    K = cv["sse"].shape[1]
    n = max(int(cv["n_rows"].sum()), 1)
    q = held.shape[2]
    lin = np.nan_to_num(cv["sse"][0, :, 0, :q])  # (K, q)
    e_best = np.array([held[e, :, o] for o, (_, e) in enumerate(chosen)]).T  # (K, q)
    per = {"linear": lin, "poly": e_best, "chosen": np.where([u for u, _ in chosen], e_best, lin)}
    rmse = {key: np.sqrt(e.sum(axis=0) / n).tolist() for key, e in per.items()}
    folds = {key: (e * weight**2).sum(axis=1) for key, e in per.items()}
    score = {key: float(np.sqrt(f.sum() / (n * q))) for key, f in folds.items()}
    alphas = cv["alphas"]
    row_alpha = [float(alphas[a]) if use else None for (j, a), (use, _) in zip(best, chosen)]
    used = [a for a in row_alpha if a is not None]
    ratio = score["chosen"] / score["linear"] if score["linear"] > 0 else float("nan")
    if requested == "auto":
        kinds = ", ".join(f"{sum(j == i and u for (j, _), (u, _) in zip(best, chosen))} {name}"
                          for i, name in enumerate(names))
        why = (f"cross-validated over {K} folds of {n_segments} loading groups: per output group (forces, torques), "
               f"the best correction where its mean held-out score beats the affine fit's by more than {N_SE:g} "
               f"standard error (over folds) of its own: {q - len(used)} affine, {kinds}; held-out error {ratio:.2f}× "
               "the affine fit's")
    else:
        pr = score["poly"] / score["linear"] if score["linear"] > 0 else float("nan")
        why = f"{requested} as requested (cross-validated polynomial/affine held-out error {pr:.2f}×)"
    return ModelChoice(name="poly" if used else "linear", requested=requested, alpha=max(used) if used else None,
                       row_alpha=row_alpha if used else [], cv_rmse=rmse, cv_score=score,
                       folds_won=int(np.sum(folds["chosen"] < folds["linear"])), n_folds=K,
                       n_segments=int(n_segments), reason=why)


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
        Loading group of each sample: folds hold whole groups, one group per fold up to
        ``MAX_LEAVE_ONE_OUT`` groups, else ``n_folds`` folds dealt round-robin so every fold
        spans the data. Default: ``DEFAULT_SEGMENTS`` contiguous pieces.
    model : {"auto", "linear", "poly"}
        ``auto`` scores, per output group (forces, torques), the affine fit and each correction of
        ``FAMILIES`` (each channel's square and cube; a full quadratic of the channels; the same with
        cubes) along its ridge path by
        their mean held-out score over the folds; the best is then scored as it is used, continued
        beyond each fold's training range by each of ``EXTENSIONS``, and kept (with the extension of
        the best mean) only where it beats the affine fit by more than ``_cv.N_SE`` standard errors
        (the one-standard-error rule). Past the farthest reach its held-out groups tested
        (``SensorFit.reach_``) the correction fades to the affine fit. ``linear`` is the plain affine
        least squares everywhere, ``poly`` the best correction. Fewer than ``MIN_FOLDS`` folds: the
        affine fit.
    n_folds : int
        Folds when there are more than ``MAX_LEAVE_ONE_OUT`` groups.
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
    K = int(n_groups if n_groups <= MAX_LEAVE_ONE_OUT else min(n_folds, n_groups))
    center = c.mean(axis=0)
    scale = c.std(axis=0)
    scale = np.where(scale > 0, scale, 1.0)
    m, q = c.shape[1], w.shape[1]
    blocks = [range(m)] if m <= MAX_FULL_QUADRATIC else [[i] for i in range(m)]
    pairs, cubes = poly_terms(blocks)
    r = pairs.shape[0] + cubes.size
    nl = model != "linear" and K >= MIN_FOLDS
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
        chosen, picks, reach = [(False, 0)] * q, [(-1, 0)] * q, 1.0
        if nl:
            sd = w.std(axis=0)
            weight = 1.0 / np.where(sd > 0, sd, 1.0)
            probs = [Problem(np.arange(1 + m), 1 + m + _family_terms(f, pairs, cubes), np.arange(q), weight)
                     for f in FAMILIES]
            cv = cross_validate(folded, probs, alphas)
            best = _best(cv, weight)
            held, reach = _held_out(c, w, center, scale, fold, folded, probs, best, cv["alphas"], pairs, cubes)
            chosen = _choose(cv, held, weight, model)
            choice = _choice(cv, held, weight, best, chosen, model, n_groups, FAMILIES)
            picks = [pk if use else (-1, 0) for pk, (use, _) in zip(best, chosen)]
            for j, pr in enumerate(probs):
                for a in sorted({a for jj, a in picks if jj == j}):
                    rows = np.array([jj == j and aa == a for jj, aa in picks])
                    Xp = solve_problem(folded, pr, [cv["alphas"][a]])[0]
                    X[:, rows] = Xp[: 1 + m, rows]
                    D[np.ix_(rows, pr.b - 1 - m)] = Xp[1 + m :, rows].T
        else:
            why = "the affine least squares, as requested" if model == "linear" else \
                f"the affine least squares: {n_groups} loading segment(s) are too few to cross-validate"
            choice = ModelChoice(name="linear", requested=model, n_segments=n_groups, reason=why)
    coef = (X[1 : 1 + m] / scale[:, None]).T
    u = (c - center) / scale  # the range fitted: the correction draws its channels back into it (_poly.py)
    edge = ((X[1 : 1 + m] - X_lin[1 : 1 + m]) / scale[:, None]).T  # beyond the range: the linear fit's slope
    correction = None
    ext = [e for _, e in chosen]
    if choice.name == "poly":
        lo, hi = u.min(axis=0), u.max(axis=0)
        correction = _correction(scale, pairs, cubes, D, lo, hi, edge, [EXTENSIONS[e] for e in ext])
    names = ("linear",) + tuple(FAMILIES)
    extension = [EXTENSIONS[e] if j >= 0 else "" for (j, _), e in zip(picks, ext)]
    return SensorFit(choice, coef, X[0].copy(), center, correction, [names[j + 1] for j, _ in picks], extension,
                     ((X_lin[1 : 1 + m] / scale[:, None]).T, X_lin[0].copy()), reach)

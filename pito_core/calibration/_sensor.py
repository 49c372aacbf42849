"""``fit_sensor``: the model choice for any multi-axis sensor, in scikit-learn's manner.

Counts of ``m`` channels against a reference wrench: the affine least-squares fit, or
the same with a ridge-regularised polynomial correction (``_poly.py``), chosen by
cross-validation over whole loading segments (``_cv.py``). The cube's methods use the
same machinery (``_fit.py``); this is the entry point for any other sensor.
"""

from __future__ import annotations

import numpy as np
from threadpoolctl import threadpool_limits

from ._cv import ALPHAS, MODELS, N_FOLDS, N_SE, SCORE_ATOL, FoldedGram, ModelChoice, Problem, cross_validate, \
    TANGENT_GAIN, fold_bounds, fold_of_segments, solve_problem, tangent_rows
from ._lstsq import StreamedQR
from ._poly import PolyCorrection, poly_features_t, poly_terms

__all__ = ["fit_sensor", "SensorFit"]

#: Channels up to which every pairwise product is a feature (beyond: squares and cubes only).
MAX_FULL_QUADRATIC = 12
#: Samples (every k-th) on which the extension beyond the range is chosen (``_cv.tangent_rows``).
MAX_EXTENSION_ROWS = 1 << 15
#: Contiguous segments a session is cut into when no ``groups`` are given.
DEFAULT_SEGMENTS = 40
#: Groups up to which each is a fold of its own (leave one group out); beyond, ``n_folds`` folds.
MAX_LEAVE_ONE_OUT = 12
#: The corrections scored beside the affine fit, simplest first: every square and pairwise product
#: of the scaled channels (``MAX_FULL_QUADRATIC``); the same with each channel's cube.
FAMILIES = ("quadratic", "cubic")
#: Fewer folds than this: the affine fit (a standard error over fewer is itself too noisy, and each
#: held-out group then leaves a large part of the loads untrained).
MIN_FOLDS = 4
#: Outputs chosen together (forces, torques).
OUTPUT_GROUP = 3


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
    """

    def __init__(self, choice, coef, intercept, center, correction=None, row_model=None):
        self.choice = choice
        self.row_model_ = list(row_model or ["linear"] * np.shape(intercept)[0])
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


def _choose(cv: dict, weight: np.ndarray, requested: str, n_se: float = N_SE):
    """Per output, ``(family, ridge index)`` of the chosen candidate (family ``-1``: the affine fit).

    ``cv["sse"] (A, K, J, q)``: held-out sums of squares of the ``J`` families (simplest first) along
    the ridge path (``inf`` first: the affine fit, the same in every family), per output group of
    ``OUTPUT_GROUP`` (weighted by ``weight``). The best correction is the family and ridge of the best
    mean held-out score over the folds; the one-standard-error rule (Hastie et al.) keeps the affine
    fit unless the correction's mean beats it by more than ``n_se`` standard errors (over folds) of
    the correction's. ``poly``: the best correction.
    """
    ok = cv["n_rows"] > 0
    sse = np.nan_to_num(cv["sse"])[:, ok] * weight**2  # (A, K, J, q), outputs on one footing
    K = sse.shape[1]
    out = []
    for g in range(0, sse.shape[3], OUTPUT_GROUP):
        score = sse[..., g : g + OUTPUT_GROUP].sum(axis=3) / cv["n_rows"][ok][None, :, None]  # (A, K, J)
        mean = score.mean(axis=1)  # (A, J)
        best_a = 1 + np.argmin(mean[1:], axis=0)  # (J,)
        fam = mean[best_a, np.arange(best_a.size)]
        jb = int(np.argmin(fam))
        pick = (jb, int(best_a[jb]))
        if requested != "poly":
            se = float(np.std(score[best_a[jb], :, jb], ddof=1) / np.sqrt(K)) if K > 1 else np.inf
            bound = fam[jb] + max(n_se * se, SCORE_ATOL)
            if mean[0, 0] <= bound:
                pick = (-1, 0)
        out += [pick] * min(OUTPUT_GROUP, sse.shape[3] - g)
    return out


def _choice(cv: dict, weight: np.ndarray, picks, requested: str, n_segments: int, names) -> ModelChoice:
    """The :class:`ModelChoice` of per-output ``picks`` (``_choose``), with its cross-validated figures."""
    sse = np.nan_to_num(cv["sse"])  # (A, K, J, q)
    n = max(int(cv["n_rows"].sum()), 1)
    q = sse.shape[3]
    best = _choose(cv, weight, "poly")
    rows = {"linear": [(0, 0)] * q, "poly": [(a, j) for j, a in best],
            "chosen": [(0, 0) if j < 0 else (a, j) for j, a in picks]}
    rmse, folds = {}, {}
    for key, aj in rows.items():
        e = np.stack([sse[a, :, j, o] for o, (a, j) in enumerate(aj)], axis=1)  # (K, q)
        rmse[key] = np.sqrt(e.sum(axis=0) / n).tolist()
        folds[key] = (e * weight**2).sum(axis=1)
    score = {key: float(np.sqrt(f.sum() / (n * q))) for key, f in folds.items()}
    alphas = cv["alphas"]
    row_alpha = [None if j < 0 else float(alphas[a]) for j, a in picks]
    used = [a for a in row_alpha if a is not None]
    K = sse.shape[1]
    ratio = score["chosen"] / score["linear"] if score["linear"] > 0 else float("nan")
    if requested == "auto":
        kinds = ", ".join(f"{sum(j == i for j, _ in picks)} {name}" for i, name in enumerate(names))
        why = (f"cross-validated over {K} folds of {n_segments} loading groups: per output group (forces, torques), "
               f"the best correction where its mean held-out score beats the affine fit's by more than {N_SE:g} "
               f"standard error: {q - len(used)} affine, {kinds}; held-out error {ratio:.2f}× the affine fit's")
    else:
        pr = score["poly"] / score["linear"] if score["linear"] > 0 else float("nan")
        why = f"{requested} as requested (cross-validated polynomial/affine held-out error {pr:.2f}×)"
    return ModelChoice(name="poly" if used else "linear", requested=requested, alpha=max(used) if used else None,
                       row_alpha=row_alpha if used else [], cv_rmse=rmse, cv_score=score,
                       folds_won=int(np.sum(folds["chosen"] < folds["linear"])), n_folds=K,
                       n_segments=int(n_segments), reason=why)


def _held_out_extension(c, w, center, scale, fold, folded, probs, picks, alphas, pairs, cubes):
    """``(2, q)`` held-out sums of squares, beyond the range of their training folds, of the chosen
    corrections continued with the linear fit's slope (row 0) or the polynomial's tangent (row 1);
    None when no held-out sample lies beyond its training folds' range.

    Each fold's model is the chosen one refitted without it (its Gram down-dated); its correction is
    drawn back into the range of the other folds' channels, as the fit's is into the whole range.
    """
    from ._cv import _paths
    from ._poly import _ray_into

    m, q, K, p = c.shape[1], w.shape[1], folded.n_folds, folded.p
    u = (c - center) / scale
    e = np.zeros((2, q))
    found = False
    for k in range(K):
        te = fold == k
        if not te.any() or te.all():
            continue
        lo, hi = u[~te].min(axis=0), u[~te].max(axis=0)
        out = np.flatnonzero(te)[_ray_into(u[te], lo, hi) < 1.0]
        if out.size == 0:
            continue
        found = True
        G = folded.total(exclude=k)
        X_lin = _paths(G, p, [probs[0]], [np.inf])[0][0][: 1 + m]
        X, D = X_lin.copy(), np.zeros((q, p - 1 - m))
        for j, pr in enumerate(probs):
            for a in sorted({a for jj, a in picks if jj == j}):
                rows = np.array([jj == j and aa == a for jj, aa in picks])
                Xp = _paths(G, p, [pr], [alphas[a]])[0][0]
                X[:, rows] = Xp[: 1 + m, rows]
                D[np.ix_(rows, pr.b - 1 - m)] = Xp[1 + m :, rows].T
        edge = ((X[1:] - X_lin[1:]) / scale[:, None]).T
        x = c[out] - center
        base = u[out] @ X[1:] + X[0]
        for i, tan in enumerate((None, np.ones(q, dtype=bool))):
            corr = PolyCorrection(scale, pairs, cubes, D, lo, hi, edge, tangent=tan)
            e[i] += ((base + corr(x) - w[out]) ** 2).sum(axis=0)
    return e if found else None


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
        ``FAMILIES`` (a full quadratic of the channels; the same with cubes) along its ridge path by
        their mean held-out score over the folds, and takes the best correction only where it beats
        the affine fit by more than ``_cv.N_SE`` standard errors (the one-standard-error rule);
        ``linear`` is the plain affine least squares everywhere, ``poly`` the best correction.
        Fewer than ``MIN_FOLDS`` folds: the affine fit.
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
        picks = [(-1, 0)] * q
        if nl:
            sd = w.std(axis=0)
            weight = 1.0 / np.where(sd > 0, sd, 1.0)
            n_terms = {"quadratic": pairs.shape[0], "cubic": r}
            probs = [Problem(np.arange(1 + m), 1 + m + np.arange(n_terms[f]), np.arange(q), weight) for f in FAMILIES]
            cv = cross_validate(folded, probs, alphas)
            picks = _choose(cv, weight, model)
            choice = _choice(cv, weight, picks, model, n_groups, FAMILIES)
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

        tangent = np.zeros(q, dtype=bool)
        cube_cols = 1 + m + pairs.shape[0] + np.arange(cubes.size)
        with threadpool_limits(limits=1):
            for j, pr in enumerate(probs):  # each family's rows, refitted with its own features
                ra = np.array([cv["alphas"][a] if jj == j else np.nan for jj, a in picks])
                if np.isfinite(ra).any():
                    tangent |= tangent_rows(build, 1 + m + r, u[sub], lo, hi, pr, ra, cube_cols)
            held = _held_out_extension(c, w, center, scale, fold, folded, probs, picks, cv["alphas"], pairs, cubes)
        if held is not None:  # the caller's held-out groups beyond their folds' range decide where they exist
            e_slope, e_tan = held * weight**2
            for g in range(0, q, OUTPUT_GROUP):
                cols = slice(g, g + OUTPUT_GROUP)
                if e_slope[cols].sum() > 0:
                    tangent[cols] = e_tan[cols].sum() < TANGENT_GAIN * e_slope[cols].sum()
        correction = PolyCorrection(scale, pairs, cubes, D, lo, hi, edge, tangent=tangent)
    names = ("linear",) + tuple(FAMILIES)
    return SensorFit(choice, coef, X[0].copy(), center, correction, [names[j + 1] for j, _ in picks])

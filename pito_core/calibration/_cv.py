"""Model choice by cross-validation over loading segments, from per-fold Gram matrices.

Rows are dealt to ``K`` folds by whole loading segments (contiguous runs of samples),
round-robin so that every fold spans the session's time (never shuffled neighbours:
scikit-learn's ``GroupKFold``). One pass keeps each fold's Gram matrix ``G_k`` of
``[A | B]`` (``FoldedGram``, BLAS ``syrk``); fold ``k``'s training Gram is the down-date
``Σ G − G_k``, and the held-out sum of squares of a solution ``X`` is the quadratic form
``diag(G_yy − 2 Xᵀ G_xy + Xᵀ G_xx X)`` of ``G_k`` alone: no second pass, no re-built
features.

A problem regresses some columns ``y`` of ``B`` on unpenalised columns ``a`` of ``A``
(offsets, channels) and penalised columns ``b`` (nonlinear features), with a ridge
``α · mean(σ²)`` on ``b`` (``σ²`` the eigenvalues of ``b``'s Gram once ``a`` is projected
out). ``α = ∞`` is the affine fit. Every α comes from one eigendecomposition per fold and
problem. The Gram squares the design's condition number: the chosen model's linear rows
are the papers' fit by QR (``_lstsq.py``), the Gram only scores and fits the correction
(its columns are scaled to unit spread, the ridge bounds its part).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._poly import ray_into

__all__ = ["N_FOLDS", "ALPHAS", "FoldedGram", "Problem", "segment_ids", "fold_of_segments", "cross_validate",
           "solve_problem", "fold_bounds"]

#: Folds of the cross-validation.
N_FOLDS = 5
#: Ridge strengths tried for the nonlinear features (relative to their mean squared singular value).
ALPHAS = 10.0 ** np.arange(-7.0, 0.5, 1.0)
#: Segments are cut to at most this fraction of a session, so every fold holds many of them.
MAX_SEGMENT_FRACTION = 1 / 20
#: ... and each load pattern's rows in a session (faces loaded together; not the rest) into at least
#: this many, so no fold holds all of a load's rows (a session of many short patterns, as squeezes
#: after single loads, would otherwise leave the fits that score a load none of its rows).
MIN_PIECES = 3
#: Eigenvalues of the scaled Gram of the unpenalised columns below this fraction of the
#: largest are dropped (singular values under 10⁻⁶·σ₁: what a Gram in double can resolve).
GRAM_RTOL = 1e-12
#: At most this many strata (patterns of faces carrying nothing) per ``FoldedGram``: single-face loads
#: make one per loaded face and one at rest; rows of further patterns count as carrying.
MAX_STRATA = 16


class SegmentCounter:
    """Loading segments of a stream of samples, block by block.

    A segment starts where the loaded faces change; segments longer than ``max_len``
    samples are cut into contiguous pieces of ``max_len``, or of the pattern's cap in the
    session (``caps``, :func:`pattern_caps`). Numbering continues across blocks (and across
    sessions, when one counter reads them all).
    """

    def __init__(self, max_len: int):
        self.max_len = max(1, int(max_len))
        self.count = 0  # segments started so far
        self._last = None
        self._run = 0  # samples of the current segment so far

    def ids(self, loaded: np.ndarray, new_session: bool = False, caps: np.ndarray | None = None) -> np.ndarray:
        """``(n,)`` segment of each row of ``loaded (n, k)``; ``caps (2**k,)`` the piece length of each
        load pattern (bit ``j``: column ``j`` loaded) in this session, else ``max_len`` for all."""
        loaded = np.asarray(loaded).reshape(len(loaded), -1)
        n = loaded.shape[0]
        if n == 0:
            return np.zeros(0, dtype=np.int64)
        fresh = self._last is None or new_session
        change = np.empty(n, dtype=bool)
        change[0] = fresh or bool((loaded[0] != self._last).any())
        change[1:] = (loaded[1:] != loaded[:-1]).any(axis=1)
        idx = np.arange(n)
        last_change = np.maximum.accumulate(np.where(change, idx, -1))
        pos = np.where(last_change >= 0, idx - last_change, self._run + idx)  # samples since the pattern began
        cap = self.max_len if caps is None else np.asarray(caps)[pattern_codes(loaded)]
        start = pos % cap == 0
        out = self.count - 1 + np.cumsum(start)
        self.count += int(start.sum())
        self._run = int(pos[-1]) + 1
        self._last = loaded[-1].copy()
        return out


def pattern_codes(loaded: np.ndarray) -> np.ndarray:
    """``(n,)`` the load pattern of each row of ``loaded (n, k)``: bit ``j`` set where column ``j`` is loaded."""
    loaded = np.asarray(loaded).reshape(len(loaded), -1)
    return (loaded.astype(bool) @ (1 << np.arange(loaded.shape[1]))).astype(np.int64)


def pattern_caps(loaded, max_len: int, block: int = 1 << 20) -> np.ndarray:
    """``(2**k,)`` piece length per load pattern of a session's ``loaded (N, k)`` (an array or a lazy
    dataset, read in blocks): ``max_len``, or less so each pattern's rows (but the rest's) make at least
    ``MIN_PIECES`` pieces."""
    k = loaded.shape[1]
    n = np.zeros(1 << k, dtype=np.int64)
    for s in range(0, loaded.shape[0], block):
        n += np.bincount(pattern_codes(np.asarray(loaded[s : s + block])), minlength=1 << k)
    caps = np.clip(-(-n // MIN_PIECES), 1, max(1, int(max_len)))
    caps[0] = max(1, int(max_len))
    return caps


def segment_ids(loaded: np.ndarray, max_len: int | None = None) -> np.ndarray:
    """``(N,)`` loading segment of each sample (see :class:`SegmentCounter`).

    Default ``max_len``: ``MAX_SEGMENT_FRACTION`` of the samples; each load pattern in at least
    ``MIN_PIECES`` pieces (:func:`pattern_caps`).
    """
    n = len(loaded)
    if max_len is None:
        max_len = int(np.ceil(n * MAX_SEGMENT_FRACTION))
    loaded = np.asarray(loaded).reshape(n, -1)
    return SegmentCounter(max_len).ids(loaded, caps=pattern_caps(loaded, max_len) if loaded.shape[1] <= 16 else None)


def fold_of_segments(segments: np.ndarray, n_folds: int = N_FOLDS) -> np.ndarray:
    """``(N,)`` fold of each sample: segments dealt round-robin in order of first appearance."""
    segments = np.asarray(segments)
    _, first, inverse = np.unique(segments, return_index=True, return_inverse=True)
    rank = np.argsort(np.argsort(first))  # order of first appearance of each segment
    return (rank[inverse] % n_folds).astype(np.int64)


def fold_bounds(fold: np.ndarray, n_folds: int) -> tuple[np.ndarray, np.ndarray]:
    """``(order (n,), bounds (K + 1,))``: rows sorted by fold (stable); fold ``k`` is ``order[bounds[k]:bounds[k+1]]``."""
    order = np.argsort(fold, kind="stable")
    return order, np.searchsorted(fold[order], np.arange(n_folds + 1))


class FoldedGram:
    """One Gram matrix of ``[A | B]`` (``p + q`` columns) per fold, split by which outputs carry nothing.

    The targets ``B`` come in output groups of six (a face's wrench; one group if ``q`` is not a
    multiple of 6). A row where a group's targets are all zero is one where that face carries nothing
    (``block_targets``): its free rows. Each fold keeps one Gram per pattern of free groups (a
    *stratum*: at rest, face 1 loaded, …), so the held-out error of a face splits into its carrying
    and its free rows at no extra product (``cross_validate``).

    Parameters
    ----------
    p, q : int
        Columns of ``A`` (regressors) and ``B`` (targets).
    n_folds : int

    Attributes
    ----------
    gram : ndarray, shape (K, S, p + q, p + q)
        Per fold and stratum.
    rows : ndarray of int, shape (K, S)
    free : ndarray of bool, shape (S, n_groups)
        The output groups each stratum's rows leave at zero.
    """

    def __init__(self, p: int, q: int, n_folds: int = N_FOLDS):
        self.p, self.q, self.n_folds = p, q, n_folds
        self.n_groups = q // 6 if q % 6 == 0 and q else 1
        self.gram = np.zeros((n_folds, 0, p + q, p + q))
        self.rows = np.zeros((n_folds, 0), dtype=np.int64)
        self.free = np.zeros((0, self.n_groups), dtype=bool)

    def _stratum(self, pattern: np.ndarray) -> int:
        """Index of the stratum of ``pattern (n_groups,)`` (a new one if unseen; past ``MAX_STRATA`` the
        rows count as carrying everywhere)."""
        hit = np.flatnonzero((self.free == pattern).all(axis=1))
        if hit.size:
            return int(hit[0])
        if self.free.shape[0] >= MAX_STRATA:  # the last stratum then counts as carrying everywhere
            hit = np.flatnonzero(~self.free.any(axis=1))
            if not hit.size:
                self.free[-1] = False
            return int(hit[0]) if hit.size else self.free.shape[0] - 1
        d = self.p + self.q
        self.gram = np.concatenate([self.gram, np.zeros((self.n_folds, 1, d, d))], axis=1)
        self.rows = np.concatenate([self.rows, np.zeros((self.n_folds, 1), dtype=np.int64)], axis=1)
        self.free = np.vstack([self.free, pattern])
        return self.free.shape[0] - 1

    def add_sorted(self, ZT: np.ndarray, bounds: np.ndarray) -> None:
        """Fold in ``ZT (p + q, n)``: the rows ``[A | B]`` as columns, sorted by fold (``fold_bounds``)."""
        for k in range(self.n_folds):
            a, b = int(bounds[k]), int(bounds[k + 1])
            if b <= a:
                continue
            Z = ZT[:, a:b]
            zero = ~ZT[self.p :, a:b].reshape(self.n_groups, -1, b - a).any(axis=1)  # (n_groups, n): free
            # each column's pattern as one integer, the first group the highest bit: the order of
            # np.unique(zero, axis=1), at a tenth of its time
            bits = 1 << np.arange(self.n_groups - 1, -1, -1, dtype=np.int64)
            codes, code = np.unique(bits @ zero, return_inverse=True)
            kinds = (codes[None, :] & bits[:, None]) > 0
            for c in range(kinds.shape[1]):
                s = self._stratum(kinds[:, c])
                Zs = Z if kinds.shape[1] == 1 else Z[:, code.reshape(-1) == c]
                self.gram[k, s] += Zs @ Zs.T  # BLAS syrk: numpy spots the transposed operand
                self.rows[k, s] += Zs.shape[1]

    def add(self, A: np.ndarray, B: np.ndarray, fold: np.ndarray) -> None:
        """Fold in rows ``A (n, p)``, ``B (n, q)`` of folds ``fold (n,)``."""
        order, bounds = fold_bounds(np.asarray(fold), self.n_folds)
        ZT = np.empty((self.p + self.q, order.size))
        ZT[: self.p] = A[order].T
        ZT[self.p :] = B[order].T
        self.add_sorted(ZT, bounds)

    @property
    def n_rows(self) -> int:
        return int(self.rows.sum())

    def total(self, exclude: int | None = None, free_of: int | None = None) -> np.ndarray:
        """``(p + q, p + q)`` Gram of the folds other than ``exclude`` (all if None); of the rows where
        output group ``free_of`` carries nothing only, if given."""
        parts = self.gram if free_of is None else self.gram[:, self.free[:, free_of]]
        G = parts.sum(axis=(0, 1))
        if exclude is not None:
            G -= parts[exclude].sum(axis=0)
        return 0.5 * (G + G.T)

    def train_share(self) -> float:
        """The share of its load's rows a held-out row's fit was trained on, the mean over the rows
        where some face carries: ``1 − Σ_k π_k²`` per stratum (``π_k`` the share of its rows in fold
        ``k``; whole loading segments are held out, so a face's few long ones leave its fits far less
        than ``(K − 1) / K``). The rows at rest (every group free) are left out: their error is the
        gauges' noise, not the fit's."""
        N = np.where(self.free.all(axis=1), 0, self.rows.sum(axis=0))
        if not N.sum():
            return 1.0
        pi = self.rows / np.maximum(N, 1)
        return float(np.sum(N * (1.0 - (pi**2).sum(axis=0))) / N.sum())

    def fold(self, k: int, free_of: int | None = None) -> np.ndarray:
        """Fold ``k``'s Gram (of the rows where output group ``free_of`` carries nothing, if given)."""
        return (self.gram[k] if free_of is None else self.gram[k, self.free[:, free_of]]).sum(axis=0)

    def free_rows(self, group: int) -> np.ndarray:
        """``(K,)`` rows per fold where output group ``group`` carries nothing."""
        return self.rows[:, self.free[:, group]].sum(axis=1)


@dataclass(frozen=True)
class Problem:
    """Columns ``y`` of B regressed on unpenalised ``a`` and ridge-penalised ``b`` columns of A.

    ``weight (len(y),)`` puts the outputs on one footing in the score (1 / full scale);
    ``rank_a`` (optional) keeps only that many directions of the unpenalised columns (the
    load rank of the affine fit: directions the loads leave unexcited carry noise only).
    """

    a: np.ndarray
    b: np.ndarray
    y: np.ndarray
    weight: np.ndarray
    rank_a: int | None = None


def _eliminate(G: np.ndarray, a: np.ndarray, rank_a=None):
    """``(Gaa⁺ (na, na), S)``: the pseudo-inverse of the unpenalised block and the Schur
    complement ``S = G − G[:, a] Gaa⁺ G[a, :]`` (``a`` projected out of every column).

    ``Gaa⁺`` keeps the scaled directions above ``GRAM_RTOL`` (and at most ``rank_a``).
    """
    Gaa = G[np.ix_(a, a)]
    dg = np.diag(Gaa)
    d = np.where(dg > 0, 1.0 / np.sqrt(np.where(dg > 0, dg, 1.0)), 0.0)
    w, V = np.linalg.eigh(Gaa * np.outer(d, d))
    keep = w > GRAM_RTOL * max(w[-1], 0.0) if w.size else w > 0
    if rank_a is not None and keep.sum() > rank_a:
        keep[: keep.size - int(rank_a)] = False
    Vk = V[:, keep] * d[:, None]
    P = (Vk / w[keep]) @ Vk.T
    Ga = G[a]
    return P, G - Ga.T @ (P @ Ga)


def ridge_paths(G: np.ndarray, p: int, problems, alphas) -> list[list[np.ndarray]]:
    """Solutions ``(na + nb, ny)`` of each problem for each α (``inf``: b fixed at 0) from a Gram ``G``.

    Problems with the same unpenalised columns share one elimination of them.
    """
    out, cache, eig = [], {}, {}
    for pr in problems:
        key = (pr.a.tobytes(), pr.rank_a)
        if key not in cache:
            cache[key] = _eliminate(G, pr.a, pr.rank_a)
        P, S = cache[key]
        y = p + pr.y
        nb = pr.b.size
        if nb:
            bkey = (key, pr.b.tobytes())  # a joint fit's faces often share their features: one eigh
            if bkey not in eig:
                s2, U = np.linalg.eigh(S[np.ix_(pr.b, pr.b)])
                eig[bkey] = (np.clip(s2, 0.0, None), U)
            s2, U = eig[bkey]
            UtY = U.T @ S[np.ix_(pr.b, y)]
            lam0 = float(np.mean(s2)) if s2[-1] > 0 else 1.0
        Gay, Gab = G[np.ix_(pr.a, y)], G[np.ix_(pr.a, pr.b)]
        sols = []
        for alpha in alphas:
            if np.isinf(alpha) or nb == 0:
                Xb = np.zeros((nb, y.size))
            else:
                Xb = U @ (UtY / (s2 + alpha * lam0)[:, None])
            sols.append(np.vstack([P @ (Gay - Gab @ Xb), Xb]))
        out.append(sols)
    return out


def held_out_sse(G: np.ndarray, p: int, pr: Problem, X) -> np.ndarray:
    """Sum of squared residuals of solution ``X (nx, ny)`` (or a stack ``(A, nx, ny)``: ``(A, ny)``)
    over the rows whose Gram is ``G``."""
    x = np.r_[pr.a, pr.b]
    y = p + pr.y
    Gxy = G[np.ix_(x, y)]
    X = np.asarray(X)
    sse = np.diag(G)[y] - 2.0 * np.sum(X * Gxy, axis=-2) + np.sum(X * (G[np.ix_(x, x)] @ X), axis=-2)
    return np.clip(sse, 0.0, None)


def cross_validate(folded: FoldedGram, problems, alphas=ALPHAS) -> dict:
    """Held-out sums of squares of every problem, fold and α (``inf`` first: the affine fit).

    Returns
    -------
    dict
        ``alphas (A,)`` with ``inf`` first; ``sse (A, K, n_problems, ny)`` held-out sums of
        squares per output (output units²); ``n_rows (K,)``. Where some output group carries
        nothing in some rows (:class:`FoldedGram`) also ``free_sse`` (the same over those rows),
        ``fit_sse``, ``fit_free_sse (A, n_problems, ny)`` (in sample: the solution of every fold,
        over all its rows and over the free ones) and ``free_rows (K, n_problems)``;
        ``train_share``: :meth:`FoldedGram.train_share`.
    """
    alphas = np.r_[np.inf, np.asarray(alphas, dtype=float)]
    K, p = folded.n_folds, folded.p
    ny = max(pr.y.size for pr in problems)
    sse = np.full((alphas.size, K, len(problems), ny), np.nan)
    split = bool(folded.free.any())
    group = [int(pr.y[0]) // 6 if folded.n_groups > 1 else 0 for pr in problems]
    if split:
        free_sse = np.full_like(sse, np.nan)
        fit_sse, fit_free = np.full((2, alphas.size, len(problems), ny), np.nan)
        G, total = folded.total(), ridge_paths(folded.total(), p, problems, alphas)
        for j, (pr, sols) in enumerate(zip(problems, total)):
            fit_sse[:, j, : pr.y.size] = held_out_sse(G, p, pr, np.stack(sols))
            fit_free[:, j, : pr.y.size] = held_out_sse(folded.total(free_of=group[j]), p, pr, np.stack(sols))
    n_rows = folded.rows.sum(axis=1)
    for k in range(K):
        if n_rows[k] == 0:
            continue
        Gk = folded.fold(k)
        for j, (pr, sols) in enumerate(zip(problems, ridge_paths(folded.total(exclude=k), p, problems, alphas))):
            sse[:, k, j, : pr.y.size] = held_out_sse(Gk, p, pr, np.stack(sols))
            if split:
                free_sse[:, k, j, : pr.y.size] = held_out_sse(folded.fold(k, group[j]), p, pr, np.stack(sols))
    out = {"alphas": alphas, "sse": sse, "n_rows": n_rows, "train_share": folded.train_share()}
    if split:
        out.update(free_sse=free_sse, fit_sse=fit_sse, fit_free_sse=fit_free,
                   free_rows=np.stack([folded.free_rows(g) for g in group], axis=1))
    return out


def solve_problem(folded: FoldedGram, prob: Problem, alphas) -> list[np.ndarray]:
    """``(na + nb, ny)`` solutions of ``prob`` on every fold for each of ``alphas`` (``inf``: affine)."""
    return ridge_paths(folded.total(), folded.p, [prob], np.atleast_1d(np.asarray(alphas, dtype=float)))[0]


#: The one-standard-error rule (Hastie et al.): the affine fit unless the correction's mean held-out
#: score beats it by more than this many standard errors (over folds) of the correction's
#: (``fit_sensor``: folds of the caller's groups).
N_SE = 1.0
#: The same for the cube's ``calibrate``, whose folds are loading segments of the same sessions:
#: they do not show what a later session changes (on the simulated cube, its frame's hysteresis);
#: the measurements behind the 3 are in docs/calibration/coverage.md.
N_SE_SESSION = 3.0
#: Held-out mean squares (outputs scaled by full scale) closer than this are a tie: an RMSE of
#: 10⁻⁶ of full scale, below what the Gram's rounding resolves on noise-free data.
SCORE_ATOL = 1e-12
MODELS = ("auto", "linear", "poly")


@dataclass
class ModelChoice:
    """Which model a fit uses, and the cross-validated figures that chose it.

    The choice is made per output group: each face's forces ``[fx, fy, fz]`` and torques
    ``[tx, ty, tz]`` (for ``fit_sensor``, outputs in threes) take the correction, or the
    papers' affine rows, on their own.

    Attributes
    ----------
    name : {"linear", "poly"}
        ``linear``: the papers' affine least squares (``C = W S⁺``) on every row. ``poly``:
        a ridge-regularised polynomial correction (``_poly.py``) on the rows ``row_alpha``
        names, the papers' rows elsewhere.
    requested : {"auto", "linear", "poly"}
        What the caller asked for.
    alpha : float or None
        Ridge strength of the correction (relative), the largest over the rows that use
        it (None for ``linear``).
    row_alpha : list of (float or None)
        Per output row (the fit's order), the ridge of its correction, or None for an
        affine row; empty for ``linear`` and files written before the per-row choice.
    cv_rmse : dict
        ``{"linear": [...], "poly": [...], "chosen": [...]}``: cross-validated RMSE of every
        output (N, N·m) for the affine fit, the correction (each group at its ridge) and the
        chosen mix; empty when no cross-validation ran.
    cv_score : dict
        The same keys: held-out RMSE of all outputs, each scaled by its full scale (dimensionless).
    folds_won : int
        Folds on which the chosen model had the lower held-out error.
    n_folds, n_segments : int
        Folds and loading segments of the cross-validation.
    reason : str
        One sentence for the operator.
    cv_split : list or None
        ``(6F, 2, 2)``: per output row, the chosen mix's RMSE held out and in sample (last axis) over
        the rows where the row's face carries and where it carries nothing (middle axis; 0 where
        there are none), for the error model (``_error.held_out_ratio``); None where no row of the
        fit carried nothing, no cross-validation ran, or a file predates it.
    cv_train_share : float or None
        The share of the rows of a held-out row's loads its fold's fit was trained on, the mean over
        the rows (:meth:`FoldedGram.train_share`); None as ``cv_split``.
    """

    name: str = "linear"
    requested: str = "linear"
    alpha: float | None = None
    cv_rmse: dict | None = None
    cv_score: dict | None = None
    folds_won: int = 0
    n_folds: int = 0
    n_segments: int = 0
    reason: str = "the papers' affine least squares, as requested"
    row_alpha: list | None = None
    cv_split: list | None = None
    cv_train_share: float | None = None

    def to_dict(self) -> dict:
        """JSON-serialisable fields (for files and reports)."""
        return {"name": self.name, "requested": self.requested, "alpha": self.alpha,
                "cv_rmse": self.cv_rmse or {}, "cv_score": self.cv_score or {}, "folds_won": int(self.folds_won),
                "n_folds": int(self.n_folds), "n_segments": int(self.n_segments), "reason": self.reason,
                "row_alpha": list(self.row_alpha or []), "cv_split": self.cv_split,
                "cv_train_share": self.cv_train_share}

    def cv_rms(self) -> dict:
        """``{candidate: (forces N, torques N·m)}``: RMS over outputs of each candidate's cross-validated RMSE."""
        out = {}
        for key in ("linear", "poly", "chosen"):
            r = np.asarray((self.cv_rmse or {}).get(key) or [], dtype=float)
            if r.size:
                axis = np.arange(r.size) % 6
                out[key] = (float(np.sqrt(np.mean(r[axis < 3] ** 2))), float(np.sqrt(np.mean(r[axis >= 3] ** 2))))
        return out

    def corrected(self, output_faces) -> list:
        """``[(face, "forces" | "torques"), ...]``: the output groups that use the correction.

        ``row_alpha`` runs six rows per face in the order of ``output_faces``.
        """
        rows = list(self.row_alpha or [])
        return [(int(f), part) for k, f in enumerate(output_faces) for part, a in (("forces", 0), ("torques", 3))
                if 6 * k + a < len(rows) and rows[6 * k + a] is not None]

    @classmethod
    def from_dict(cls, d: dict) -> "ModelChoice":
        d = dict(d)
        if d.get("name") not in ("linear", "poly"):
            raise ValueError(f"model.name: expected 'linear' or 'poly', got {d.get('name')!r}")
        return cls(**{k: d[k] for k in cls.__dataclass_fields__ if k in d})


def _group_choice(e: np.ndarray, n_rows: np.ndarray, force: bool, n_se: float = N_SE) -> int:
    """Index of the chosen candidate (0: affine; ``i ≥ 1``: the correction at ``alphas[i]``) for one
    output group from its held-out SSE ``e (A, K)``.

    Each candidate's score on fold ``k`` is its held-out mean square ``e[a, k] / n_rows[k]``. The
    correction's ridge is the one of the best mean over folds; then the one-standard-error rule
    between the two candidates: the affine fit unless the correction's mean beats it by more than
    ``n_se`` standard errors (over folds) of the correction's (or by ``SCORE_ATOL``). ``force``: the
    correction.
    """
    ok = n_rows > 0
    score = e[:, ok] / n_rows[ok]
    mean = score.mean(axis=1)
    best = 1 + int(np.argmin(mean[1:]))
    if force:
        return best
    K = score.shape[1]
    se = float(np.std(score[best], ddof=1) / np.sqrt(K)) if K > 1 else np.inf
    return best if mean[0] > mean[best] + max(n_se * se, SCORE_ATOL) else 0


def choose_model(results, requested: str, n_segments: int, group: int = 3, n_se: float = N_SE) -> ModelChoice:
    """Choose, per output group, the affine rows or the correction.

    Parameters
    ----------
    results : list of (dict, list of ndarray)
        ``(cross_validate output, weights per problem)``; the outputs, in order of the parts,
        problems and their ``y``, are the fit's rows. Groups: outputs ``0–2``, ``3–5``, … of
        each problem (a face's forces and torques).
    requested : {"auto", "linear", "poly"}
        ``auto`` applies :func:`_group_choice`; ``poly`` uses the correction on every group;
        ``linear`` none (the figures are still reported).
    n_segments : int
    group : int
        Outputs chosen together: 3 (forces, torques) or 6 (a face's whole wrench).
    n_se : float
        Standard errors the correction must win by (``N_SE``, ``N_SE_SESSION``).
    """
    alphas = results[0][0]["alphas"]
    K = results[0][0]["sse"].shape[1]
    row_alpha, rmse, split = [], {"linear": [], "poly": [], "chosen": []}, []
    folds = np.zeros((3, K))  # weighted held-out SSE per fold: linear, poly, chosen
    n_out = 0
    for cv, weights in results:
        sse = np.nan_to_num(cv["sse"])
        n = max(int(cv["n_rows"].sum()), 1)
        for j, w in enumerate(weights):
            for g in range(0, w.size, group):
                cols = np.arange(g, min(g + group, w.size))
                e = np.einsum("akc,c->ak", sse[:, :, j, cols], w[cols] ** 2)
                chosen = _group_choice(e, cv["n_rows"], requested == "poly", n_se)
                pick = chosen if chosen else 1 + int(np.argmin(e[1:].sum(axis=1)))  # the correction at its best ridge
                use = chosen > 0 and requested != "linear"
                folds += np.stack([e[0], e[pick], e[pick] if use else e[0]])
                for key, a in (("linear", 0), ("poly", pick), ("chosen", pick if use else 0)):
                    rmse[key] += np.sqrt(sse[a][:, j][:, cols].sum(axis=0) / n).tolist()
                row_alpha += [float(alphas[pick]) if use else None] * cols.size
                if split is not None and "free_sse" in cv:
                    split += _split_rmse(cv, pick if use else 0, j, cols)
                else:
                    split = None
            n_out += w.size
    rows = sum(int(cv["n_rows"].sum()) * sum(w.size for w in ws) for cv, ws in results)
    score = {key: float(np.sqrt(folds[i].sum() / max(rows, 1))) for i, key in enumerate(("linear", "poly", "chosen"))}
    used = [a for a in row_alpha if a is not None]
    won = int(np.sum(folds[2] < folds[0]))
    ratio = score["chosen"] / score["linear"] if score["linear"] > 0 else float("nan")
    n_groups, n_used = len(row_alpha) // group, len(used) // group
    name = "poly" if used else "linear"
    if requested == "auto":
        why = (f"cross-validated over {K} folds of {n_segments} loading segments: the polynomial correction is used for "
               f"{n_used} of {n_groups} output groups (a face's forces or torques): where its best mean held-out "
               f"score beats the affine fit's by more than {n_se:g} standard error{'' if n_se == 1 else 's'}; held-out "
               f"error {ratio:.2f}× the affine fit's")
        if not used:
            why += "; kept the papers' affine fit"
    else:
        pr = score["poly"] / score["linear"] if score["linear"] > 0 else float("nan")
        why = f"{requested} as requested (cross-validated polynomial/affine held-out error {pr:.2f}×)"
    return ModelChoice(name=name, requested=requested, alpha=max(used) if used else None,
                       row_alpha=row_alpha if used else [], cv_rmse=rmse, cv_score=score, folds_won=won, n_folds=K,
                       n_segments=int(n_segments), reason=why, cv_split=split,
                       cv_train_share=None if split is None else float(
                           sum(cv["train_share"] * cv["n_rows"].sum() for cv, _ in results)
                           / max(sum(cv["n_rows"].sum() for cv, _ in results), 1)))


def _split_rmse(cv: dict, a: int, j: int, cols: np.ndarray) -> list:
    """Per output ``cols`` of problem ``j`` at ridge index ``a``: ``[[held out, in sample] where its face
    carries, [held out, in sample] where it carries nothing]`` RMSE (0 where no such rows)."""
    n_free = float(cv["free_rows"][:, j].sum())
    n_carry = float(cv["n_rows"].sum()) - n_free
    held = np.nan_to_num(cv["sse"][a][:, j][:, cols]).sum(axis=0)
    held_free = np.nan_to_num(cv["free_sse"][a][:, j][:, cols]).sum(axis=0)
    fit, fit_free = np.nan_to_num(cv["fit_sse"][a, j, cols]), np.nan_to_num(cv["fit_free_sse"][a, j, cols])
    ms = np.stack([np.stack([held - held_free, fit - fit_free]) / max(n_carry, 1.0),
                   np.stack([held_free, fit_free]) / max(n_free, 1.0)])  # (2, 2, c)
    return np.sqrt(np.clip(ms, 0.0, None)).transpose(2, 0, 1).tolist()


#: The extension beyond the box is chosen on the samples beyond the box shrunk to hold this fraction of
#: the loads (by their farthest channel relative to its edge; the rest excepted): the correction is
#: refitted on those inside and scored on those outside.
EXTRAPOLATION_QUANTILE = 0.7
#: The tangent must bring the held-out extrapolation error below this fraction of the linear slope's
#: (a marginal win is not enough: docs/calibration/coverage.md).
TANGENT_GAIN = 0.95
#: Fewer samples than this outside the shrunk box: no choice, the linear fit's slope.
MIN_BEYOND_ROWS = 20


def shrunk_box(u, lower, upper, loads=None) -> tuple[float, np.ndarray]:
    """``(shrink, t (n,))``: the factor that shrinks the box ``lower, upper (m,)`` to hold
    ``EXTRAPOLATION_QUANTILE`` of the loaded rows of ``u (n, m)`` (``loads (n,)`` bool, default every row;
    by each row's farthest channel relative to its edge), and each row's ray factor into the shrunk box."""
    with np.errstate(divide="ignore", invalid="ignore"):
        reach = np.nan_to_num(np.where(u > 0, u / upper, u / lower), nan=0.0, posinf=0.0).max(axis=1)
    on = reach if loads is None else reach[np.asarray(loads, dtype=bool)]
    shrink = float(np.quantile(on, EXTRAPOLATION_QUANTILE)) if on.size else 1.0
    return shrink, ray_into(u, shrink * lower, shrink * upper)


def tested_reach(u, lower, upper, loads=None) -> float:
    """The factor beyond the box that the extension's held-out rows (``extension_errors``) reach: the largest
    ``1 / t`` of those outside the shrunk box (:func:`shrunk_box`), drawn back to it (1.0: too few of them,
    untested)."""
    if not len(u):
        return 1.0
    _, t = shrunk_box(u, lower, upper, loads)
    outer = t < 1.0
    if outer.sum() < MIN_BEYOND_ROWS or (~outer).sum() < MIN_BEYOND_ROWS:
        return 1.0
    return float(1.0 / max(t[outer].min(), 1e-12))


def extension_errors(build, p: int, u, lower, upper, prob: Problem, row_alpha, cube_cols, face_cols=None,
                     cache=None, loads=None):
    """Held-out errors of the ways a correction continues beyond the box it is trained on.

    Beyond the box the correction continues with the linear fit's slope, or with the polynomial's
    tangent at the edge (``_poly.PolyCorrection``), or either faded to the linear fit (the linear fit
    plus ``t`` of what it adds, ``t`` how far the row lies out along its ray). Each is scored as it is
    used: the problem ``prob`` refitted (its ridges ``row_alpha (ny,)``, NaN for rows without a
    correction) on the rows inside the box shrunk to hold ``EXTRAPOLATION_QUANTILE`` of them, the rows
    outside predicted from their point drawn back to the shrunk box (:func:`shrunk_box` on ``loads``, the
    rows that carry load). ``build(idx, v)`` gives the design
    ``ZT (p + q, len(idx))`` (``p`` regressor columns) of rows ``idx`` with the scaled channels
    ``v (len(idx), m)`` in place of theirs; ``u (n, m)`` the rows' scaled channels; ``lower, upper (m,)``
    the box (of ``u``); ``cube_cols`` the design columns that are cubes (the rest of ``prob.b`` squares
    and products). ``face_cols``: the columns of ``u`` of the outputs' own face (a joint fit's face is
    driven by its own gauges): the rows outside are then judged where its own gauges are beyond the
    shrunk box too. ``cache``: a dict shared by calls with the same ``build``, ``u`` and box (a joint
    fit's output faces): the rows and their designs are worked out once.

    Returns
    -------
    dict or None
        ``slope``, ``tangent``, ``fade_slope``, ``fade_tangent``, and ``poly`` (the polynomial itself,
        not drawn back): ``(ny,)`` weighted squared errors over the judged rows outside; ``residuals``:
        each one's errors ``(n_out, ny)`` (output units) on every row outside, and ``beyond (n_out,)``
        their ``‖u − t u‖²`` (for the error model's ``beyond_cov``); None where too few rows lie inside
        or outside.
    """
    ra = np.asarray(row_alpha, dtype=float)
    use = np.isfinite(ra)
    if not use.any():
        return None
    shared = None if cache is None else cache.get("rows")
    if shared is None:
        shrink, t = shrunk_box(u, lower, upper, loads)
        inner, outer = np.flatnonzero(t >= 1.0), np.flatnonzero(t < 1.0)
        G = Zc = Zr = None
        if outer.size >= MIN_BEYOND_ROWS and inner.size >= MIN_BEYOND_ROWS:
            Z = build(inner, u[inner])
            G = Z @ Z.T
            G = 0.5 * (G + G.T)
            # the rows outside: drawn back to the shrunk box; as they are
            Zc, Zr = build(outer, u[outer] * t[outer][:, None]), build(outer, u[outer])
        shared = (shrink, t, outer, G, Zc, Zr)
        if cache is not None:
            cache["rows"] = shared
    shrink, t, outer, G, Zc, Zr = shared
    if G is None:
        return None
    judged = np.ones(outer.size, dtype=bool)
    if face_cols is not None:
        fc = np.asarray(face_cols)
        judged = ray_into(u[outer][:, fc], shrink * lower[fc], shrink * upper[fc]) < 1.0
        if judged.sum() < MIN_BEYOND_ROWS:
            return None
    levels = np.unique(ra[use])
    sols = ridge_paths(G, p, [prob], np.r_[np.inf, levels])[0]
    X = np.zeros_like(sols[0])
    for a, Xa in zip(levels, sols[1:]):
        X[:, ra == a] = Xa[:, ra == a]
    tc = t[outer]
    na = prob.a.size
    y = Zc[p + prob.y].T
    linear = Zr[prob.a].T @ sols[0][:na]  # the linear fit (refitted on the rows inside), at the rows themselves
    edge = Zc[prob.b].T @ X[na:]  # the correction at the edge
    slope = Zc[prob.a].T @ X[:na] + edge + (Zr[prob.a] - Zc[prob.a]).T @ sols[0][:na]  # then the linear fit's slope
    r = (1.0 / tc - 1.0)[:, None]
    dphi = Zc[prob.b].T * np.where(np.isin(prob.b, cube_cols)[None, :], 3.0 * r, 2.0 * r)
    tangent = Zr[prob.a].T @ X[:na] + edge + dphi @ X[na:]  # or the corrected model's tangent
    w2 = np.asarray(prob.weight, dtype=float) ** 2

    fade = tc[:, None]
    poly = Zr[prob.a].T @ X[:na] + Zr[prob.b].T @ X[na:]  # or the polynomial itself, at the rows as they are
    preds = {"slope": slope, "tangent": tangent, "fade_slope": linear + fade * (slope - linear),
             "fade_tangent": linear + fade * (tangent - linear), "poly": poly}
    res = {k: v - y for k, v in preds.items()}  # every row outside (the error model's), the judged scored
    out = {k: (r[judged] ** 2).sum(axis=0) * w2 for k, r in res.items()}
    out["residuals"] = res
    out["beyond"] = (u[outer] ** 2).sum(axis=1) * (1.0 - tc) ** 2
    return out


def choose_extension(errors, row_alpha, group: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """``(tangent (ny,), fade (ny,))`` bool from :func:`extension_errors`' ``errors`` (None: neither), per output
    group of ``group`` rows, all corrected (``row_alpha`` finite). A group takes the tangent only where its
    held-out error is below ``TANGENT_GAIN`` of the slope's; then it fades where the chosen extension faded
    to the linear fit does better (no extension of the correction beat the linear fit beyond the loads
    it was fitted on)."""
    ra = np.asarray(row_alpha, dtype=float)
    tangent, fade = np.zeros(ra.size, dtype=bool), np.zeros(ra.size, dtype=bool)
    if errors is None:
        return tangent, fade
    use = np.isfinite(ra)
    for g in range(0, ra.size, group):
        cols = np.arange(g, min(g + group, ra.size))
        if not use[cols].all():
            continue
        tangent[cols] = errors["tangent"][cols].sum() < TANGENT_GAIN * errors["slope"][cols].sum()
        kind = "tangent" if tangent[g] else "slope"
        fade[cols] = errors["fade_" + kind][cols].sum() < errors[kind][cols].sum()
    return tangent, fade


def extension_kind(tangent: bool, fade: bool, trusted: bool = False) -> str:
    """The key of :func:`extension_errors` for a row's extension (``poly`` where the polynomial is trusted)."""
    return "poly" if trusted else ("fade_" if fade else "") + ("tangent" if tangent else "slope")


def chosen_error(errors, row_alpha, tangent, fade) -> tuple[float, float]:
    """``(chosen, poly)``: the held-out extrapolation error (``extension_errors``) summed over the corrected
    rows (``row_alpha`` finite) of the extensions :func:`choose_extension` chose (``tangent``, ``fade``), and
    of the polynomial itself there; ``(0, 0)`` without errors."""
    if errors is None:
        return 0.0, 0.0
    use = np.isfinite(np.asarray(row_alpha, dtype=float))
    chosen = sum(float(errors[extension_kind(tg, fd)][i])
                 for i, (tg, fd) in enumerate(zip(tangent, fade)) if use[i])
    return chosen, float(errors["poly"][use].sum())


def trust_polynomial(chosen: float, poly: float) -> bool:
    """Whether a part's correction is trusted as it is out to its tested reach (its box enlarged to it) in
    place of the chosen extensions beyond the box: only where, held out, it brings their error below
    ``TANGENT_GAIN`` of theirs (summed over a face's rows, or a joint fit's; :func:`chosen_error`)."""
    return chosen > 0 and poly < TANGENT_GAIN * chosen

"""Model choice by cross-validation over loading segments, from one streamed QR pass.

Rows are dealt to ``K`` folds by whole loading segments (contiguous runs of samples),
round-robin so that every fold spans the session's time (never shuffled neighbours:
scikit-learn's ``GroupKFold``). Each fold keeps its own triangular factor of
``[A | B]`` (``StreamedQR``), so one pass over the data gives every candidate's
cross-validated error: the training factor of fold ``k`` is the QR of the other folds'
stacked factors, and the held-out sum of squares of a solution ``X`` is
``‖R11_k X − R12_k‖² + tr(EᵀE)_k`` from fold ``k``'s factor alone.

A problem regresses some columns ``y`` of ``B`` on unpenalised columns ``a`` of ``A``
(offsets, channels) and penalised columns ``b`` (nonlinear features), with a ridge
``α · mean(σ²)`` on ``b`` (``σ`` the singular values of ``b`` once ``a`` is projected
out). ``α = ∞`` is the affine fit.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._lstsq import RANK_RTOL, StreamedQR

__all__ = ["N_FOLDS", "ALPHAS", "FoldedQR", "Problem", "segment_ids", "fold_of_segments", "cross_validate",
           "solve_problem"]

#: Folds of the cross-validation.
N_FOLDS = 5
#: Ridge strengths tried for the nonlinear features (relative to their mean squared singular value).
ALPHAS = 10.0 ** np.arange(-7.0, 0.5, 1.0)
#: Segments are cut to at most this fraction of a session, so every fold holds many of them.
MAX_SEGMENT_FRACTION = 1 / 40


class SegmentCounter:
    """Loading segments of a stream of samples, block by block.

    A segment starts where the loaded faces change; segments longer than ``max_len``
    samples are cut into contiguous pieces of ``max_len``. Numbering continues across
    blocks (and across sessions, when one counter reads them all).
    """

    def __init__(self, max_len: int):
        self.max_len = max(1, int(max_len))
        self.count = 0  # segments started so far
        self._last = None
        self._run = 0  # samples of the current segment so far

    def ids(self, loaded: np.ndarray, new_session: bool = False) -> np.ndarray:
        """``(n,)`` segment of each row of ``loaded (n, k)``."""
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
        start = pos % self.max_len == 0
        out = self.count - 1 + np.cumsum(start)
        self.count += int(start.sum())
        self._run = int(pos[-1]) + 1
        self._last = loaded[-1].copy()
        return out


def segment_ids(loaded: np.ndarray, max_len: int | None = None) -> np.ndarray:
    """``(N,)`` loading segment of each sample (see :class:`SegmentCounter`).

    Default ``max_len``: ``MAX_SEGMENT_FRACTION`` of the samples.
    """
    n = len(loaded)
    if max_len is None:
        max_len = int(np.ceil(n * MAX_SEGMENT_FRACTION))
    return SegmentCounter(max_len).ids(loaded)


def fold_of_segments(segments: np.ndarray, n_folds: int = N_FOLDS) -> np.ndarray:
    """``(N,)`` fold of each sample: segments dealt round-robin in order of first appearance."""
    segments = np.asarray(segments)
    _, first, inverse = np.unique(segments, return_index=True, return_inverse=True)
    rank = np.argsort(np.argsort(first))  # order of first appearance of each segment
    return (rank[inverse] % n_folds).astype(np.int64)


class FoldedQR:
    """One :class:`StreamedQR` of ``[A | B]`` per fold."""

    def __init__(self, p: int, q: int, n_folds: int = N_FOLDS):
        self.p, self.q, self.n_folds = p, q, n_folds
        self.folds = [StreamedQR(p, q) for _ in range(n_folds)]

    def add(self, A: np.ndarray, B: np.ndarray, fold: np.ndarray) -> None:
        """Fold rows ``A (n, p)``, ``B (n, q)`` into their folds ``fold (n,)``."""
        for k in range(self.n_folds):
            m = fold == k
            if m.any():
                self.folds[k].add(A[m], B[m])

    @property
    def n_rows(self) -> int:
        return sum(f.n_rows for f in self.folds)

    def factor(self, exclude: int | None = None) -> np.ndarray:
        """``(p, p + q)`` ``[R11 | R12]`` of the folds other than ``exclude`` (all if None)."""
        blocks = [np.hstack([np.triu(f.R11), f.R12]) for k, f in enumerate(self.folds) if k != exclude]
        M = np.vstack(blocks)
        R = np.linalg.qr(M, mode="r")
        out = np.zeros((self.p, self.p + self.q))
        r = min(R.shape[0], self.p)
        out[:r] = R[:r]
        return out


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


def _reduce(F: np.ndarray, p: int, prob: Problem) -> np.ndarray:
    """Triangular factor of ``[A_a | A_b | B_y]`` from a factor ``F = [R11 | R12]`` of ``[A | B]``."""
    M = np.hstack([F[:, prob.a], F[:, prob.b], F[:, p + prob.y]])
    return np.linalg.qr(M, mode="r")


def _path(T: np.ndarray, na: int, nb: int, alphas, rank_a=None) -> list[np.ndarray]:
    """Solutions ``(na + nb, ny)`` for each α (``inf``: b fixed at 0) from the reduced factor ``T``.

    With ``rank_a`` (or a rank-deficient ``a``), the unpenalised part lies in the span of the
    leading right singular vectors of the column-scaled ``a`` (as the affine fit's truncated
    solve), and ``b`` is fitted against that span, not against all of ``a``.
    """
    d = np.linalg.norm(T[:na, :na], axis=0)
    d = np.where(d > 0, 1.0 / np.where(d > 0, d, 1.0), 0.0)
    Ua, sa, Vta = np.linalg.svd(T[:na, :na] * d)
    r = int(np.sum(sa > RANK_RTOL * sa[0])) if sa.size and sa[0] > 0 else 0
    r = r if rank_a is None else min(r, int(rank_a))
    Pa = np.eye(na)
    if r < na:
        Pa = d[:, None] * Vta[:r].T  # (na, r): the kept directions of a, in its own columns
        T = np.linalg.qr(np.hstack([T[:, :na] @ Pa, T[:, na:]]), mode="r")
    Taa, Tab, Tay = T[:r, :r], T[:r, r : r + nb], T[:r, r + nb :]
    Tbb, Tby = T[r : r + nb, r : r + nb], T[r : r + nb, r + nb :]
    if nb:
        U, s, Vt = np.linalg.svd(Tbb)
        UtY = U.T @ Tby
        lam0 = float(np.mean(s**2)) if s.size and s[0] > 0 else 1.0
    out = []
    for alpha in alphas:
        if np.isinf(alpha) or nb == 0:
            Xb = np.zeros((nb, Tay.shape[1]))
        else:
            Xb = Vt.T @ ((s / (s**2 + alpha * lam0))[:, None] * UtY)
        Xa = Pa @ np.linalg.solve(Taa, Tay - Tab @ Xb) if r else np.zeros((na, Tay.shape[1]))
        out.append(np.vstack([Xa, Xb]))
    return out


def cross_validate(folded: FoldedQR, problems, alphas=ALPHAS) -> dict:
    """Held-out weighted sum of squares of every problem, fold and α (``inf`` first: the affine fit).

    Returns
    -------
    dict
        ``alphas (A,)`` with ``inf`` first; ``sse (A, K, n_problems, ny)`` held-out sums of
        squares per output (output units²); ``n_rows (K,)``.
    """
    alphas = np.r_[np.inf, np.asarray(alphas, dtype=float)]
    K, p = folded.n_folds, folded.p
    ny = max(pr.y.size for pr in problems)
    sse = np.full((alphas.size, K, len(problems), ny), np.nan)
    for k in range(K):
        fk = folded.folds[k]
        if fk.n_rows == 0:
            continue
        F = folded.factor(exclude=k)
        Rk = np.triu(fk.R11)
        for j, pr in enumerate(problems):
            T = _reduce(F, p, pr)
            base = np.diag(fk.residual_cp)[pr.y]
            Ak = np.hstack([Rk[:, pr.a], Rk[:, pr.b]])
            Bk = fk.R12[:, pr.y]
            for i, X in enumerate(_path(T, pr.a.size, pr.b.size, alphas, pr.rank_a)):
                E = Ak @ X - Bk
                sse[i, k, j, : pr.y.size] = np.sum(E * E, axis=0) + base
    return {"alphas": alphas, "sse": sse, "n_rows": np.array([f.n_rows for f in folded.folds])}


def solve_problem(folded: FoldedQR, prob: Problem, alpha: float) -> np.ndarray:
    """``(na + nb, ny)`` solution of ``prob`` on every fold with ridge ``alpha`` (``inf``: affine)."""
    T = _reduce(folded.factor(), folded.p, prob)
    return _path(T, prob.a.size, prob.b.size, [alpha], prob.rank_a)[0]


#: The nonlinear model must cut the cross-validated error below this fraction of the affine fit's.
MARGIN = 0.9
#: ... win on more than half of the folds, and be no worse on forces nor on torques alone.
MODELS = ("auto", "linear", "poly")


@dataclass
class ModelChoice:
    """Which model a fit uses, and the cross-validated figures that chose it.

    Attributes
    ----------
    name : {"linear", "poly"}
        ``linear``: the papers' affine least squares (``C = W S⁺``). ``poly``: the same
        with a ridge-regularised polynomial correction (``_poly.py``).
    requested : {"auto", "linear", "poly"}
        What the caller asked for.
    alpha : float or None
        Ridge strength of the polynomial correction (relative; None for ``linear``).
    cv_rmse : dict
        ``{"linear": [...], "poly": [...]}``: cross-validated RMSE of every output (in the
        order of the fit's outputs: N, N·m); empty when no cross-validation ran.
    cv_score : dict
        ``{"linear": s, "poly": s}``: held-out RMSE of all outputs, each scaled by its
        full scale (dimensionless); the choice compares these.
    folds_won : int
        Folds on which ``poly`` had the lower held-out error.
    n_folds, n_segments : int
        Folds and loading segments of the cross-validation.
    reason : str
        One sentence for the operator.
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

    def to_dict(self) -> dict:
        """JSON-serialisable fields (for files and reports)."""
        return {"name": self.name, "requested": self.requested, "alpha": self.alpha,
                "cv_rmse": self.cv_rmse or {}, "cv_score": self.cv_score or {}, "folds_won": int(self.folds_won),
                "n_folds": int(self.n_folds), "n_segments": int(self.n_segments), "reason": self.reason}

    @classmethod
    def from_dict(cls, d: dict) -> "ModelChoice":
        d = dict(d)
        if d.get("name") not in ("linear", "poly"):
            raise ValueError(f"model.name: expected 'linear' or 'poly', got {d.get('name')!r}")
        return cls(**{k: d[k] for k in cls.__dataclass_fields__ if k in d})


def choose_model(results, requested: str, n_segments: int) -> ModelChoice:
    """Pick ``linear`` or ``poly`` from ``results``: list of ``(cross_validate output, weights per problem)``.

    ``poly`` (at its best α) is chosen under ``auto`` only if its held-out error is below
    ``MARGIN`` × the affine fit's and it wins on more than half of the folds; ``linear`` and
    ``poly`` force the choice (the figures are still reported).
    """
    alphas = results[0][0]["alphas"]
    K = results[0][0]["sse"].shape[1]
    per_fold = np.zeros((alphas.size, K))  # weighted held-out SSE
    per_kind = np.zeros((alphas.size, 2))  # ... of the forces and of the torques
    rows = 0
    rmse = {"linear": [], "poly": []}
    for cv, weights in results:
        sse = np.nan_to_num(cv["sse"])
        for j, w in enumerate(weights):
            e = sse[:, :, j, : w.size] * w**2
            per_fold += e.sum(axis=2)
            kind = (np.arange(w.size) % 6) >= 3
            per_kind[:, 0] += e[:, :, ~kind].sum(axis=(1, 2))
            per_kind[:, 1] += e[:, :, kind].sum(axis=(1, 2))
        rows += int(cv["n_rows"].sum()) * sum(w.size for w in weights)
    total = per_fold.sum(axis=1)
    best = 1 + int(np.argmin(total[1:]))
    for cv, weights in results:
        n = max(int(cv["n_rows"].sum()), 1)
        for j, w in enumerate(weights):
            for key, a in (("linear", 0), ("poly", best)):
                rmse[key] += np.sqrt(cv["sse"][a, :, j, : w.size].sum(axis=0) / n).tolist()
    score = {"linear": float(np.sqrt(total[0] / max(rows, 1))), "poly": float(np.sqrt(total[best] / max(rows, 1)))}
    won = int(np.sum(per_fold[best] < per_fold[0]))
    each = bool(np.all(per_kind[best] <= per_kind[0]))
    gain = score["poly"] < MARGIN * score["linear"] and won > K / 2 and each and score["linear"] > 1e-9
    ratio = score["poly"] / score["linear"] if score["linear"] > 0 else float("nan")
    if requested == "auto":
        name = "poly" if gain else "linear"
        why = (f"cross-validated over {K} folds of {n_segments} loading segments, the polynomial correction's "
               f"held-out error is {ratio:.2f}× the affine fit's (won {won}/{K} folds)")
        keep = (f"; kept the papers' affine fit (the correction must reach ≤ {MARGIN:.2f}× on most folds, "
                "and not be worse on forces or torques alone)")
        why += "; it is used" if gain else keep
    else:
        name = requested
        why = f"{requested} as requested (cross-validated polynomial/affine held-out error {ratio:.2f}×, {won}/{K} folds)"
    return ModelChoice(name=name, requested=requested, alpha=float(alphas[best]) if name == "poly" else None,
                       cv_rmse=rmse, cv_score=score, folds_won=won, n_folds=K, n_segments=int(n_segments), reason=why)

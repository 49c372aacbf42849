"""Least squares by streamed (blocked) Householder QR, with column scaling.

``C = W S⁺`` is solved as the least-squares problem ``S X = W`` (``X = Cᵀ``), rows
= samples. Blocks of ``[S | W]`` are folded into a running triangular factor
(``R ← qr([R; block])``), so memory is bounded by one block whatever the number of
samples, and the result equals the in-memory QR solution to rounding. Normal
equations are never formed (they would square the condition number).
"""

from __future__ import annotations

import numpy as np
import scipy.linalg
import scipy.linalg.lapack

__all__ = ["StreamedQR", "LstsqResult"]

#: Relative singular-value cut-off below which the scaled design is called rank deficient.
RANK_RTOL = 1e-10


class LstsqResult:
    """Solution ``X (p, q)``, the scaled design's singular values ``sv (p,)`` and the rank kept."""

    def __init__(self, X, sv, n_rows, residual_rms, rank, numerical_rank):
        self.rank = rank
        self.numerical_rank = numerical_rank
        self.X = X
        self.sv = sv
        self.n_rows = n_rows
        self.residual_rms = residual_rms



class StreamedQR:
    """Accumulate ``[A | B]`` row blocks into a triangular factor.

    Parameters
    ----------
    p : int
        Number of unknowns per right-hand side (columns of A).
    q : int
        Number of right-hand sides (columns of B).
    flush_rows : int
        Rows gathered before they are folded into R: memory ≈ ``flush_rows·(p+q)·8`` B.
    """

    def __init__(self, p: int, q: int, flush_rows: int = 65536):
        self.p, self.q = p, q
        self.flush_rows = int(flush_rows)
        self.R = np.zeros((0, p + q))
        self.n_rows = 0
        self._pending: list[np.ndarray] = []
        self._pending_rows = 0

    def add(self, A: np.ndarray, B: np.ndarray) -> None:
        """Append rows ``A (n, p)`` and ``B (n, q)``."""
        if A.shape[0] == 0:
            return
        self._pending.append(np.concatenate([A, B], axis=1))
        self._pending_rows += A.shape[0]
        self.n_rows += A.shape[0]
        if self._pending_rows >= self.flush_rows:
            self._flush()

    def _flush(self) -> None:
        if not self._pending:
            return
        width = self.p + self.q
        rows = self.R.shape[0] + self._pending_rows
        M = np.empty((rows, width), order="F")  # LAPACK's layout: no hidden copy
        M[: self.R.shape[0]] = self.R
        at = self.R.shape[0]
        for block in self._pending:
            M[at : at + block.shape[0]] = block
            at += block.shape[0]
        self._pending, self._pending_rows = [], 0
        qr, _, _, info = scipy.linalg.lapack.dgeqrf(M, overwrite_a=1)
        if info != 0:  # pragma: no cover - LAPACK argument error
            raise RuntimeError(f"dgeqrf failed with info={info}")
        k = min(rows, width)
        self.R = np.triu(qr[:k])

    def solve(self, rank: int | None = None) -> LstsqResult:
        """Least-squares solution from the accumulated factor, of rank at most ``rank``.

        Columns of A are scaled to unit norm (their norms are read off R) before the
        solve, so counts of very different gains do not spoil the solve or the rank
        test. The scaled problem is solved by SVD keeping the ``rank`` largest singular
        values (default all): with fewer, the minimum-norm solution in the subspace
        the data span. Singular values below ``RANK_RTOL·σ1`` are always dropped (the
        ``S⁺`` of the papers: least squares when the design has full rank, minimum norm
        when it has not).
        """
        self._flush()
        p = self.p
        R = np.zeros((p + self.q, p + self.q))
        R[: self.R.shape[0]] = self.R
        R11, R12, R22 = R[:p, :p], R[:p, p:], R[p:, p:]
        norms = np.linalg.norm(R11, axis=0)
        d = np.where(norms > 0, 1.0 / np.where(norms > 0, norms, 1.0), 0.0)
        U, sv, Vt = np.linalg.svd(R11 * d)
        r_num = int(np.sum(sv > RANK_RTOL * sv[0])) if sv.size and sv[0] > 0 else 0
        r = r_num if rank is None else int(min(rank, r_num))
        keep = slice(0, r)
        Z = Vt[keep].T @ ((U[:, keep].T @ R12) / np.where(sv[keep] > 0, sv[keep], np.inf)[:, None])
        X = Z * d[:, None]
        resid = np.sqrt(np.sum(R22**2, axis=0) / max(self.n_rows, 1))
        return LstsqResult(X, sv, self.n_rows, resid, r, r_num)

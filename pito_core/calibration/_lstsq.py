"""Least squares from a streamed triangular factor, with column scaling: two cores.

``C = W S⁺`` is solved as the least-squares problem ``S X = W`` (``X = Cᵀ``), rows
= samples. Both cores keep only the triangular factor ``R`` of ``[S | W]`` (``R11``,
``R12``) and the residuals' cross-products ``EᵀE``, so memory is bounded by one block
whatever the number of samples, and the covariance of the fit needs nothing else.

- :class:`GramQR` (the fast path): the Gram matrix of ``[S | W]`` summed over blocks (one
  level-3 BLAS product per block), then ``R`` by Cholesky of the column-scaled Gram
  (Cholesky-QR). It squares the condition number, so :meth:`GramQR.trouble` says when it
  must not be trusted: the Cholesky fails, a column is empty, or the scaled factor's
  condition number exceeds ``GRAM_KAPPA_MAX`` (forward error of the solution against a
  QR solve then stays below ~``10·ε·κ²`` ≈ 2·10⁻⁸ relative; tests/calibration/test_numerics.py).
  The caller then refits with the streamed QR.
- :class:`StreamedQR` (the stable core): blocks are folded into a running factor by
  Householder QR (``R ← qr([R; block])``); normal equations are never formed, and the
  result equals the in-memory QR solution to rounding.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg.lapack

__all__ = ["StreamedQR", "GramQR", "LstsqResult", "solve_factor"]

#: Relative singular-value cut-off below which the scaled design is called rank deficient.
RANK_RTOL = 1e-10
#: Largest condition number of the column-scaled design that :class:`GramQR` solves itself.
GRAM_KAPPA_MAX = 1e4


class LstsqResult:
    """Result of :meth:`StreamedQR.solve`.

    Attributes
    ----------
    X : ndarray, shape (p, q)
        The least-squares solution (minimum norm in the scaled columns where the design is
        rank deficient).
    sv : ndarray, shape (p,)
        Singular values of the column-scaled design.
    rank, numerical_rank : int
        Singular values kept, and those above ``RANK_RTOL·σ1``.
    n_rows : int
        Rows (samples) folded in.
    residual_rms : ndarray, shape (q,)
        RMS residual of each right-hand side over the rows.
    residual_cp : ndarray, shape (q, q)
        ``Eᵀ E``: cross-products of the residuals ``E = B − A X`` (sums over rows).
    design_pinv : ndarray, shape (p, p)
        ``(AᵀA)⁺`` restricted to the kept directions: the covariance of a row of ``X`` per
        unit residual variance (``Cov(X[:, j]) = σ_j² (AᵀA)⁺``).
    """

    def __init__(self, X, sv, n_rows, residual_rms, rank, numerical_rank, residual_cp=None, design_pinv=None):
        self.rank = rank
        self.numerical_rank = numerical_rank
        self.X = X
        self.sv = sv
        self.n_rows = n_rows
        self.residual_rms = residual_rms
        self.residual_cp = residual_cp
        self.design_pinv = design_pinv


class StreamedQR:
    """Accumulate ``[A | B]`` row blocks into a triangular factor.

    Each block is folded in as it arrives, ``chunk_rows`` rows at a time, by the
    structured Householder QR of ``[R11; A_chunk]`` (LAPACK ``dtpqrt``: R11 triangular on
    top of a dense chunk) and the same reflectors applied to ``[R12; B_chunk]``
    (``dtpmqrt``). Only ``R11 (p, p)``, ``R12 (p, q)`` and the column sums of squares of
    the residual rows are kept: the same ``R`` as a QR of the whole ``[A | B]`` (to
    rounding), in cache-sized pieces, with no copy of the block.

    Parameters
    ----------
    p : int
        Number of unknowns per right-hand side (columns of A).
    q : int
        Number of right-hand sides (columns of B).
    flush_rows : int
        Kept for compatibility; blocks are no longer buffered (memory is one chunk of
        ``chunk_rows·(p+q)·8`` B beyond the caller's block).
    chunk_rows : int
        Rows per Householder sweep (512: the sweep's working set stays in L2 cache).
    """

    def __init__(self, p: int, q: int, flush_rows: int = 65536, chunk_rows: int = 512):
        self.p, self.q = p, q
        self.flush_rows = int(flush_rows)
        self.chunk_rows = max(1, int(chunk_rows))
        self.R11 = np.zeros((p, p), order="F")
        self.R12 = np.zeros((p, q), order="F")
        self.residual_cp = np.zeros((q, q))  # Σ over samples of the residuals' cross-products (Eᵀ E)
        self.n_rows = 0
        self._nb = max(1, min(64, p))  # one Householder block for p ≤ 64 (36 gauges): ~5 % faster than 32

    def add(self, A: np.ndarray, B: np.ndarray) -> None:
        """Fold rows ``A (n, p)`` and ``B (n, q)`` into the factor."""
        n = A.shape[0]
        if n == 0:
            return
        self.n_rows += n
        tpqrt, tpmqrt = scipy.linalg.lapack.dtpqrt, scipy.linalg.lapack.dtpmqrt
        R11, R12, nb, step = self.R11, self.R12, self._nb, self.chunk_rows
        for s in range(0, n, step):
            Ak = np.array(A[s : s + step], dtype=float, order="F")
            Bk = np.array(B[s : s + step], dtype=float, order="F")
            R11, V, T, info = tpqrt(0, nb, R11, Ak, overwrite_a=1, overwrite_b=1)
            if info != 0:  # pragma: no cover - LAPACK argument error
                raise RuntimeError(f"dtpqrt failed with info={info}")
            R12, Bk, info = tpmqrt(0, V, T, R12, Bk, trans="T", overwrite_a=1, overwrite_b=1)
            if info != 0:  # pragma: no cover
                raise RuntimeError(f"dtpmqrt failed with info={info}")
            self.residual_cp += Bk.T @ Bk  # rows of Qᵀ[B] below R12: the residual's Gram
        self.R11, self.R12 = R11, R12

    @property
    def residual_ss(self) -> np.ndarray:
        """``(q,)`` Σ over samples of the squared residual of each column of B."""
        return np.diag(self.residual_cp).copy()

    def solve(self, rank: int | None = None) -> LstsqResult:
        """Least-squares solution from the accumulated factor, of rank at most ``rank``.

        Columns of A are scaled to unit norm (their norms are read off R) before the
        solve, so counts of very different gains do not spoil the solve or the rank
        test. The scaled problem is solved by SVD keeping the ``rank`` largest singular
        values (default all): with fewer, the minimum-norm solution in the subspace
        the data span. Singular values below ``RANK_RTOL·σ1`` are always dropped (the
        ``S⁺`` of the papers: least squares when the design has full rank, minimum norm
        when it has not). A full-rank least-squares solution does not depend on the scale.
        """
        return solve_factor(self.R11, self.R12, self.residual_cp, self.n_rows, rank)


def solve_factor(R11, R12, residual_cp, n_rows, rank=None) -> LstsqResult:
    """:meth:`StreamedQR.solve` for a factor ``R11 (p, p)``, ``R12 (p, q)``, ``EᵀE (q, q)`` of ``n_rows`` rows."""
    R11 = np.triu(R11)
    p = R11.shape[0]
    norms = np.linalg.norm(R11, axis=0)
    d = np.where(norms > 0, 1.0 / np.where(norms > 0, norms, 1.0), 0.0)
    U, sv, Vt = np.linalg.svd(R11 * d)
    r_num = int(np.sum(sv > RANK_RTOL * sv[0])) if sv.size and sv[0] > 0 else 0
    r = r_num if rank is None else int(min(rank, r_num))
    keep = slice(0, r)
    inv_s = 1.0 / sv[keep]
    Z = Vt[keep].T @ ((U[:, keep].T @ R12) * inv_s[:, None])
    X = Z * d[:, None]
    F = (Vt[keep].T * inv_s) * d[:, None]  # (p, r): (AᵀA)⁺ = F Fᵀ
    resid_cp = np.array(residual_cp, dtype=float)
    if r < r_num or r < p:  # directions left out add their part of R12 to the residual
        Ud = U[:, r:].T @ R12
        resid_cp += Ud.T @ Ud
    resid = np.sqrt(np.clip(np.diag(resid_cp), 0.0, None) / max(n_rows, 1))
    return LstsqResult(X, sv, n_rows, resid, r, r_num, resid_cp, F @ F.T)


class GramQR:
    """The factor of ``[A | B]`` from its Gram matrix (Cholesky-QR): the fast core.

    Holds the same ``R11 (p, p)``, ``R12 (p, q)``, ``residual_cp (q, q)`` and ``n_rows``
    as :class:`StreamedQR` and solves the same way, but from ``G = [A | B]ᵀ[A | B]``
    accumulated by the caller (one BLAS ``syrk`` per block). ``R11`` is the Cholesky
    factor of the column-scaled ``AᵀA`` (scaled back), ``R12 = R11⁻ᵀ AᵀB`` and
    ``EᵀE = BᵀB − R12ᵀR12``. Check :meth:`trouble` before trusting it.

    Parameters
    ----------
    G_AA : ndarray, shape (p, p)
    G_AB : ndarray, shape (p, q)
    G_BB : ndarray, shape (q, q)
    n_rows : int
        Rows (samples) summed into the Gram.
    """

    def __init__(self, G_AA, G_AB, G_BB, n_rows: int):
        G_AA, G_AB, G_BB = (np.asarray(g, dtype=float) for g in (G_AA, G_AB, G_BB))
        self.p, self.q = G_AB.shape
        self.n_rows = int(n_rows)
        self.kappa = np.inf
        self.R11 = np.zeros((self.p, self.p))
        self.R12 = np.zeros((self.p, self.q))
        self.residual_cp = 0.5 * (G_BB + G_BB.T)
        self._problem = None
        dg = np.diag(G_AA)
        if self.p == 0 or not np.all(dg > 0) or not np.all(np.isfinite(G_AA)):
            self._problem = "a column of the design is empty (zero norm)"
            return
        d = 1.0 / np.sqrt(dg)
        Gs = G_AA * np.outer(d, d)
        Rs, info = scipy.linalg.lapack.dpotrf(0.5 * (Gs + Gs.T), lower=0, clean=1)
        if info != 0:
            self._problem = f"the scaled Gram matrix is not positive definite (Cholesky info {info})"
            return
        sv = np.linalg.svd(Rs, compute_uv=False)
        self.kappa = float(sv[0] / sv[-1]) if sv[-1] > 0 else np.inf
        if not self.kappa <= GRAM_KAPPA_MAX:
            self._problem = f"condition number {self.kappa:.3g} of the scaled design exceeds {GRAM_KAPPA_MAX:.0e}"
            return
        self.R11 = Rs / d[None, :]
        R12s, info = scipy.linalg.lapack.dtrtrs(Rs, G_AB * d[:, None], lower=0, trans=1)
        if info != 0:  # pragma: no cover - a positive diagonal was just checked
            self._problem = f"triangular solve failed (info {info})"
            return
        self.R12 = R12s
        E = self.residual_cp - R12s.T @ R12s
        self.residual_cp = 0.5 * (E + E.T)

    def trouble(self) -> str | None:
        """Why the Gram route must not be trusted for these data (None: it may)."""
        return self._problem

    def solve(self, rank: int | None = None) -> LstsqResult:
        """As :meth:`StreamedQR.solve` (raises if :meth:`trouble`)."""
        if self._problem is not None:
            raise RuntimeError(f"GramQR: {self._problem}; use StreamedQR")
        return solve_factor(self.R11, self.R12, self.residual_cp, self.n_rows, rank)

"""Polynomial features of scaled channels, and the nonlinear correction a calibration applies.

The correction adds, to the affine fit's output, a linear combination of low-order
monomials of the offset-free channels ``u = (counts − offset) / scale``: within each block
of channels (a face's own six gauges), every square and pairwise product (``u_i u_j``,
``i ≤ j``) and every cube (``u_i³``). Squares and products model a quadratic response
(hub bending, load-dependent contact in the frame's screw joints); cubes a per-gauge
odd nonlinearity (amplifier or bridge saturation). Beyond the range its channels were
fitted on (``lower``, ``upper``), a polynomial grows fast and its fit says nothing: there
each monomial continues from its value at the range's edge along ``EDGE_SLOPE`` of its
slope there (a taper between holding the edge value and the tangent line).
"""

from __future__ import annotations

import numpy as np

__all__ = ["poly_terms", "poly_features", "poly_features_t", "PolyCorrection", "EDGE_SLOPE"]

#: Beyond the fitted range, a monomial continues along this fraction of its slope at the edge.
#: 0 holds the edge value, 1 follows the tangent. Measured (held-out RMSE on a later session,
#: docs/calibration.md): holding (0) lost to the linear fit on a cube whose gauges saturate
#: (tanh) when the later loads were twice the training's (1.23×); the tangent (1) lost on
#: ``pito_core.sim``'s free-face torques (1.06×); 0.5 won on both (≤ 0.55×, ≤ 1.013×).
EDGE_SLOPE = 0.5


def poly_terms(blocks) -> tuple[np.ndarray, np.ndarray]:
    """Monomials of ``blocks`` (sequences of channel indices): ``pairs (P, 2)`` and ``cubes (Q,)``.

    ``pairs`` holds every ``(i, j)`` with ``i ≤ j`` inside a block (squares and products),
    ``cubes`` every channel of every block.
    """
    pairs = [(i, j) for b in blocks for a, i in enumerate(b) for j in list(b)[a:]]
    cubes = [i for b in blocks for i in b]
    return np.asarray(pairs, dtype=np.int64).reshape(-1, 2), np.asarray(cubes, dtype=np.int64)


def poly_features(u: np.ndarray, pairs: np.ndarray, cubes: np.ndarray) -> np.ndarray:
    """``(N, P + Q)`` features ``[u_i u_j for pairs, u_i³ for cubes]`` of ``u (N, m)`` (dimensionless)."""
    uT = np.ascontiguousarray(np.asarray(u, dtype=float).T)  # (m, N): a channel per contiguous row
    return poly_features_t(uT, pairs, cubes).T


def poly_features_t(uT: np.ndarray, pairs: np.ndarray, cubes: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """``(P + Q, N)`` the features of :func:`poly_features`, transposed, from ``uT (m, N)``.

    ``out`` (optional, shape ``(P + Q, N)``, rows contiguous) receives them.
    """
    P = pairs.shape[0]
    if out is None:
        out = np.empty((P + cubes.size, uT.shape[1]))
    np.multiply(uT[pairs[:, 0]], uT[pairs[:, 1]], out=out[:P])
    c = uT[cubes]
    np.multiply(c * c, c, out=out[P:])
    return out


class PolyCorrection:
    """The nonlinear part of a calibration: ``Δw = coef · φ((counts − offset) / scale)``.

    Parameters
    ----------
    scale : array-like, shape (m,)
        Counts per unit of ``u`` for each channel (positive).
    pairs : array-like of int, shape (P, 2)
    cubes : array-like of int, shape (Q,)
        The monomials (see :func:`poly_terms`).
    coef : array-like, shape (q, P + Q)
        Output units per feature: rows in the order of the calibration's matrix rows
        (``[fx, fy, fz, tx, ty, tz]`` per output face, N and N·m, in its output frame).
    lower, upper : array-like, shape (m,), optional
        Range of ``u`` (dimensionless) the correction was fitted on; beyond it the monomials
        are tapered (``EDGE_SLOPE``). None (files written before the range was kept): the
        plain polynomial everywhere.
    """

    def __init__(self, scale, pairs, cubes, coef, lower=None, upper=None):
        self.scale = np.asarray(scale, dtype=float).reshape(-1)
        self.pairs = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
        self.cubes = np.asarray(cubes, dtype=np.int64).reshape(-1)
        self.coef = np.asarray(coef, dtype=float)
        m, r = self.scale.size, self.pairs.shape[0] + self.cubes.size
        if not np.all(np.isfinite(self.scale)) or np.any(self.scale <= 0):
            raise ValueError("scale: expected finite positive counts per unit")
        for name, idx in (("pairs", self.pairs), ("cubes", self.cubes)):
            if idx.size and (idx.min() < 0 or idx.max() >= m):
                raise ValueError(f"{name}: expected channel indices in 0..{m - 1}")
        if self.coef.ndim != 2 or self.coef.shape[1] != r or not np.all(np.isfinite(self.coef)):
            raise ValueError(f"coef: expected finite values of shape (q, {r}), got {self.coef.shape}")
        if (lower is None) != (upper is None):
            raise ValueError("lower, upper: expected both or neither")
        self.lower = self.upper = None
        if lower is not None:
            self.lower = np.asarray(lower, dtype=float).reshape(-1)
            self.upper = np.asarray(upper, dtype=float).reshape(-1)
            if self.lower.shape != (m,) or self.upper.shape != (m,) or np.any(np.isnan(self.lower)) \
                    or np.any(np.isnan(self.upper)) or np.any(self.lower > self.upper):
                raise ValueError(f"lower, upper: expected ({m},) ranges with lower ≤ upper")

    def _features_t(self, x: np.ndarray, pairs: np.ndarray, cubes: np.ndarray) -> np.ndarray:
        """``(P + Q, N)`` features of offset-free counts ``x (N, m)``, tapered beyond the fitted range.

        With ``c`` the channels clipped to the range, ``d = u − c`` and ``s = EDGE_SLOPE``:
        ``u_i u_j → c_i c_j + s (c_j d_i + c_i d_j)`` and ``u_i³ → c_i³ + 3 s c_i² d_i``.
        """
        uT = np.ascontiguousarray((np.asarray(x, dtype=float) / self.scale).T)  # (m, N)
        if self.lower is None:
            return poly_features_t(uT, pairs, cubes)
        cT = np.clip(uT, self.lower[:, None], self.upper[:, None], out=np.empty_like(uT))
        out = poly_features_t(cT, pairs, cubes)
        beyond = np.flatnonzero(np.any(cT != uT, axis=0))  # samples with a channel beyond the range
        if beyond.size:
            c, d = cT[:, beyond], uT[:, beyond] - cT[:, beyond]
            P = pairs.shape[0]
            i, j = pairs[:, 0], pairs[:, 1]
            out[:P, beyond] += EDGE_SLOPE * (c[j] * d[i] + c[i] * d[j])
            out[P:, beyond] += EDGE_SLOPE * 3.0 * c[cubes] ** 2 * d[cubes]
        return out

    @property
    def n_features(self) -> int:
        return self.coef.shape[1]

    def features(self, x: np.ndarray) -> np.ndarray:
        """``(N, P + Q)`` features of offset-free counts ``x (N, m)``."""
        return self._features_t(x, self.pairs, self.cubes).T

    def __call__(self, x: np.ndarray) -> np.ndarray:
        """``(N, q)`` correction for offset-free counts ``x (N, m)``, output units."""
        used = np.flatnonzero(np.any(self.coef != 0, axis=0))  # rows that keep the affine fit use none
        P = self.pairs.shape[0]
        phi = self._features_t(x, self.pairs[used[used < P]], self.cubes[used[used >= P] - P])
        return (self.coef[:, used] @ phi).T

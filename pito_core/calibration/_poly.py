"""Polynomial features of scaled channels, and the nonlinear correction a calibration applies.

The correction adds, to the affine fit's output, a linear combination of low-order
monomials of the offset-free channels ``u = (counts − offset) / scale``: within each block
of channels (a face's own six gauges), every square and pairwise product (``u_i u_j``,
``i ≤ j``) and every cube (``u_i³``). Squares and products model a quadratic response
(hub bending, load-dependent contact in the frame's screw joints); cubes a per-gauge
odd nonlinearity (amplifier or bridge saturation). A polynomial must not extrapolate: where a
sample lies beyond the loads it was fitted on, the sample is drawn back along its own ray from
zero load, ``x_c = t x`` with the largest ``t ≤ 1`` that puts it inside (a larger load of the
same pattern becomes the largest trained one; a clamp of each channel alone would put the
products at corners no load reached), and the correction is
``Δw = coef · φ(x_c / scale) + E (x_c − x)``, ``E`` the corrected model's slopes less the linear
fit's (``edge_matrix``). Inside: the polynomial; beyond: its value at the edge plus the linear
fit's slope from there, so it never grows faster than the linear fit.

"Inside" is inside one of two boxes: each channel's range in training (``lower``, ``upper``), or,
with a ``domain``, the range of the training loads on each axis of the linear fit's wrenches
``z = domain · x`` (``domain_lower``, ``domain_upper``). Each alone draws back loads the other
knows were trained: a gauge's extremes need several axes at theirs at once (rarely reached, so
loads within the trained ones leave the channel box), and an axis at its extreme with the others
small leaves the wrench box while every gauge stays in range. An ``input_map`` ``P`` first takes
what a face's gauges read of other faces' loads out of them (``x → P x``, ``face_to_face``: its
correction of a face was fitted with the other faces unloaded); with a ``map_matrix`` ``L`` (the
linear fit's rows where a row is corrected) those rows read ``P x`` whole, their linear part too:
``L (P x − x)`` takes out what the linear fit's own-gauge slopes read of other faces' loads.
"""

from __future__ import annotations

import numpy as np

#: The correction is fitted (and cross-validated) from at most about this many samples, every
#: ``stride``-th of the sessions' (neighbouring samples at 1 kHz repeat one held load): its cost
#: stays bounded beside the affine fit, which uses every sample.
MAX_ROWS = 1 << 15

__all__ = ["poly_terms", "poly_features", "poly_features_t", "ray_into", "PolyCorrection"]


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


def ray_into(z: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """``(N,)`` the largest ``t ≤ 1`` with ``t z`` inside the box ``[lo, hi]`` (which holds zero), for ``z (N, d)``."""
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(z > hi, hi / z, np.where(z < lo, lo / z, 1.0))
    return np.clip(np.nan_to_num(t, nan=1.0), 0.0, 1.0).min(axis=1, initial=1.0)


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
        Range of ``u`` (dimensionless) the correction was fitted on. None: the plain polynomial
        everywhere (for tests of the features).
    edge_matrix : array-like, shape (q, m), optional
        Slopes of the corrected model less those of the linear fit (output units per count):
        beyond the range, ``edge_matrix (x_c − x)`` brings the slope back to the linear fit's.
        None: zero.
    domain : array-like, shape (d, m), optional
        Coordinates of the second box (a calibration: the linear fit's rows, N and N·m per count).
    domain_lower, domain_upper : array-like, shape (d,), optional
        Its range in training (with ``domain``).
    input_map : array-like, shape (m, m), optional
        ``P``: the correction reads ``P x`` in place of the offset-free counts ``x`` (None: ``x``).
    tangent : array-like of bool, shape (q,), optional
        Rows that continue beyond the box along the corrected model's own tangent at the edge (the
        polynomial's slope there, chosen on held-out largest loads: ``_cv.extension_errors``) in place of
        the linear fit's slope. None: none.
    map_matrix : array-like, shape (q, m), optional
        With ``input_map``: slopes (output units per count) applied to ``P x − x``, the part of the
        counts the map takes out (the linear fit's rows where the row is corrected, zero elsewhere:
        a corrected row then reads ``P x`` in its linear part too). None: zero.
    map_lower, map_upper : array-like, shape (m,), optional
        With ``map_matrix``: the range of ``P x − x`` on the rows the correction was fitted on (what the
        map misreads of a face's own load); ``map_matrix`` reads only what lies beyond it. None: zeros.
    reach : float or array-like of shape (q,), optional
        Factor ≥ 1 beyond the box as far as held-out loads tested its extension (``_cv.tested_reach``),
        one for every row or one per row (1: the row fades from the box's edge on, ``_cv.choose_extension``):
        a sample farther out along its ray (``t · reach < 1``) takes ``t · reach`` of the
        correction and the rest of the linear fit (the correction fades to it, ``edge_matrix`` being their
        slopes' difference). None: no fade.
    edge_mapped : bool, optional
        With ``input_map``: ``edge_matrix`` reads ``x_c − P x`` (zero inside the box) in place of
        ``x_c − x``: the corrected model's linear part reads the counts themselves, only its features
        ``P x`` (a joint method's correction). None or False: ``x_c − x``.
    """

    def __init__(self, scale, pairs, cubes, coef, lower=None, upper=None, edge_matrix=None, domain=None,
                 domain_lower=None, domain_upper=None, input_map=None, tangent=None, map_matrix=None,
                 map_lower=None, map_upper=None, edge_mapped=None, reach=None):
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
        self.domain = self.domain_lower = self.domain_upper = self.input_map = None
        if domain is not None:
            self.domain = np.asarray(domain, dtype=float)
            if self.domain.ndim != 2 or self.domain.shape[1] != m or not np.all(np.isfinite(self.domain)):
                raise ValueError(f"domain: expected finite values of shape (d, {m}), got {self.domain.shape}")
            d = self.domain.shape[0]
            self.domain_lower = np.asarray(domain_lower, dtype=float).reshape(-1)
            self.domain_upper = np.asarray(domain_upper, dtype=float).reshape(-1)
            if lower is None or self.domain_lower.shape != (d,) or self.domain_upper.shape != (d,) \
                    or not np.all(self.domain_lower <= self.domain_upper):
                raise ValueError(f"domain_lower, domain_upper: expected ({d},) ranges with lower ≤ upper, and lower, "
                                 "upper")
        if input_map is not None:
            self.input_map = np.asarray(input_map, dtype=float)
            if self.input_map.shape != (m, m) or not np.all(np.isfinite(self.input_map)):
                raise ValueError(f"input_map: expected finite values of shape ({m}, {m}), got {self.input_map.shape}")
        if (lower is None) != (upper is None):
            raise ValueError("lower, upper: expected both or neither")
        self.lower = self.upper = None
        if lower is not None:
            self.lower = np.asarray(lower, dtype=float).reshape(-1)
            self.upper = np.asarray(upper, dtype=float).reshape(-1)
            if self.lower.shape != (m,) or self.upper.shape != (m,) or np.any(np.isnan(self.lower)) \
                    or np.any(np.isnan(self.upper)) or np.any(self.lower > self.upper):
                raise ValueError(f"lower, upper: expected ({m},) ranges with lower ≤ upper")
        self.tangent = None
        if tangent is not None:
            self.tangent = np.asarray(tangent).astype(bool).reshape(-1)
            if self.tangent.shape != (self.coef.shape[0],):
                raise ValueError(f"tangent: expected ({self.coef.shape[0]},) flags, got {self.tangent.shape}")
            if not self.tangent.any():
                self.tangent = None
        self.map_matrix = None
        if map_matrix is not None:
            self.map_matrix = np.asarray(map_matrix, dtype=float)
            if self.input_map is None or self.map_matrix.shape != (self.coef.shape[0], m) \
                    or not np.all(np.isfinite(self.map_matrix)):
                raise ValueError(f"map_matrix: expected finite values of shape ({self.coef.shape[0]}, {m}) with an "
                                 f"input_map, got {self.map_matrix.shape}")
        self.map_lower = self.map_upper = None
        if map_lower is not None or map_upper is not None:
            self.map_lower = np.asarray(map_lower, dtype=float).reshape(-1)
            self.map_upper = np.asarray(map_upper, dtype=float).reshape(-1)
            if self.map_matrix is None or self.map_lower.shape != (m,) or self.map_upper.shape != (m,) \
                    or not np.all(self.map_lower <= 0) or not np.all(self.map_upper >= 0):
                raise ValueError(f"map_lower, map_upper: expected ({m},) ranges around zero, with a map_matrix")
        self.edge_mapped = True if edge_mapped is not None and bool(np.asarray(edge_mapped)) else None
        if self.edge_mapped and self.input_map is None:
            raise ValueError("edge_mapped: expected an input_map")
        self.reach = None
        if reach is not None:
            r = np.asarray(reach, dtype=float)
            self.reach = float(r) if r.ndim == 0 else r.reshape(-1)
            if r.shape not in ((), (self.coef.shape[0],)) or not np.all(np.isfinite(r)) or np.any(r < 1.0) \
                    or lower is None or edge_matrix is None:
                raise ValueError(f"reach: expected finite factors ≥ 1 (one, or ({self.coef.shape[0]},) per row), with "
                                 "lower, upper and edge_matrix")
        self.edge_matrix = None
        if edge_matrix is not None:
            self.edge_matrix = np.asarray(edge_matrix, dtype=float)
            if self.edge_matrix.shape != (self.coef.shape[0], m) or not np.all(np.isfinite(self.edge_matrix)):
                raise ValueError(f"edge_matrix: expected finite values of shape ({self.coef.shape[0]}, {m}), "
                                 f"got {self.edge_matrix.shape}")

    def mapped(self, x: np.ndarray) -> np.ndarray:
        """``(N, m)`` what the correction reads of offset-free counts ``x (N, m)``: ``P x`` (or ``x``)."""
        x = np.asarray(x, dtype=float)
        return x if self.input_map is None else x @ self.input_map.T

    def ray(self, x: np.ndarray):
        """``(P x (N, m), t (N,) or None)``: the mapped counts and the largest ``t ≤ 1`` that puts them in the box;
        what :meth:`all_terms`, :meth:`fade` and :meth:`beyond_sq` read (``ray=``: worked out once by a caller
        of all three)."""
        x = self.mapped(x)
        if self.lower is None:
            return x, None
        t = ray_into(x, self.lower * self.scale, self.upper * self.scale)
        if self.domain is not None:  # inside either box
            t = np.maximum(t, ray_into(x @ self.domain.T, self.domain_lower, self.domain_upper))
        return x, t

    def beyond_sq(self, x: np.ndarray, cols, ray=None) -> np.ndarray:
        """``(N, len(cols))``: how far offset-free counts ``x (N, m)`` lie beyond the box the correction reads
        in, ``‖(P x − t P x) / scale‖²`` over each set of channels in ``cols`` (``t`` the ray's factor into
        the box, :meth:`clamped`; ``ray``: :meth:`ray` of ``x``, if known); zero inside, or without a box."""
        xm, t = self.ray(x) if ray is None else ray
        if t is None:
            return np.zeros((xm.shape[0], len(cols)))
        d = (xm * (1.0 - t)[:, None] / self.scale) ** 2
        return np.stack([d[:, c].sum(axis=1) for c in cols], axis=1)

    def clamped(self, x: np.ndarray) -> np.ndarray:
        """``(N, m)`` offset-free counts ``x (N, m)``, mapped (:meth:`mapped`) and drawn back along their
        ray from zero into the fitted box (unchanged inside it, or without a box)."""
        x, t = self.ray(x)
        return x if t is None else x * t[:, None]

    def _features_t(self, x: np.ndarray, pairs: np.ndarray, cubes: np.ndarray) -> np.ndarray:
        """``(P + Q, N)`` features of offset-free counts ``x (N, m)`` drawn back into the fitted range."""
        uT = np.ascontiguousarray((self.clamped(x) / self.scale).T)  # (m, N)
        return poly_features_t(uT, pairs, cubes)

    def beyond(self, x: np.ndarray) -> np.ndarray | None:
        """``(N, m)`` ``x_c − x``: where the correction reads offset-free counts ``x (N, m)`` (mapped and
        drawn back into the fitted box; counts), less ``x``; zero inside the box without ``input_map``.
        None when there is no box or no ``edge_matrix``. ``edge_matrix (x_c − x)`` moves the corrected
        model's slopes, beyond the linear fit's, to that point: what they add is read there too."""
        if self.lower is None or self.edge_matrix is None:
            return None
        return self.clamped(x) - (self.mapped(x) if self.edge_mapped else np.asarray(x, dtype=float))

    def terms(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
        """``(features (N, P + Q), beyond (N, m) or None)`` of offset-free counts ``x (N, m)``: what
        :meth:`features` and :meth:`beyond` give, drawn back once."""
        return self.all_terms(x)[:2]

    def map_terms(self, x: np.ndarray) -> np.ndarray | None:
        """``(N, m)`` ``P x − x`` for offset-free counts ``x (N, m)``, less its trained range (``map_lower``,
        ``map_upper``): what ``map_matrix`` reads; None without a ``map_matrix``."""
        if self.map_matrix is None:
            return None
        d = self.mapped(x) - np.asarray(x, dtype=float)
        return d if self.map_lower is None else d - np.clip(d, self.map_lower, self.map_upper)

    def all_terms(self, x: np.ndarray, ray=None):
        """``(features, beyond, tangent)``: :meth:`terms`, and for the ``tangent`` rows what they add
        beyond the box, ``(dphi (N, P + Q), dray (N, m))`` or None: ``coef · dphi + edge_matrix · dray``
        turns the linear fit's slope into the polynomial's tangent along the ray (its squares and
        products grow as ``2/t − 1``, its cubes as ``3/t − 2`` of their value at the edge ``x_c = t P x``,
        first order in ``1/t``), and the corrected model's own slopes. (``map_matrix``'s term:
        :meth:`map_terms`.)"""
        xm, t = self.ray(x) if ray is None else ray
        xc = xm if t is None else xm * t[:, None]
        phi = poly_features_t(np.ascontiguousarray((xc / self.scale).T), self.pairs, self.cubes).T
        if self.lower is None or self.edge_matrix is None:
            return phi, None, None
        extra = None
        if self.tangent is not None and np.any(t < 1):
            r = np.where(t > 0, 1.0 / np.where(t > 0, t, 1.0) - 1.0, 0.0)[:, None]
            P = self.pairs.shape[0]
            dphi = np.empty_like(phi)
            dphi[:, :P] = 2.0 * r * phi[:, :P]
            dphi[:, P:] = 3.0 * r * phi[:, P:]
            extra = (dphi, xm - xc)
        xc -= xm if self.edge_mapped else np.asarray(x, dtype=float)
        return phi, xc, extra

    @property
    def n_features(self) -> int:
        return self.coef.shape[1]

    def features(self, x: np.ndarray) -> np.ndarray:
        """``(N, P + Q)`` features of offset-free counts ``x (N, m)``."""
        return self._features_t(x, self.pairs, self.cubes).T

    def fade(self, x: np.ndarray, ray=None) -> np.ndarray | None:
        """``(N, q)`` the share of each row's correction kept for offset-free counts ``x (N, m)``:
        ``min(1, t · reach)`` (None without a ``reach``)."""
        if self.reach is None:
            return None
        reach = np.broadcast_to(np.asarray(self.reach, dtype=float), (self.coef.shape[0],))
        return np.minimum((self.ray(x) if ray is None else ray)[1][:, None] * reach, 1.0)

    def __call__(self, x: np.ndarray) -> np.ndarray:
        """``(N, q)`` correction for offset-free counts ``x (N, m)``, output units (the edge and map terms included)."""
        out = self._call(x)
        if self.map_matrix is not None:
            out = out + self.map_terms(x) @ self.map_matrix.T
        f = self.fade(x)
        if f is not None and np.any(f < 1):  # past the reach: toward the linear fit (slopes less edge_matrix)
            out = f * out - (1.0 - f) * (np.asarray(x, dtype=float) @ self.edge_matrix.T)
        return out

    def _call(self, x: np.ndarray) -> np.ndarray:
        if self.tangent is not None:
            phi, d, extra = self.all_terms(x)
            out = phi @ self.coef.T
            if d is not None:
                out += d @ self.edge_matrix.T
            if extra is not None:
                out[:, self.tangent] += extra[0] @ self.coef[self.tangent].T + extra[1] @ self.edge_matrix[self.tangent].T
            return out
        used = np.flatnonzero(np.any(self.coef != 0, axis=0))  # rows that keep the affine fit use none
        P = self.pairs.shape[0]
        phi = self._features_t(x, self.pairs[used[used < P]], self.cubes[used[used >= P] - P])
        out = (self.coef[:, used] @ phi).T
        d = self.beyond(x)
        return out if d is None else out + d @ self.edge_matrix.T

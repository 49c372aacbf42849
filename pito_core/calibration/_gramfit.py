"""One pass over the sessions for the linear fit: every sum :meth:`Calibrator._fit` needs.

Per block, the samples are checked (NaN, inf, saturation) and laid out once as
``Z = [1 | counts − c_k | targets of all six faces]`` (``c_k`` a provisional centre of
session ``k``: its tare mean when already known, else its first sample), and ``ZᵀZ``
(one ``syrk``) is added to the Gram matrix of the joint design; each face's own-gauge
design takes the Gram of its own rows and columns. In the same pass: the tare moments
(mean and covariance of the unloaded samples' counts, the reference's covariance at rest),
the Gram of the targets, and a uniform subsample (≤ ``ERROR_MODEL_SAMPLES``) for the error
model. After the pass the design is re-centred exactly on each session's tare mean
(``A_m = A_c M``, ``G_m = Mᵀ G_c M``) and factored by :class:`GramQR`.
"""

from __future__ import annotations

import numpy as np

from ..io import SessionBlock, few_indices as _few
from ._lstsq import GramQR
from ._residuals import ERROR_MODEL_SAMPLES
from ._targets import block_targets

__all__ = ["GramPass"]


class GramPass:
    """Accumulate the one-pass sums of the linear fit (see the module docstring).

    Parameters
    ----------
    n_int : int
        Sessions (offset columns).
    own_faces : tuple of int
        Faces (1..6) whose own-gauge design is needed (empty: none).
    total_samples : int
        Samples of all sessions (sets the error model's subsample stride).
    centers : list of ndarray (36,) or None
        Known tare means (then ``c_k`` is exact and no re-centring is needed).
    joint : bool
        Whether the joint design (all 36 gauges) is needed; without it only the targets' Gram
        and the own-gauge designs are summed.
    """

    def __init__(self, n_int: int, own_faces, total_samples: int, centers=None, joint: bool = True):
        self.n_int = n_int
        self.joint = bool(joint)
        self.G = np.zeros((n_int + 72, n_int + 72))
        self.own = {f: np.zeros((n_int + 12, n_int + 12)) for f in own_faces}
        self.own_rows = {f: 0 for f in own_faces}
        self.n_used = 0
        self.carried_any = np.zeros(6, dtype=bool)
        self.centers = [None] * n_int if centers is None else [np.asarray(c, float) for c in centers]
        self.tare = [dict(n=0, s=np.zeros(36), ss=np.zeros((36, 36)), r=np.zeros(6), rr=np.zeros((6, 6)), rshift=None, xshift=None)
                     for _ in range(n_int)]
        self.stride = max(1, int(total_samples) // ERROR_MODEL_SAMPLES)
        self.sub = [[] for _ in range(n_int)]

    def add(self, k: int, b, mount, output_frame: str, poly=None, poly_center=None):
        """Add block ``b`` of session ``k``; returns ``bad_connected`` (n,) of :func:`block_targets`.

        ``poly`` (a ``PolyAccumulator``) is fed the counts less ``poly_center`` (the tare mean).
        """
        n = b.counts.shape[0]
        if self.centers[k] is None:
            self.centers[k] = b.counts[0].astype(float)
        c = self.centers[k]
        targets, carries, usable, bad = block_targets(b.reference, b.loaded, mount, output_frame)
        if poly is not None:  # before Z exists: the polynomial features are the largest arrays of a block
            poly.add(k, b.counts - poly_center, targets, usable, carries, b.loaded)
        if self.joint:  # Z = [1 | X | T]: the joint design's Gram in one product
            Z = np.empty((n, 73))
            Z[:, 0] = 1.0
            X, T = Z[:, 1:37], Z[:, 37:]
            np.subtract(b.counts, c, out=X)
            T[:] = targets.reshape(n, 36)
        else:  # own-gauge fits only: no 36-gauge Gram
            X, T = b.counts - c, targets.reshape(n, 36)
        unloaded = ~b.loaded.any(axis=1)
        self._tare(k, X[unloaded], b.reference[unloaded])
        first = (-b.start) % self.stride
        # the subsample keeps counts less the centre in float32 (relative rounding 6·10⁻⁸: far below any
        # residual the error model reads), so it costs 200 B a sample
        self.sub[k].append(SessionBlock(b.start + first, X[first::self.stride].astype(np.float32),
                                        b.reference[first::self.stride].copy(), b.loaded[first::self.stride].copy()))
        if not usable.all():
            T[~usable] = 0.0  # (targets are NaN there; a view of them when not joint)
            if self.joint:
                Z[~usable] = 0.0
        self.n_used += int(usable.sum())
        self.carried_any |= (carries & usable[:, None]).any(axis=0)
        if self.joint:
            idx = np.r_[k, self.n_int + np.arange(72)]
            self.G[np.ix_(idx, idx)] += Z.T @ Z
        else:
            self.G[self.n_int + 36 :, self.n_int + 36 :] += T.T @ T
        for f, G in self.own.items():
            rows = np.flatnonzero(usable & (carries[:, f - 1] | unloaded))
            g = slice(6 * (f - 1), 6 * f)
            Zf = np.empty((rows.size, 13))
            Zf[:, 0] = 1.0
            Zf[:, 1:7] = X[rows, g]
            Zf[:, 7:] = T[rows, g]
            idx_f = np.r_[k, self.n_int + np.arange(12)]
            G[np.ix_(idx_f, idx_f)] += Zf.T @ Zf
            self.own_rows[f] += rows.size
        return bad

    def _tare(self, k, x, r) -> None:
        t = self.tare[k]
        if x.shape[0] == 0:
            return
        if t["rshift"] is None:  # sums of squares about the first unloaded sample do not cancel catastrophically
            t["rshift"], t["xshift"] = r[0].copy(), x[0].copy()
        r = r - t["rshift"]
        x = x - t["xshift"]
        t["n"] += x.shape[0]
        t["s"] += x.sum(axis=0)
        t["ss"] += x.T @ x
        t["r"] += r.sum(axis=0)
        t["rr"] += r.T @ r

    def rest_noise(self):
        """``(tare_means, gauge_cov (36, 36), ref_covs, samples at rest)`` as :meth:`Calibrator._rest_noise` gives them."""
        means, covs, ns, ref_covs = [], [], [], []
        for k, t in enumerate(self.tare):
            n = t["n"]
            if n == 0:
                raise ValueError("loaded: the session has no unloaded samples (rows of all False) to take the offsets from")
            mu = t["s"] / n
            cov = t["ss"] / n - np.outer(mu, mu)
            means.append(self.centers[k] + t["xshift"] + mu)
            covs.append(0.5 * (cov + cov.T))
            ns.append(n)
            rm = t["r"] / n
            rc = t["rr"] / n - np.outer(rm, rm)
            ref_covs.append(0.5 * (rc + rc.T) * n / max(n - 1, 1))
        gauge_cov = sum(c * n for c, n in zip(covs, ns)) / max(sum(ns) - self.n_int, 1)
        return means, gauge_cov, ref_covs, ns

    def subsample(self, rows: int = 2048):
        """Per session, a list of :class:`SessionBlock` of every ``stride``-th sample (the error
        model's data), in blocks of at most ``rows`` samples (bounded working memory)."""
        out = []
        for k, blocks in enumerate(self.sub):
            x, r, ld = (np.concatenate([getattr(b, a) for b in blocks]) for a in ("counts", "reference", "loaded"))
            out.append([SessionBlock(blocks[0].start, x[a : a + rows] + self.centers[k], r[a : a + rows], ld[a : a + rows])
                        for a in range(0, x.shape[0], rows)])
        return out

    def target_gram(self) -> np.ndarray:
        """``(36, 36)`` Gram of the targets of all six faces (face-major), unscaled."""
        return self.G[self.n_int + 36 :, self.n_int + 36 :].copy()

    def factors(self, tare_means, joint_faces):
        """``(own, joint)``: :class:`GramQR` of each own-gauge design and of the joint design, centred on the tare means."""
        n_int = self.n_int
        D = np.stack([m - c for m, c in zip(tare_means, self.centers)])  # (n_int, 36) tare mean − provisional centre
        M = np.eye(n_int + 72)
        M[:n_int, n_int : n_int + 36] = -D
        G = M.T @ self.G @ M
        own = {}
        for f, Gf in self.own.items():
            Mf = np.eye(n_int + 12)
            Mf[:n_int, n_int : n_int + 6] = -D[:, 6 * (f - 1) : 6 * f]
            Gf = Mf.T @ Gf @ Mf
            p = n_int + 6
            own[f] = GramQR(Gf[:p, :p], Gf[:p, p:], Gf[p:, p:], self.own_rows[f])
        joint = None
        if joint_faces:
            a = np.r_[np.arange(n_int), n_int + np.arange(36)]
            t = n_int + 36 + np.concatenate([np.arange(6 * (f - 1), 6 * f) for f in joint_faces])
            joint = GramQR(G[np.ix_(a, a)], G[np.ix_(a, t)], G[np.ix_(t, t)], self.n_used)
        return own, joint


def check_connected(bad, k, b, connected_face) -> None:
    """Refuse loads on the connected face under a ``frame`` flange, naming the samples."""
    if bad.any():
        raise ValueError(
            f"sessions[{k}].loaded: the connected face {connected_face} cannot be loaded with "
            f"flange 'frame', yet it is marked loaded at sample indices {_few(np.flatnonzero(bad) + b.start)}"
        )

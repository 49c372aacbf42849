"""One pass over the sessions for the linear fit: every sum :meth:`Calibrator._fit` needs.

Every target is the reference ``r`` (n, 6) mapped by the mount: face ``f``'s target is
``s_f r A_fᵀ`` with ``A_f`` the adjoint to face ``f``'s frame (or the identity in the
reference frame) and ``s_f ∈ {0, ±1}`` set by which face is loaded (the load paths of
``_targets.py``). Within a *load group* (the samples of one session with the same loaded
face, or none) the signs are constant, so the Gram matrix of the joint design
``Z = [1 | counts − c_k | targets of all six faces]`` (73 columns) is ``Eᵀ H E`` with
``H`` the Gram of the group's ``[1 | counts − c_k | r]`` (43 columns) and ``E`` the
group's fixed (43, 73) map: the targets are never laid out per sample. Each cache-sized
chunk of consecutive samples is sorted by group (stable) into one reused buffer, each
group's run adding its ``ZᵀZ`` to its group's ``H`` (the rows are read in order, from
memory once: taking a group's rows across a whole block missed the cache); ``c_k`` is a
provisional centre of session ``k`` (its first sample), subtracted exactly (the counts are
converted to float chunk by chunk, from their stored dtype; integer counts in the ADC range
less ``c_k`` in that dtype). Samples loading two faces or
more (``_targets.py``: not usable) add nothing. Each face's own-gauge design takes its rows
and columns of the groups where the face carries load or none does; without the joint
design (``face_to_face``) a group sums only the gauges of the faces that carry load in it.

In the same pass: the tare moments (mean and covariance of the unloaded samples' counts,
the reference's covariance at rest), which faces carried load, and a uniform subsample
(≤ ``ERROR_MODEL_SAMPLES``) for the error model. After the pass the design is re-centred
exactly on each session's tare mean (``A_m = A_c M``, ``G_m = Mᵀ G_c M``) and factored by
:class:`GramQR`.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg.blas

from ..frames import N_GAUGES
from ..io import SessionBlock, few_indices as _few
from ._lstsq import GramQR
from ._error import ERROR_MODEL_SAMPLES
from ._targets import block_targets

__all__ = ["GramPass", "check_block", "check_connected"]

#: Load groups: 0 unloaded, 1..6 the one loaded face, 7 two faces or more (not usable).
_UNUSABLE = 7
#: Rows per chunk of the sorted block (4096 × 43 × 8 B ≈ 1.4 MB: the chunk stays in cache).
CHUNK = 4096
_ONE, _X, _R = 0, slice(1, 37), slice(37, 43)  # columns of a group's design [1 | counts − c | r]


_ROW_R = np.dtype((np.void, 48))  # one sample's reference (6 float64) as one item: copied without a loop over its 6
_BITS = (1 << np.arange(6)).astype(np.float32)  # a float product (BLAS, exact on 0..63): 2× an integer one
#: Load group of each pattern of loaded faces (bit i-1: face i loaded).
_GROUP_OF_PATTERN = np.array([0 if p == 0 else (p.bit_length() if p & (p - 1) == 0 else _UNUSABLE) for p in range(64)],
                             dtype=np.int8)


def load_groups(loaded: np.ndarray) -> np.ndarray:
    """``(n,) int8``: each sample's load group (see ``_UNUSABLE``) from ``loaded (n, 6) bool``."""
    pattern = np.asarray(loaded, dtype=bool).view(np.uint8).astype(np.float32) @ _BITS
    return np.take(_GROUP_OF_PATTERN, pattern.astype(np.intp))


def group_signs(flange: str, connected_face: int) -> np.ndarray:
    """``(7, 6)`` sign ``s_f`` of face ``f``'s target in each load group (0: the face carries nothing).

    As ``block_targets``: the loaded face carries ``+r``; under a ``face`` flange the connected
    face carries the reaction ``−r`` of a load elsewhere (eq. 6 of the multi-touch paper).
    """
    s = np.zeros((7, 6))
    s[np.arange(1, 7), np.arange(6)] = 1.0
    if flange == "face":
        c = connected_face - 1
        s[1:, c] -= 1.0
        s[1 + c, c] = 1.0
    return s


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
        Whether the joint design (all 36 gauges) is needed; without it a load group sums only
        the gauges of the faces that carry load in it (all that the own-gauge designs read).
    """

    def __init__(self, n_int: int, own_faces, total_samples: int, centers=None, joint: bool = True):
        self.n_int = n_int
        self.joint = bool(joint)
        self.own_faces = tuple(own_faces)
        self.H = np.zeros((n_int, 7, 43, 43))  # per session and load group: Gram of [1 | counts − c | r]
        self._cols = [None] * n_int  # per session and load group: (faces, columns) it sums (None: all 43)
        self._Hp = [None] * n_int  # per session and load group summing fewer columns: their Gram (lower triangle)
        self.maps = [None] * n_int  # per session: (signs (7, 6), A (6, 6, 6)) of its mount and output frame
        self.sizes = np.zeros((n_int, 7), dtype=np.int64)  # samples per session and load group
        self.n_used = 0
        self.carried_any = np.zeros(6, dtype=bool)
        self.centers = [None] * n_int if centers is None else [np.asarray(c, float) for c in centers]
        # per session: unloaded samples and the Gram (lower triangle) of their [1 | counts − c − xshift | r − rshift]
        self.tare = [dict(n=0, G=np.zeros((43, 43)), shift=None) for _ in range(n_int)]
        self.stride = max(1, int(total_samples) // ERROR_MODEL_SAMPLES)
        self.sub = [[] for _ in range(n_int)]
        self._buf = np.empty(CHUNK * 43)  # one chunk of a group's design, rows of up to 43 columns
        self._cbuf = None
        self._rbuf = np.empty((CHUNK, 6))
        self._ones_held = (0, 0)  # rows and width of the designs whose column of ones _buf holds
        self._one = np.ones(CHUNK)
        self._int_center = [None] * n_int  # c_k in the counts' integer dtype, where c_k is their first sample
        self._xc = [None if c is None else np.r_[0.0, c, np.zeros(6)] for c in self.centers]  # c_k in Z's columns
        self._G = self._GG = None

    def add(self, k: int, b, mount, output_frame: str, poly=None, poly_center=None, limits=None):
        """Add block ``b`` of session ``k``; returns ``bad_connected`` (n,): samples loading the
        connected face under a ``frame`` flange (see :func:`check_connected`).

        ``b.counts`` may be in the stored dtype (integer counts are converted chunk by chunk).
        ``poly`` (a ``PolyAccumulator``) is fed the counts less ``poly_center`` (its zero, the session's
        opening tare).
        With ``limits`` (the ADC range ``(lo, hi)``) the block is checked as :func:`check_block`
        does, chunk by chunk as it is read (before anything else reads it when ``poly`` is given).
        """
        span = None if limits is None else limits[1] - limits[0]
        if limits is not None and poly is not None:
            check_block(b, *limits)
            limits = None
        if self.centers[k] is None:
            self.centers[k] = b.counts[0].astype(float)
            self._int_center[k] = b.counts[0].copy() if b.counts.dtype.kind == "i" else None
            self._xc[k] = np.r_[0.0, self.centers[k], np.zeros(6)]
        if self.maps[k] is None:
            A = mount.X_face_ati if output_frame == "face" else np.broadcast_to(np.eye(6), (6, 6, 6))
            self.maps[k] = (group_signs(mount.flange, mount.connected_face), np.array(A))
            self._cols[k] = [None if c.size == 43 else (f, c, self._xc[k][c])
                             for f, c in (self._group_columns(k, g) for g in range(7))]
            self._Hp[k] = [None if p is None else np.zeros((p[1].size, p[1].size)) for p in self._cols[k]]
        self._G = self._GG = None
        group = load_groups(b.loaded)
        if poly is not None:
            self._add_poly(k, b, mount, output_frame, poly, poly_center)
        # integer counts in the ADC range less c_k, their first sample, are exact in their dtype (counts out of
        # the range raise below, whether they fail the chunk's quick test or check_block)
        ci = self._int_center[k]
        if ci is None or span is None or ci.dtype != b.counts.dtype or span > np.iinfo(ci.dtype).max:
            ci = None
        first = (-b.start) % self.stride
        # the subsample keeps counts less the centre in float32 (relative rounding 6·10⁻⁸: far below any
        # residual the error model reads), so it costs 200 B a sample
        self.sub[k].append(SessionBlock(b.start + first, self._less_center(k, b.counts[first::self.stride], ci),
                                        b.reference[first::self.stride].copy(), b.loaded[first::self.stride].copy()))
        sizes = np.bincount(group, minlength=8)[:7]
        c = None if ci is None else np.tile(ci, 8)
        for a in range(0, group.size, CHUNK):
            rows = slice(a, min(a + CHUNK, group.size))
            if not self._add_chunk(k, b, group, rows, limits, c):
                check_block(b, *limits)  # raises, naming the samples (a chunk's sum may overflow where the block's did not)
                self._add_chunk(k, b, group, rows, None, c)
        self.sizes[k] += sizes
        self.n_used += int(sizes.sum())
        self.carried_any |= ((sizes[:, None] > 0) & (self.maps[k][0] != 0)).any(axis=0)
        return b.loaded[:, mount.connected_face - 1] if mount.flange == "frame" else np.zeros(b.loaded.shape[0], dtype=bool)

    def _add_chunk(self, k, b, group, rows: slice, limits=None, int_center=None) -> bool:
        """Add the consecutive samples ``rows`` of block ``b`` to ``H[k, ·]``: sorted by load group
        (stable) into reused buffers, each group's run adding its Gram to its ``H``. Returns False
        if the chunk fails :func:`check_block`'s quick test against ``limits`` (then nothing is added).

        Without the joint design only the gauges of the faces that carry load in a group enter
        (every face's in the unloaded group): the own-gauge designs read nothing else.

        ``int_center`` (``c_k`` repeated 8 times in the counts' integer dtype, or None) is subtracted from
        the sorted integer counts in place (exact in the ADC range: checked here or by :func:`check_block`),
        8 samples a row: 45 against 66 µs a chunk for ``_design``'s rank-1 update, bit for bit the same.
        """
        g = group[rows]
        order = np.argsort(g, kind="stable")
        ends = np.zeros(9, dtype=np.intp)
        np.cumsum(np.bincount(g, minlength=8), out=ends[1:])
        counts = np.take(b.counts[rows], order, axis=0, out=self._counts_buf(b.counts)[: g.size], mode="clip")
        r = np.take(b.reference[rows], order, axis=0, out=self._rbuf[: g.size], mode="clip")
        if limits is not None and not (counts.min() > limits[0] and counts.max() < limits[1] and np.isfinite(r.sum())):
            return False
        if int_center is not None:
            n8 = -(-g.size // 8) * 8  # whole rows of 8 samples (the buffer's rows past g.size are scratch)
            x8 = self._cbuf[:n8].reshape(-1, int_center.size)
            np.subtract(x8, int_center, out=x8)
        centred = int_center is not None
        Z = self._design(k, counts, r, None, centred) if self.joint else None  # every group sums all 43 columns
        for j in range(7):
            sl = slice(ends[j], ends[j + 1])
            if sl.start == sl.stop:
                continue
            part = self._cols[k][j]  # None, or (faces, columns, c_k in them) of a group summing fewer
            Zg = Z[sl] if Z is not None else self._design(k, counts[sl], r[sl], part, centred)
            # a group summing fewer columns keeps their Gram apart (put in H by _group_grams): 35 against 58 µs
            # for 800 rows of 19 columns adding Zg.T @ Zg to H[k, j][np.ix_(columns, columns)]
            _syrk_lower(self.H[k, j] if part is None else self._Hp[k][j], Zg)
            if j == 0:
                self._tare(k, Zg)
        return True

    def _design(self, k, counts, r, part, centred=False) -> np.ndarray:
        """``[1 | counts − c_k | r]`` of the given rows in the reused buffer: all 43 columns (``part``
        None), or only the gauges of ``part``'s faces. Unless ``counts`` are already less ``c_k``
        (``centred``), ``c_k`` is subtracted exactly, in place (one rank-1 update: the rows are short for
        numpy, and a broadcast subtraction into the strided columns is slower)."""
        n = counts.shape[0]
        w = 43 if part is None else part[1].size
        Z = self._buf[: n * w].reshape(n, w)
        if self._ones_held[1] != w or self._ones_held[0] < n:  # the column of ones stays from the last design of this width
            Z[:, _ONE] = 1.0
            self._ones_held = (n, w)
        if part is None:
            np.copyto(Z[:, _X], counts, casting="unsafe")
        for i, f in enumerate(() if part is None else part[0]):
            np.copyto(Z[:, 1 + 6 * i : 7 + 6 * i], counts[:, 6 * f : 6 * f + 6], casting="unsafe")
        np.copyto(Z[:, w - 6 :].view(_ROW_R), r.view(_ROW_R))  # a row of r as one item: 23 against 40 µs a chunk
        if centred:
            return Z
        xc = self._xc[k] if part is None else part[2]
        return scipy.linalg.blas.dger(-1.0, xc, self._one[:n], a=Z.T, overwrite_a=1).T

    def _less_center(self, k, counts, int_center) -> np.ndarray:
        """``counts − c_k`` in float32; less ``int_center`` (``c_k`` in the counts' integer dtype, or None)
        in that dtype, exact, so rounded to float32 alike: 0.28 against 0.68 ms for the 6554 rows of a block
        (the float64 difference and its copy to float32: two passes over short rows)."""
        if int_center is not None:
            return np.subtract(counts, int_center, out=np.empty(counts.shape, np.float32), casting="unsafe")
        return (counts - self.centers[k]).astype(np.float32)

    def _group_columns(self, k, g):
        """``(faces, columns)``: the faces (0-based) whose gauges load group ``g`` of session ``k`` sums,
        and their columns in ``[1 | counts − c | r]`` (43)."""
        faces = np.arange(6) if self.joint or g == 0 else np.flatnonzero(self.maps[k][0][g])
        return faces, np.r_[0, 1 + (6 * faces[:, None] + np.arange(6)).ravel(), 37 + np.arange(6)]

    def _counts_buf(self, counts):
        """A reused (CHUNK, 36) buffer of the counts' dtype."""
        if self._cbuf is None or self._cbuf.dtype != counts.dtype:
            self._cbuf = np.empty((CHUNK, N_GAUGES), dtype=counts.dtype)
        return self._cbuf

    @staticmethod
    def _add_poly(k, b, mount, output_frame, poly, poly_center) -> None:
        def targets_of(rows):
            return block_targets(b.reference[rows], b.loaded[rows], mount, output_frame)[:3]

        poly.add(k, b.counts, poly_center, b.loaded, targets_of)

    def _tare(self, k, Z) -> None:
        """Add the unloaded samples ``Z`` (rows of ``[1 | counts − c | r]``) to session ``k``'s tare sums."""
        t = self.tare[k]
        if Z.shape[0] == 0:
            return
        if t["shift"] is None:  # sums of squares about the first unloaded sample do not cancel catastrophically
            t["shift"] = np.r_[0.0, Z[0, 1:]]
        W = Z - t["shift"]
        t["n"] += W.shape[0]
        _syrk_lower(t["G"], W)  # n, the sums and the sums of products at once (its lower triangle)

    def rest_noise(self):
        """``(tare_means (36,) each, gauge_cov (36, 36) pooled within sessions, ref_covs (6, 6) each, samples at rest each)``:
        the counts' means and covariance at rest (counts, counts²) and the reference's (N², N²·m, N²·m²)."""
        means, covs, ns, ref_covs = [], [], [], []
        for k, t in enumerate(self.tare):
            n = t["n"]
            if n == 0:
                raise ValueError("loaded: the session has no unloaded samples (rows of all False) to take the offsets from")
            G = np.tril(t["G"]) + np.tril(t["G"], -1).T
            mu = G[0, _X] / n
            cov = G[_X, _X] / n - np.outer(mu, mu)
            means.append(self.centers[k] + t["shift"][_X] + mu)
            covs.append(0.5 * (cov + cov.T))
            ns.append(n)
            rm = G[0, _R] / n
            rc = G[_R, _R] / n - np.outer(rm, rm)
            ref_covs.append(0.5 * (rc + rc.T) * n / max(n - 1, 1))
        gauge_cov = sum(c * n for c, n in zip(covs, ns)) / max(sum(ns) - self.n_int, 1)
        return means, gauge_cov, ref_covs, ns

    def subsample(self, rows: int = 2048):
        """Per session, a list of :class:`SessionBlock` of every ``stride``-th sample (the error
        model's data), in blocks of at most ``rows`` samples (bounded working memory)."""
        out = []
        for k, blocks in enumerate(self.sub):
            x, r, ld = (np.concatenate([getattr(b, a) for b in blocks]) for a in ("counts", "reference", "loaded"))
            # float64 first, then the centre added in place: the same sums as x + c (float32 + float64), 0.5
            # against 0.6 ms for 10⁴ samples
            x = x.astype(float)
            x += self.centers[k]
            out.append([SessionBlock(blocks[0].start, x[a : a + rows], r[a : a + rows], ld[a : a + rows])
                        for a in range(0, x.shape[0], rows)])
        return out

    def _group_grams(self):
        """Per session ``k``: ``(7, 73, 73)`` Gram of ``[1 | counts − c_k | targets of all six faces]``
        in each load group, ``Eᵀ H E`` (see the module docstring); None for a session without blocks.
        Made once after the last block (the joint and the own-gauge Grams read it: 0.4 ms a fit)."""
        if self._GG is not None:
            return self._GG
        out = []
        for k in range(self.n_int):
            if self.maps[k] is None:
                out.append(None)
                continue
            for j in range(7):  # the groups hold their lower triangle (_syrk_lower); fewer columns apart
                if self._cols[k][j] is None:
                    self.H[k, j] = np.tril(self.H[k, j]) + np.tril(self.H[k, j], -1).T
                else:
                    c, Hp = self._cols[k][j][1], self._Hp[k][j]
                    self.H[k, j][np.ix_(c, c)] = np.tril(Hp) + np.tril(Hp, -1).T
            signs, A = self.maps[k]
            E = np.zeros((7, 43, 73))
            E[:, :37, :37] = np.eye(37)
            # face f's target is s_f r A_fᵀ: rows of r, columns 6f..6f+5 of the targets
            E[:, 37:, 37:] = (signs[:, :, None, None] * A[None]).transpose(0, 3, 1, 2).reshape(7, 6, 36)
            out.append(np.transpose(E, (0, 2, 1)) @ self.H[k] @ E)
        self._GG = out
        return out

    def _joint_gram(self) -> np.ndarray:
        """``(n_int + 72, n_int + 72)`` Gram of ``[offset column of each session | counts − c | targets]``
        over the usable samples (provisional centres); its counts' columns are complete only with ``joint``."""
        if self._G is None:
            n_int = self.n_int
            self._G = np.zeros((n_int + 72, n_int + 72))
            for k, Gk in enumerate(self._group_grams()):
                if Gk is not None:
                    idx = np.r_[k, n_int + np.arange(72)]
                    self._G[np.ix_(idx, idx)] += Gk.sum(axis=0)
        return self._G

    def _own_grams(self):
        """Per own face ``f``: ``(Gram (n_int + 12)² of [offset columns | its counts − c | its targets], rows)``
        over the samples where it carries load or none is loaded."""
        n_int = self.n_int
        out = {f: [np.zeros((n_int + 12, n_int + 12)), 0] for f in self.own_faces}
        for k, Gk in enumerate(self._group_grams()):
            if Gk is None:
                continue
            signs = self.maps[k][0]
            for f, acc in out.items():
                groups = np.flatnonzero((signs[:, f - 1] != 0) | (np.arange(7) == 0))
                sel = np.r_[0, 1 + np.arange(6 * (f - 1), 6 * f), 37 + np.arange(6 * (f - 1), 6 * f)]
                idx = np.r_[k, n_int + np.arange(12)]
                acc[0][np.ix_(idx, idx)] += Gk[np.ix_(groups, sel, sel)].sum(axis=0)
                acc[1] += int(self.sizes[k, groups].sum())
        return out

    def target_gram(self) -> np.ndarray:
        """``(36, 36)`` Gram of the targets of all six faces (face-major), unscaled."""
        return self._joint_gram()[self.n_int + N_GAUGES :, self.n_int + N_GAUGES :].copy()

    def factors(self, tare_means, joint_faces):
        """``(own, joint)``: :class:`GramQR` of each own-gauge design and of the joint design, centred on the tare means."""
        n_int = self.n_int
        D = np.stack([m - c for m, c in zip(tare_means, self.centers)])  # (n_int, 36) tare mean − provisional centre
        own = {}
        for f, (Gf, rows) in self._own_grams().items():
            Mf = np.eye(n_int + 12)
            Mf[:n_int, n_int : n_int + 6] = -D[:, 6 * (f - 1) : 6 * f]
            Gf = Mf.T @ Gf @ Mf
            p = n_int + 6
            own[f] = GramQR(Gf[:p, :p], Gf[:p, p:], Gf[p:, p:], rows)
        joint = None
        if joint_faces:
            M = np.eye(n_int + 72)
            M[:n_int, n_int : n_int + N_GAUGES] = -D
            G = M.T @ self._joint_gram() @ M
            a = np.r_[np.arange(n_int), n_int + np.arange(N_GAUGES)]
            t = n_int + N_GAUGES + np.concatenate([np.arange(6 * (f - 1), 6 * f) for f in joint_faces])
            joint = GramQR(G[np.ix_(a, a)], G[np.ix_(a, t)], G[np.ix_(t, t)], self.n_used)
        return own, joint


_DSYRK = scipy.linalg.blas.dsyrk


def _syrk_lower(H, Z) -> None:
    """Add ``ZᵀZ`` to the lower triangle of ``H`` (C order) in place: BLAS ``dsyrk`` into ``H``'s
    F-ordered transpose, no temporary (62 against 89 µs for ``H += Z.T @ Z`` on a load group's run of
    600 rows; the whole pass of 10⁵ samples 34.2 against 35.0 ms). The upper triangle is left as it was."""
    # arguments by position, and H's own memory known by its base first: 2.2 against 4.2 µs a call (200 a fit)
    out = _DSYRK(1.0, Z.T, 1.0, H.T, 0, 0, 1)  # alpha, a, beta, c, trans, lower, overwrite_c
    if out.base is not (H if H.base is None else H.base) and not np.shares_memory(out, H):
        H.T[...] = out  # a copy (H not F-contiguous in transpose): keep its sums all the same


def check_connected(bad, k, b, connected_face) -> None:
    """Refuse loads on the connected face under a ``frame`` flange, naming the samples."""
    if bad.any():
        raise ValueError(
            f"sessions[{k}].loaded: the connected face {connected_face} cannot be loaded with "
            f"flange 'frame', yet it is marked loaded at sample indices {_few(np.flatnonzero(bad) + b.start)}"
        )


def check_block(b, lo, hi) -> None:
    """Refuse NaN or inf counts or reference, and counts at or beyond the ADC range ``[lo, hi]``, naming the samples."""
    if b.counts.min() > lo and b.counts.max() < hi and np.isfinite(b.reference.sum()):
        return  # the usual case: three reductions of the block (NaN fails the comparisons)
    bad = ~np.isfinite(b.counts).all(axis=1)
    if bad.any():
        raise ValueError(f"counts: NaN or inf at sample indices {_few(np.flatnonzero(bad) + b.start)}")
    bad = ~np.isfinite(b.reference).all(axis=1)
    if bad.any():
        raise ValueError(f"reference: NaN or inf at sample indices {_few(np.flatnonzero(bad) + b.start)}")
    sat = ((b.counts <= lo) | (b.counts >= hi)).any(axis=1)
    raise ValueError(
        f"counts: saturated (at or beyond the ADC range [{lo}, {hi}]) at sample indices "
        f"{_few(np.flatnonzero(sat) + b.start)}"
    )

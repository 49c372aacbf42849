"""The cube's polynomial correction: accumulated beside the affine fit, chosen by cross-validation.

The design of a method's least-squares problem (offset columns, counts less each
session's tare mean) gains the features of ``_poly.py``: each face's own six gauges,
scaled by their spread, as squares, products and cubes. A face's outputs use its own
face's features; under a ``face`` flange also the squares of the connected face's gauges
(every load passes through it), and the connected face's outputs (the reactions ``−ΣW``)
use every face's, or only its own where it also takes direct loads (``total``: with every
face's, fitted on single-face loads, its reaction to a squeeze, two faces loaded at once, was
up to 5× the linear fit's error). A joint method's free faces' outputs read every
gauge in their linear part (to cancel crosstalk), so the other faces' nonlinearity leaks in:
with outputs in face frames they also take the other free faces' features
(``other_features``). Each face's features are fitted where that face carries (zero
elsewhere) and read from ``P x`` (:func:`input_map`), as ``face_to_face``'s: of the raw counts,
a product of a gauge reading its own load and a neighbour's crosstalk at once has cross terms
no single-face load showed. ``unloaded_frame`` (a
connected face carrying reactions and no direct load): only their cubes, of the counts (a
saturating gauge is odd in its own strain, crosstalk included). Not for ``loaded_frame``:
with a noisy reference its correction fitted the noise. Not the connected
face's products and cubes in a free face's outputs: they see the sum of every load, and a
squeeze (two faces at once, never in the training data) drove them far outside what
single-face loads fitted. Rows
are dealt to folds by loading segment (``_cv.py``) in the same pass as the affine fit's
QR, each fold keeping a Gram matrix; the model is chosen per face and per output group
(forces, torques) from those, without another pass, and the rows the correction does not
win keep the affine fit's.
"""

from __future__ import annotations

import numpy as np

from ..defaults import FULL_SCALE_FACE
from ..frames import FACES, N_GAUGES
from ._lstsq import RANK_RTOL
from ._cv import ALPHAS, N_FOLDS, N_SE_SESSION, FoldedGram, MAX_SEGMENT_FRACTION, Problem, SegmentCounter, pattern_caps, \
    choose_extension, choose_model, chosen_error, cross_validate, extension_errors, extension_kind, fold_bounds, \
    held_out_sse, solve_problem, tested_reach, trust_polynomial
from ._gramfit import load_groups
from ._poly import MAX_ROWS, PolyCorrection, poly_features_t, poly_terms

__all__ = ["PolyAccumulator", "FULL_SCALE_WEIGHT", "mixed_offsets"]

#: Outputs are weighed by 1 / full scale in the model choice: ``[fx … tz]`` in 1/N and 1/(N·m).
FULL_SCALE_WEIGHT = 1.0 / np.asarray(FULL_SCALE_FACE)
#: Rows whose features are built at once (8192 × 235 columns × 8 B ≈ 15 MB).
CHUNK = 8192
#: The extension beyond the trained range is chosen on at most about this many of them (``_cv.extension_errors``).
MAX_EXTENSION_ROWS = 1 << 13
_PAIRS, _CUBES = poly_terms([range(6 * (f - 1), 6 * f) for f in FACES])
_N_PAIRS = _PAIRS.shape[0] // 6  # 21 per face
_PAIRS6, _CUBES6 = poly_terms([range(6)])  # one face's own, in the order of face_features
_FEATURE_FACE = np.r_[_PAIRS[:, 0] // 6, _CUBES // 6]  # the face (0..5) of each of the 162 features

#: Singular values of a Gram below this fraction of the largest are dropped in :func:`input_map`.
INPUT_MAP_RTOL = 1e-10


def face_features(f: int) -> np.ndarray:
    """Indices (into the 162 features) of face ``f``'s own squares, products and cubes."""
    return np.r_[np.arange(_N_PAIRS * (f - 1), _N_PAIRS * f), _PAIRS.shape[0] + np.arange(6 * (f - 1), 6 * f)]


def connected_squares(f: int) -> np.ndarray:
    """Indices (into the 162 features) of the squares ``u_i²`` of face ``f``'s six gauges."""
    own = face_features(f)[:_N_PAIRS]
    return own[_PAIRS[own, 0] == _PAIRS[own, 1]]


class PolyAccumulator:
    """Per-fold Gram matrices of ``[offsets | u | φ(u) | targets]`` for one method's fit.

    Parameters
    ----------
    own : bool
        The method fits each face from its own gauges (``face_to_face``): one problem per face,
        on the rows that load it (or none).
    out_faces : tuple of int
        Output faces of a joint fit (ignored for ``own``).
    n_int : int
        Sessions (offset columns).
    scale : ndarray, shape (36,)
        Counts per unit of ``u`` while the rows are added (any positive scale: the Grams are put in
        the final one, each gauge's RMS about its zero over the fitted rows, before the fit).
    reaction_faces : set of int
        Connected faces under a ``face`` flange.
    session_lengths : list of int
    other_features : {None, "cubes", "all"}
        A joint fit's free faces' outputs also take the other free faces' cubes (of the counts), or all
        their features, each face's fitted where it carries and read from ``P x`` (:func:`correction`).
    reaction_features : {"all", "own"}
        A connected face's outputs take every face's features, or its own only.
    session_loaded : list of array-like, shape (N_k, 6), optional
        Each session's ``loaded`` (arrays or lazy datasets, read once in blocks): each load pattern is
        cut into at least ``_cv.MIN_PIECES`` segments (:func:`~._cv.pattern_caps`); else by length only.
    """

    def __init__(self, own, out_faces, n_int, scale, reaction_faces, session_lengths, n_folds=N_FOLDS,
                 other_features=None, session_loaded=None, reaction_features="all"):
        if reaction_features not in ("all", "own"):
            raise ValueError(f"reaction_features: expected 'all' or 'own', got {reaction_features!r}")
        self.own, self.n_int, self.scale, self.K = own, n_int, scale, n_folds
        self.reaction_features = reaction_features
        self.other_features = None if own else other_features
        self.mapped = self.other_features == "all"  # features where a face carries, read from P x
        self.out_faces = tuple(out_faces)
        self.reaction_faces = set(reaction_faces)
        self.counter = SegmentCounter(max(1, int(np.ceil(max(session_lengths) * MAX_SEGMENT_FRACTION))))
        self.caps = None if session_loaded is None else [pattern_caps(L, self.counter.max_len) for L in session_loaded]
        self.stride = max(1, int(np.ceil(sum(session_lengths) / MAX_ROWS)))
        # range of each scaled channel over the usable rows, and of each face's targets (output frame) over
        # the fitted ones: the correction's two boxes (_poly.py)
        self.lower, self.upper = np.full(N_GAUGES, np.inf), np.full(N_GAUGES, -np.inf)
        self.target_lo, self.target_hi = np.zeros((6, 6)), np.zeros((6, 6))
        # ``own``: Gram of the counts in each load group (0 none, 1..6 the face loaded alone) and the faces
        # that carry in it (a ``face`` flange's connected face carries every load): the input map
        self.count_grams = np.zeros((7, N_GAUGES, N_GAUGES)) if own or self.mapped else None
        self.group_carries = np.zeros((7, 6), dtype=bool)
        self._ss, self._ss_rows, self._final = np.zeros(N_GAUGES), 0, False  # the final scale's sums
        self._session, self._seen = None, 0
        # every ``_keep``-th fitted row (float32, ≤ MAX_EXTENSION_ROWS): the extension's choice refits on them
        self._rows, self._kept = [], 0
        self._keep = max(1, int(np.ceil(sum(session_lengths) / self.stride / MAX_EXTENSION_ROWS)))
        self.reach = None  # after fit: how far beyond the box the extension was tested (_cv.tested_reach)
        self.tangent = None  # (6F,) bool after fit: rows extrapolated along the polynomial's tangent
        self.fade = None  # (6F,) bool after fit: rows that fade to the linear fit from the box's edge on (choose_extension)
        self.box_scale = None  # (36,) after fit: the box's factor per gauge (the reach, where the polynomial is trusted)
        self.trusted = None  # (6F,) bool after fit: rows whose polynomial is trusted out to the reach (trust_polynomial)
        self.sample = None  # (x, usable, carries, loaded) of the kept rows, after fit
        self.beyond_moment = None  # (F, 6, 6) after fit: the chosen extension's held-out error moment per unit of b
        if own:
            self.acc = {f: FoldedGram(n_int + 6 + 27, 6, n_folds) for f in FACES}
        else:
            self.acc = FoldedGram(n_int + N_GAUGES + 162, 6 * len(self.out_faces), n_folds)

    def add(self, k, counts, center, loaded, targets_of):
        """Rows of session ``k``: ``counts (n, 36)`` as stored, ``center (36,)`` its zero (opening tare),
        ``loaded (n, 6)``. ``targets_of(rows)`` (a slice) gives ``(targets (r, 6, 6), carries (r, 6),
        usable (r,))`` of the rows it keeps, as :func:`~._targets.block_targets` does: only those
        are worked out (one sample in ``stride``), the channels' range and the segments from every row.
        """
        fold = self.counter.ids(loaded, self._session != k, None if self.caps is None else self.caps[k]) % self.K
        self._session = k
        usable = np.count_nonzero(loaded, axis=1) <= 1  # as block_targets: unloaded or one face loaded
        if usable.any():  # (c − center) / scale is monotone in c: the extremes of the counts give those of u
            c = counts if usable.all() else counts[usable]
            self.lower = np.minimum(self.lower, (c.min(axis=0) - center) / self.scale)
            self.upper = np.maximum(self.upper, (c.max(axis=0) - center) / self.scale)
        rows = slice(None)
        if self.stride > 1:  # every stride-th sample of the sessions
            rows = slice((-self._seen) % self.stride, None, self.stride)
            self._seen += counts.shape[0]
        targets, carries, usable = targets_of(rows)
        x, loaded, fold = counts[rows] - center, loaded[rows], fold[rows]
        if usable.any():
            t = targets[usable]
            self.target_lo = np.minimum(self.target_lo, t.min(axis=0))
            self.target_hi = np.maximum(self.target_hi, t.max(axis=0))
        if self.count_grams is not None:
            group = load_groups(loaded)
            for j in np.unique(group[group < 7]):
                xg = x[group == j]
                self.count_grams[j] += xg.T @ xg
                self.group_carries[j] |= carries[group == j].any(axis=0)
        keep = slice((-self._kept) % self._keep, None, self._keep)
        self._kept += x.shape[0]
        self._rows.append((np.full(x[keep].shape[0], k), x[keep].astype(np.float32), targets[keep].astype(np.float32),
                           usable[keep], carries[keep], loaded[keep]))
        self._ss += np.einsum("ij,ij->j", x, x)
        self._ss_rows += x.shape[0]
        for a in range(0, x.shape[0], CHUNK):  # bounded memory: features of CHUNK rows at a time
            sl = slice(a, a + CHUNK)
            self._add(k, x[sl], targets[sl], usable[sl], carries[sl], loaded[sl], fold[sl])

    def _design(self, k, x, cols, pairs, cubes, targets):
        """``ZT (p + q, n)``: ``[offsets | u | φ(u) | targets]`` of the rows, as columns."""
        n_int, nu = self.n_int, cols.size
        uT = x.T[cols] / self.scale[cols, None]
        p = n_int + nu + pairs.shape[0] + cubes.size
        ZT = np.zeros((p + targets.shape[1], x.shape[0]))
        ZT[k] = 1.0
        ZT[n_int : n_int + nu] = uT
        poly_features_t(uT, pairs, cubes, out=ZT[n_int + nu : p])
        ZT[p:] = targets.T
        return ZT

    def _add(self, k, x, targets, usable, carries, loaded, fold):
        if self.own:
            unloaded = ~loaded.any(axis=1)
            for f, acc in self.acc.items():
                idx = np.flatnonzero(usable & (carries[:, f - 1] | unloaded))
                order, bounds = fold_bounds(fold[idx], self.K)
                idx = idx[order]
                ZT = self._design(k, x[idx], np.arange(6 * (f - 1), 6 * f), _PAIRS6, _CUBES6, targets[idx, f - 1])
                acc.add_sorted(ZT, bounds)
        else:
            idx = np.flatnonzero(usable)
            order, bounds = fold_bounds(fold[idx], self.K)
            idx = idx[order]
            t = targets[idx][:, [f - 1 for f in self.out_faces], :].reshape(idx.size, -1)
            ZT = self._design(k, x[idx], np.arange(N_GAUGES), _PAIRS, _CUBES, t)
            if self.mapped:  # a face's features where it carries: what P x keeps of it
                ZT[self.n_int + N_GAUGES : self.n_int + N_GAUGES + 162] *= carries[idx][:, _FEATURE_FACE].T
            self.acc.add_sorted(ZT, bounds)

    def _rescale(self) -> None:
        """Put the Grams, the channels' range and ``scale`` in the final scale: each gauge's RMS about its zero over
        the fitted rows (``u`` to unit spread, which the ridge's footing needs). Its features are monomials,
        so a scale per gauge scales each design column: ``G → d G d``, exact (to rounding) whatever scale
        the rows were added in (the first block's: the tare's noise alone where the session opens with a
        tare longer than a block)."""
        if self._final:
            return
        self._final = True
        rms = np.sqrt(self._ss / max(self._ss_rows, 1))
        new = np.where(rms > 0, rms, self.scale)
        r = self.scale / new  # u in the new scale = u in the old × r

        def factors(cols, pairs, cubes, q):
            rc = r[cols]
            return np.r_[np.ones(self.n_int), rc, rc[pairs[:, 0]] * rc[pairs[:, 1]], rc[cubes] ** 3, np.ones(q)]

        if self.own:
            for f, acc in self.acc.items():
                d = factors(np.arange(6 * (f - 1), 6 * f), _PAIRS6, _CUBES6, acc.q)
                acc.gram *= np.outer(d, d)
        else:
            d = factors(np.arange(N_GAUGES), _PAIRS, _CUBES, self.acc.q)
            self.acc.gram *= np.outer(d, d)
        self.lower, self.upper, self.scale = self.lower * r, self.upper * r, new

    def rows_of(self, f) -> int:
        """Rows (samples) of face ``f``'s problem (over every sample: the fitted ones × stride)."""
        return (self.acc[f].n_rows if self.own else self.acc.n_rows) * self.stride

    def _features_of(self, f) -> np.ndarray:
        """Feature indices of output face ``f`` (joint methods): every face's for a connected face (its own
        only, ``reaction_features="own"``), else
        ``f``'s own, the connected faces' squares and (``other_features``) the other free faces' features
        (``"all"``) or cubes (``"cubes"``)."""
        if f in self.reaction_faces:
            return face_features(f) if self.reaction_features == "own" else np.arange(162)
        extra = [connected_squares(c) for c in self.reaction_faces]
        if self.other_features:
            start = 0 if self.mapped else _N_PAIRS
            extra += [face_features(g)[start:] for g in FACES if g != f and g not in self.reaction_faces]
        return np.unique(np.concatenate([face_features(f)] + extra))

    def problems(self, out_faces, rank_a=None):
        """``[(FoldedGram, [Problem …], [face …])]`` of the fit."""
        n_int = self.n_int
        if self.own:
            return [(self.acc[f], [Problem(np.arange(n_int + 6), np.arange(n_int + 6, n_int + 33), np.arange(6),
                                           FULL_SCALE_WEIGHT, rank_a)], [f]) for f in out_faces]
        probs = [Problem(np.arange(n_int + N_GAUGES), n_int + N_GAUGES + self._features_of(f), np.arange(6 * k, 6 * k + 6),
                         FULL_SCALE_WEIGHT, rank_a) for k, f in enumerate(self.out_faces)]
        return [(self.acc, probs, list(self.out_faces))]

    def fit(self, out_faces, requested, linear_matrix, rank_a=None, alphas=ALPHAS, group=3):
        """Choose the model per output group; returns ``(ModelChoice, solution or None)``.

        The solution (for ``poly``) is ``(C (6F, 36), B (n_int, 6F), D (6F, 162), E2 (6F,))``: slopes
        per count, session intercepts, feature coefficients, and the fit's residual sum of squares;
        rows that keep the affine fit are ``linear_matrix``'s, with no feature and ``E2`` NaN. ``E2``
        is scaled from the fitted samples to all (× ``stride``).
        """
        self._rescale()
        parts = self.problems(out_faces, rank_a)
        results = [(cross_validate(acc, probs, alphas), [p.weight for p in probs]) for acc, probs, _ in parts]
        choice = choose_model(results, requested, self.counter.count, group, N_SE_SESSION)
        if choice.name != "poly":
            return choice, None
        F = len(out_faces)
        row = {f: k for k, f in enumerate(out_faces)}
        row_alpha = np.array([np.nan if a is None else a for a in choice.row_alpha])
        C, B, D, E2 = linear_matrix.copy(), np.zeros((self.n_int, 6 * F)), np.zeros((6 * F, 162)), np.full(6 * F, np.nan)
        n_int = self.n_int
        for acc, probs, faces in parts:
            for pr, f in zip(probs, faces):
                ra = row_alpha[6 * row[f] : 6 * row[f] + 6]
                use = np.isfinite(ra)
                if not use.any():
                    continue
                X = np.zeros((pr.a.size + pr.b.size, 6))
                levels = np.unique(ra[use])
                for a, Xa in zip(levels, solve_problem(acc, pr, levels)):
                    X[:, ra == a] = Xa[:, ra == a]
                ri = 6 * row[f] + np.flatnonzero(use)
                lin = np.arange(6 * (f - 1), 6 * f) if self.own else np.arange(N_GAUGES)
                C[np.ix_(ri, lin)] = (X[n_int : n_int + lin.size, use] / self.scale[lin, None]).T
                B[:, ri] = X[:n_int, use]
                feats = face_features(f) if self.own else self._features_of(f)
                D[np.ix_(ri, feats)] = X[n_int + lin.size :, use].T
                E2[ri] = self.stride * held_out_sse(acc.total(), acc.p, pr, X)[use]  # over every sample
        self.tangent = self._extension(parts, row, row_alpha, group)
        return choice, (C, B, D, E2)

    def _extension(self, parts, row, row_alpha, group) -> np.ndarray:
        """``(6F,)`` bool: the corrected output groups that extrapolate along the polynomial's tangent, the rest
        along the linear fit's slope; sets ``fade``, the groups that fade to the linear fit from the box's edge on
        (:func:`~._cv.extension_errors` and :func:`~._cv.choose_extension` on the fitted rows)."""
        out, fade = np.zeros(row_alpha.size, dtype=bool), np.zeros(row_alpha.size, dtype=bool)
        if not self._rows:
            return out
        k, x, targets, usable, carries, loaded = (np.concatenate(a) for a in zip(*self._rows))
        self._rows = []
        self.sample = (x, usable, carries, loaded)  # for the input map's trained range (:func:`correction`)
        u_all, targets = x / self.scale, targets.astype(float)
        n_int = self.n_int
        self.box_scale, self.trusted = np.ones(N_GAUGES), np.zeros(row_alpha.size, dtype=bool)
        beyond = []
        for acc, probs, faces in parts:
            shared = None if self.own else {}  # a joint fit's faces share their rows (extension_errors)
            errs, part_rows = [0.0, 0.0], []
            for pr, f in zip(probs, faces):
                ra = row_alpha[6 * row[f] : 6 * row[f] + 6]
                if not np.isfinite(ra).any():
                    continue
                if self.own:
                    idx = np.flatnonzero(usable & (carries[:, f - 1] | ~loaded.any(axis=1)))
                    cols, pairs, cubes, y = np.arange(6 * (f - 1), 6 * f), _PAIRS6, _CUBES6, targets[idx, f - 1]
                else:
                    idx = np.flatnonzero(usable)
                    cols, pairs, cubes = np.arange(N_GAUGES), _PAIRS, _CUBES
                    y = targets[idx][:, [g - 1 for g in self.out_faces], :].reshape(idx.size, -1)
                kk, cc = k[idx], carries[idx]

                def build(i, v, kk=kk, y=y, cols=cols, pairs=pairs, cubes=cubes, cc=cc):
                    nu = cols.size
                    ZT = np.zeros((acc.p + acc.q, i.size))
                    ZT[kk[i], np.arange(i.size)] = 1.0
                    vT = np.ascontiguousarray(v.T)
                    ZT[n_int : n_int + nu] = vT
                    poly_features_t(vT, pairs, cubes, out=ZT[n_int + nu : acc.p])
                    if self.mapped:
                        ZT[n_int + nu : acc.p] *= cc[i][:, _FEATURE_FACE].T
                    ZT[acc.p :] = y[i].T
                    return ZT

                u = u_all[idx][:, cols]
                cube_cols = acc.p - cubes.size + np.arange(cubes.size)
                cache = {} if shared is None else shared
                face_cols = None if self.own else np.arange(6 * (f - 1), 6 * f)
                loads = carries[idx, f - 1] if self.own else loaded[idx].any(axis=1)  # the box is shrunk on loads
                errors = extension_errors(build, acc.p, u, self.lower[cols], self.upper[cols], pr, ra, cube_cols,
                                          face_cols, cache, loads)
                rows = slice(6 * row[f], 6 * row[f] + 6)
                out[rows], fade[rows] = choose_extension(errors, ra, 6 if group == 6 else 3)
                if errors is not None:
                    beyond.append((row[f], rows, errors, np.isfinite(ra)))
                if "reach" not in cache:  # a joint fit's faces share it (the same rows and box)
                    cache["reach"] = tested_reach(u, self.lower[cols], self.upper[cols], loads)
                reach = cache["reach"]
                self.reach = max(self.reach or 1.0, reach)
                c, pl = chosen_error(errors, ra, out[rows], fade[rows])
                if self.own:  # a face's correction reads its own gauges: its box alone
                    if reach > 1.0 and trust_polynomial(c, pl):
                        self.box_scale[cols], self.trusted[rows] = reach, True
                else:
                    errs[0], errs[1], part_rows = errs[0] + c, errs[1] + pl, part_rows + [rows]
            if not self.own and self.reach is not None and self.reach > 1.0 and trust_polynomial(*errs):
                self.box_scale[:] = self.reach  # a joint fit's faces read every gauge: one box
                for rows in part_rows:
                    self.trusted[rows] = True
        self.fade = fade
        self.beyond_moment = np.zeros((row_alpha.size // 6, 6, 6))
        for j, rows, errors, use in beyond:  # the chosen extension's errors per unit of b (_error.py), output frame
            kinds = [extension_kind(*k) for k in zip(out[rows], fade[rows], self.trusted[rows])]
            e = np.stack([errors["residuals"][k][:, i] for i, k in enumerate(kinds)], axis=1) * use
            b = float(errors["beyond"].sum())
            if b > 0:
                self.beyond_moment[j] = e.T @ e / b
        return out


def input_map(count_grams: np.ndarray, group_carries: np.ndarray) -> np.ndarray:
    """``P (36, 36)``: each face's gauges less what they read of the other faces' loads (``face_to_face``).

    From the Grams of the offset-free counts per load group ``count_grams (7, 36, 36)`` (0: none
    loaded, ``f``: face ``f`` alone) and the faces that carry in each ``group_carries (7, 6)``. For face
    ``f``, ``B`` predicts the other gauges ``x_o`` (of the faces that carry nothing when ``f`` is loaded:
    not a ``face`` flange's connected face, whose reaction to ``f``'s load bends its gauges too) from its
    own ``x_f`` with ``f`` loaded alone; what is left, ``r = x_o − B x_f``, is the other faces' loads;
    ``A`` regresses ``x_f`` on ``r`` in the groups
    where ``f`` carries nothing (its crosstalk; none but the rest for a ``face`` flange's connected face,
    which carries every load: ``A ≈ 0``). ``P x`` has ``x_f − A r`` in face ``f``'s gauges: its own
    loads' reading alone (``x_f`` when only ``f`` is loaded, as in the rows its correction was fitted on).
    """
    P = np.eye(N_GAUGES)
    for f in FACES:
        own = np.arange(6 * (f - 1), 6 * f)
        quiet = [g for g in FACES if g != f and not group_carries[f, g - 1]]
        o = np.concatenate([np.arange(6 * (g - 1), 6 * g) for g in quiet]) if quiet else np.zeros(0, dtype=np.int64)
        if o.size == 0:
            continue
        G = count_grams[f]
        none = (np.arange(7) != f) & ~group_carries[:, f - 1]  # groups where f carries nothing
        none[0] = False
        if not np.any(np.diag(G)) or not np.any(np.trace(count_grams[none], axis1=1, axis2=2)):
            continue  # f never loaded alone, or never idle beside another load: nothing to learn
        none[0] = True
        B = np.linalg.lstsq(G[np.ix_(own, own)], G[np.ix_(own, o)], rcond=INPUT_MAP_RTOL)[0].T  # (30, 6)
        T = np.zeros((o.size, N_GAUGES))
        T[:, o] = np.eye(o.size)
        T[:, own] = -B
        S = count_grams[none].sum(axis=0)
        A = np.linalg.lstsq(T @ S @ T.T, T @ S[:, own], rcond=INPUT_MAP_RTOL)[0].T  # (6, 30)
        P[own] -= A @ T
    return P


def correction(poly: PolyAccumulator, D, edge_matrix, linear_matrix, out_faces, corrected=None) -> PolyCorrection:
    """The calibration's correction from the fitted feature coefficients ``D (6F, 162)``: inside the
    range of the gauges the accumulator ``poly`` saw, with the linear fit's slope beyond
    (``edge_matrix (6F, 36)``: the corrected slopes less the linear fit's; ``_poly.py``).

    For ``face_to_face`` it reads through :func:`input_map`, the ``corrected (6F,)`` rows (default:
    those with a feature) wholly, their linear part too (``map_matrix``: a squeeze's crosstalk on a
    face's own gauges, which its single-face training never saw, is taken out), and also inside the
    range of the training loads in the linear fit's coordinates (``linear_matrix (6F, 36)``'s output
    rows; axes that never carried load left out) is inside. Not for the joint methods: trusted out to that
    box, their corrections lost to the linear fit on fresh sessions (docs/calibration/coverage.md)."""
    seen = poly.lower <= poly.upper
    box = 1.0 if poly.box_scale is None else poly.box_scale  # the box enlarged to the reach where it is trusted
    lower, upper = np.where(seen, poly.lower * box, 0.0), np.where(seen, poly.upper * box, 0.0)
    if not poly.own:
        if not poly.mapped:
            return PolyCorrection(poly.scale, _PAIRS, _CUBES, D, lower, upper, edge_matrix, tangent=poly.tangent,
                                  reach=_row_reach(poly))
        return PolyCorrection(poly.scale, _PAIRS, _CUBES, D, lower, upper, edge_matrix, tangent=poly.tangent, reach=_row_reach(poly),
                              input_map=input_map(poly.count_grams, poly.group_carries), edge_mapped=True)
    idx = [f - 1 for f in out_faces]
    lo, hi = poly.target_lo[idx].reshape(-1), poly.target_hi[idx].reshape(-1)
    keep = hi > lo
    rows = np.any(D != 0, axis=1) if corrected is None else np.asarray(corrected, dtype=bool)
    P = input_map(poly.count_grams, poly.group_carries)
    map_lo, map_hi = map_range(P, poly.sample)
    return PolyCorrection(poly.scale, _PAIRS, _CUBES, D, lower, upper, edge_matrix, domain=linear_matrix[keep],
                          domain_lower=lo[keep], domain_upper=hi[keep], input_map=P, tangent=poly.tangent, reach=_row_reach(poly),
                          map_matrix=linear_matrix * rows[:, None], map_lower=map_lo, map_upper=map_hi)


def _row_reach(poly: PolyAccumulator):
    """The correction's ``reach``: the one tested, or ``(6F,)`` with 1 on the rows that fade from the box's edge on
    (their extension lost to the linear fit, or their box is enlarged to the reach: ``trusted``)."""
    flags = [a for a in (poly.fade, poly.trusted) if a is not None]  # trusted: the box enlarged to the reach
    one = np.logical_or.reduce(flags) if flags else None
    if poly.reach is None or one is None or not one.any():
        return poly.reach
    return np.where(one, 1.0, poly.reach)


def map_range(P: np.ndarray, sample) -> tuple[np.ndarray, np.ndarray]:
    """``(lower, upper) (36,)``: each gauge's range of ``P x − x`` over the rows its face's correction was
    fitted on (the face loaded alone, or none), from the kept ``sample`` (``(x, usable, carries, loaded)``;
    None: zeros). There ``P x − x`` is what the map misreads of the face's own load (the crosstalk's
    nonlinearity, noise): only what lies beyond it is another face's load."""
    lower, upper = np.zeros(N_GAUGES), np.zeros(N_GAUGES)
    if sample is None:
        return lower, upper
    x, usable, carries, loaded = sample
    x = np.asarray(x, dtype=float)
    unloaded = ~loaded.any(axis=1)
    for f in FACES:
        idx = np.flatnonzero(usable & (carries[:, f - 1] | unloaded))
        if idx.size:
            own = np.arange(6 * (f - 1), 6 * f)
            d = x[idx] @ P[own].T - x[idx][:, own]
            lower[own], upper[own] = np.minimum(d.min(axis=0), 0.0), np.maximum(d.max(axis=0), 0.0)
    return lower, upper


def mixed_offsets(C, linear_matrix, row_alpha, tare_means, linear_offsets) -> list:
    """Each session's zero-load counts (36,) for a calibration whose rows mix both models.

    Rows with the correction take the tare mean as their zero (their intercept, the model's
    wrench at rest, is the error at the unloaded samples); rows that keep the affine fit
    need its fitted offset, ``C_r (m − o) = b_r``. One offset serves both: ``m − δ`` with
    the least ``δ`` (in the full-scale-weighted rows) such that ``C δ`` is the affine rows'
    intercepts and zero on the corrected rows (exact where those rows leave room; the
    features move by ``δ / scale``, a fraction of the gauge noise).
    """
    linear = np.array([a is None for a in row_alpha])
    w = np.tile(FULL_SCALE_WEIGHT, C.shape[0] // 6)
    out = []
    for m, o in zip(tare_means, linear_offsets):
        rhs = np.where(linear, linear_matrix @ (m - o), 0.0)
        delta = np.linalg.lstsq(C * w[:, None], rhs * w, rcond=RANK_RTOL)[0]
        out.append(m - delta)
    return out

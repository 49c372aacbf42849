"""The one least-squares core behind the five methods: ``calibrate`` and ``Calibrator``.

Every method solves the papers' ``C = W S⁺`` as an affine least-squares problem: the
counts ``S`` (less each session's tare mean, an exact re-centring) beside one offset
column per session, the unloaded (tare) samples included as zero-wrench rows, solved by
streamed QR (``_lstsq.py``). The offsets are therefore fitted from every sample, not
from the tare samples alone, and the default result *is* the plain affine least-squares
fit. Only where the loads leave directions of the counts unexcited (a ``face`` or
``frame`` flange: 30 of 36) and the caller asks for it (``prior="own_gauge"``) are those
directions filled from each face's own-gauge fit (docs/calibration.md).
"""

from __future__ import annotations

import datetime as _dt
import functools
import warnings
from dataclasses import dataclass, field

import numpy as np
from threadpoolctl import ThreadpoolController

from ..defaults import FULL_SCALE_FACE
from ..frames import FACES, N_GAUGES
from ._calibration import Calibration
from ._coverage import measured_directions
from ._cv import MODELS, ModelChoice
from ._gramfit import GramPass, check_block, check_connected
from ._lstsq import RANK_RTOL, StreamedQR
from ._nlfit import PolyAccumulator, correction as poly_correction, mixed_offsets
from ._methods import MethodSpec, get_method
from ..io import CalibrationSession
from ._targets import MountGeometry, block_targets
from ._error import CalibrationCovariance, CovarianceGroup, fit_error_model, reference_noise_at_rest

__all__ = ["calibrate", "Calibrator", "RankDeficientWarning", "RankDeficientError", "ExcitationError", "session_offsets", "AXES", "PRIORS",
           "NET_LOAD_MEASURED", "NET_LOAD_PRIOR", "NET_LOAD_UNIDENTIFIED"]

AXES = ("fx", "fy", "fz", "tx", "ty", "tz")

#: A face's loads must excite each wrench direction with at least this fraction of
#: the strongest direction (scaled: forces by 15 N, torques by 0.1 N·m full scale).
EXCITATION_RTOL = 1e-3
#: Full-scale loads used to put forces and torques on one footing (N, N·m).
FULL_SCALE = np.array(FULL_SCALE_FACE)
_GRAM_SCALE = np.outer(np.tile(1 / FULL_SCALE, 6), np.tile(1 / FULL_SCALE, 6))
#: What may fill the load directions the data leave unexcited: nothing (the papers' plain
#: least squares) or each face's own-gauge fit.
PRIORS = (None, "own_gauge")
#: The polynomial correction's zero: the mean counts of a session's first stretch at rest (the
#: tare it opens with), up to this many samples. Its features are monomials of counts less that zero, so it
#: is read before the fit's one pass; the mean of every sample at rest took a pass of its own (13.1
#: of 36.2 s of a 10⁷-sample fit from a file).
POLY_TARE_SAMPLES = 4096
#: ``meta["net_load"]``, in words for the command line and the app.
NET_LOAD_MEASURED = "measured"
NET_LOAD_PRIOR = "not measured: from the faces' own-gauge fits"
NET_LOAD_UNIDENTIFIED = "not measured: not identified (plain least squares)"
#: Flange of the extra sessions that measure the net-load directions for face-frame methods.
NET_LOAD_FLANGE = "frame_hole"


@functools.lru_cache(maxsize=1)
def _threadpools() -> ThreadpoolController:
    """The BLAS/OpenMP pools loaded (found once: the search costs ~1–3 ms, a fit's limit then ~20 µs)."""
    return ThreadpoolController()


class RankDeficientWarning(UserWarning):
    """A face's loads did not excite every wrench direction; those directions are not calibrated."""


class RankDeficientError(ValueError):
    """The data do not determine the fit (``allow_rank_deficient=True`` gives a minimum-norm fit).

    Attributes
    ----------
    faces : tuple of int
        The faces (1..6) whose part of the fit is not determined.
    """

    def __init__(self, message: str, faces=()):
        super().__init__(message)
        self.faces = tuple(int(f) for f in faces)


class ExcitationError(RankDeficientError):
    """A face's loads did not excite every wrench direction.

    Attributes
    ----------
    faces : tuple of int
        The faces (1..6) with unexcited directions.
    directions : dict of int to list of str
        Per face, the unexcited wrench directions in words (e.g. ``"tz"``; "all six
        directions" when the face carried no load).
    """

    def __init__(self, message: str, directions: dict):
        super().__init__(message, faces=sorted(directions))
        self.directions = {int(f): list(d) for f, d in directions.items()}


def _as_sessions(sessions) -> list[CalibrationSession]:
    if isinstance(sessions, CalibrationSession):
        return [sessions]
    out = list(sessions)
    if not out:
        raise ValueError("sessions: expected at least one CalibrationSession")
    for k, s in enumerate(out):
        if not isinstance(s, CalibrationSession):
            raise ValueError(f"sessions[{k}]: expected a CalibrationSession, got {type(s).__name__}")
    return out


def session_offsets(session: CalibrationSession, block_size: int = 65536) -> np.ndarray:
    """Mean counts of the unloaded samples (rows of ``loaded`` all False), shape (36,).

    Also refuses NaN, inf and saturated counts, naming the sample indices.
    """
    return session_tare_stats(session, block_size)[0]


def session_tare_stats(session: CalibrationSession, block_size: int = 65536):
    """``(mean (36,), std (36,))`` of the counts over the unloaded samples, counts.

    The standard deviation is the gauge noise level each channel shows at rest. Refuses
    NaN, inf and saturated counts anywhere in the session, naming the sample indices.
    """
    mean, cov, _ = _tare_moments(session, block_size)
    return mean, np.sqrt(np.clip(np.diag(cov), 0.0, None))


def _tare_moments(session: CalibrationSession, block_size: int = 65536):
    """``(mean (36,), cov (36, 36), n)`` of the unloaded samples' counts (cov with 1/n).

    Refuses NaN, inf and saturated counts anywhere in the session, naming the sample indices.
    """
    total = np.zeros(N_GAUGES)
    total_sq = np.zeros((N_GAUGES, N_GAUGES))
    n = 0
    shift = None  # first unloaded sample: sums of squares about it do not cancel catastrophically
    lo, hi = session.counts_range
    for b in session.iter_blocks(block_size, counts_dtype=None):  # only the unloaded rows are converted
        check_block(b, lo, hi)
        free = ~b.loaded.any(axis=1)
        if free.any():
            c = b.counts[free]
            if shift is None:
                shift = c[0].astype(float)
            c = c - shift
            total += c.sum(axis=0)
            total_sq += c.T @ c
            n += c.shape[0]
    if n == 0:
        raise ValueError("loaded: the session has no unloaded samples (rows of all False) to take the offsets from")
    mean = total / n
    cov = total_sq / n - np.outer(mean, mean)
    return mean + shift, 0.5 * (cov + cov.T), n


def _other_features(spec, sessions):
    """What a joint method's free faces' outputs take of the other free faces' features (``PolyAccumulator``):
    nothing in the reference frame (``loaded_frame``), nor where a connected face under a ``face`` flange
    carries its own loads and every reaction (``total``: read from ``P x``, its reactions' features put
    phantom loads on that face in a free grasp); their cubes where it carries the reactions and no direct
    load (``unloaded_frame``); else all of them."""
    if spec.inputs != "all" or spec.output_frame != "face":
        return None
    if not any(s.flange == "face" for s in sessions):
        return "all"
    return None if spec.load_connected else "cubes"


def _poly_zero(session: CalibrationSession, block_size: int, n: int = POLY_TARE_SAMPLES):
    """What the polynomial correction's pass needs before it starts, from the session's first samples:
    ``(zero (36,) counts, scale_sq (36,) counts², rows)``.

    ``zero`` is the mean counts of the session's first stretch at rest (the tare it opens with; its
    first ``n`` samples); ``scale_sq`` and ``rows`` the sum of squares of the first block's counts
    less ``zero`` and its rows (a provisional scale: ``PolyAccumulator`` rescales). Only the blocks up to the stretch's end are read. Raises ``ValueError`` if the session
    has no sample at rest.
    """
    counts, got, first = [], 0, None
    for b in session.iter_blocks(block_size, counts_dtype=None):
        first = b.counts if first is None else first
        rest = ~b.loaded.any(axis=1)
        if got:  # the stretch goes on from the last block: it ends at the first loaded sample
            start = 0
        elif rest.any():
            start = int(np.argmax(rest))
        else:
            continue
        stop = start + int(np.argmin(rest[start:])) if not rest[start:].all() else rest.size
        stop = min(stop, start + n - got)
        counts.append(b.counts[start:stop].astype(float))
        got += stop - start
        if got >= n or stop < rest.size:
            break
    if got == 0:
        raise ValueError("loaded: the session has no unloaded samples (rows of all False) to take the offsets from")
    zero = np.concatenate(counts).mean(axis=0)
    d = first - zero
    return zero, np.einsum("ij,ij->j", d, d), d.shape[0]


def _rescale_groups(groups, residual, out_faces, E2, poly) -> None:
    """Give the covariance groups (and the fit residual table) the polynomial fit's residual sums of squares."""
    for g in groups:  # rows that keep the affine fit (E2 NaN) keep its residuals
        old = np.clip(np.diag(g.residual_cov), 1e-300, None)
        r = np.sqrt(E2[g.rows] / max(g.dof, 1) / old)
        r = np.where(np.isfinite(r), r, 1.0)
        g.residual_cov = g.residual_cov * np.outer(r, r)
    for k, f in enumerate(out_faces):
        n = max(poly.rows_of(f), 1)
        e = E2[6 * k : 6 * k + 6]
        residual[f - 1] = np.where(np.isfinite(e), np.sqrt(e / n), residual[f - 1])


def _load_rank(gram: np.ndarray, faces) -> int:
    """Dimension of the load space the targets of ``faces`` span (scaled to full scale)."""
    idx = np.concatenate([np.arange(6 * (f - 1), 6 * f) for f in faces])
    w = np.linalg.eigvalsh(gram[np.ix_(idx, idx)])
    if w[-1] <= 0:
        return 0
    return int(np.sum(np.sqrt(np.clip(w, 0, None) / w[-1]) >= EXCITATION_RTOL))


def _direction_name(v: np.ndarray) -> str:
    v = v / np.linalg.norm(v)
    big = np.argsort(-np.abs(v))
    v = v * np.sign(v[big[0]])
    if abs(v[big[1]]) < 0.1:
        return AXES[big[0]]
    terms = [f"{v[k]:+.2f}·{AXES[k]}" for k in big if abs(v[k]) >= 0.1]
    return "(" + " ".join(terms) + ")"


def _offset_from_intercept(C: np.ndarray, center: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Counts ``o`` with ``C (center − o) = b`` (least change of ``center``): the fitted zero-load counts."""
    return center - np.linalg.lstsq(C, b, rcond=RANK_RTOL)[0]


@dataclass
class _Streams:
    """What pass 2 of :meth:`Calibrator._fit` accumulates over the blocks."""

    gram: np.ndarray  # (36, 36) joint Gram of the scaled targets of all faces
    carried_any: np.ndarray  # (6,) bool: a face carried load in some usable sample
    n_used: int  # usable samples
    own: dict  # face -> StreamedQR of its own gauges
    joint_faces: tuple
    joint: StreamedQR | None  # all 36 gauges -> the joint faces
    poly: PolyAccumulator | None


@dataclass
class _Solution:
    """The solved linear model of :meth:`Calibrator._fit`, filled step by step."""

    matrix: np.ndarray  # (6F, 36)
    residual: np.ndarray  # (6, 6) fit residual RMS per face and axis, N and N·m
    offsets: list = field(default_factory=list)  # (36,) zero-load counts of each session
    ranks: list = field(default_factory=list)
    counts_rank: list = field(default_factory=list)
    groups: list = field(default_factory=list)  # CovarianceGroup


def _add_block(st: _Streams, k: int, n_int: int, b, center, targets, carries, usable) -> None:
    """Add one block of session ``k`` to the pass-2 accumulators."""
    st.n_used += int(usable.sum())
    st.carried_any |= (carries & usable[:, None]).any(axis=0)
    t = targets[usable].reshape(-1, 36)
    st.gram += (t.T @ t) * _GRAM_SCALE
    A = np.zeros((b.counts.shape[0], n_int + N_GAUGES))
    A[:, k] = 1.0
    np.subtract(b.counts, center, out=A[:, n_int:])
    unloaded = ~b.loaded.any(axis=1)
    for f, acc in st.own.items():
        rows = usable & (carries[:, f - 1] | unloaded)
        cols = np.r_[np.arange(n_int), n_int + np.arange(6 * (f - 1), 6 * f)]
        acc.add(A[np.ix_(rows, cols)], targets[rows, f - 1])
    if st.joint is not None:
        idx = [f - 1 for f in st.joint_faces]
        st.joint.add(A[usable], targets[usable][:, idx, :].reshape(-1, 6 * len(idx)))


def _own_offsets(tare_means, out_faces, own_C, own_b) -> list:
    """Each session's zero-load counts (36,) from the own-gauge fits' intercepts."""
    offsets = []
    for j, m in enumerate(tare_means):
        o = m.copy()
        for k, f in enumerate(out_faces):
            g = slice(6 * (f - 1), 6 * f)
            o[g] = _offset_from_intercept(own_C[6 * k : 6 * k + 6, g], m[g], own_b[j, 6 * k : 6 * k + 6])
        offsets.append(o)
    return offsets


class Calibrator:
    """Fit a calibration matrix from sessions (scikit-learn-like estimator).

    Parameters
    ----------
    method : str
        One of ``face_to_face``, ``quasi_total``, ``total``, ``loaded_frame``,
        ``unloaded_frame`` (docs/calibration.md, "The methods").
    prior : {None, "own_gauge"}
        None (default): the papers' plain least squares everywhere. ``"own_gauge"``: where
        the loads leave directions of the counts unexcited (a ``face`` or ``frame`` flange
        alone: 30 of the 36 load dimensions), each face's own-gauge fit gives the response
        in those directions only (so a free grasp's net load is estimated, not reported as
        zero); it never changes the response to the excited directions, but passes the
        gauge noise of 6 more directions (docs/calibration.md gives the cost).
    allow_rank_deficient : bool
        If a face's loads did not excite all six wrench directions, fit anyway (the
        pseudo-inverse: those directions are not calibrated) and warn
        (:class:`RankDeficientWarning`) instead of raising ``ValueError``.
    block_size : int
        Samples per block: memory is bounded by this, not by the number of samples.
    progress : callable, optional
        Called as ``progress(done, total)`` in samples during the fit.
    model : {"auto", "linear", "poly"}
        ``linear``: the papers' affine least squares ``C = W S⁺``, exactly. ``poly``: the same
        design with a ridge-regularised polynomial correction of each face's own gauges
        (docs/calibration.md). ``auto`` (default): ``poly`` only where cross-validation over
        whole loading segments chooses it: the correction at its best ridge where its mean held-out
        score beats the affine fit's by more than ``_cv.N_SE_SESSION`` standard errors, per face's forces and torques;
        the figures are in ``calibration_.model``.

    Attributes
    ----------
    calibration_ : Calibration
        The fitted calibration (after :meth:`fit`).
    offsets_ : list of ndarray (36,)
        Fitted zero-load counts of each session, counts.
    tare_means_ : list of ndarray (36,)
        Mean counts of each session's unloaded samples, counts.
    n_samples_ : int
        Samples used in the fit.
    """

    def __init__(self, method, *, prior=None, allow_rank_deficient: bool = False, block_size: int = 65536,
                 progress=None, model: str = "auto"):
        self.method = method
        self.prior = prior
        self.allow_rank_deficient = allow_rank_deficient
        self.block_size = block_size
        self.progress = progress
        self.model = model

    # ---------------------------------------------------------------- checks
    def _check_settings(self) -> None:
        """Validate the settings (at :meth:`fit`, as scikit-learn's estimators do)."""
        self.method = get_method(self.method).name
        if self.model not in MODELS:
            raise ValueError(f"model: expected one of {MODELS}, got {self.model!r}")
        if self.prior not in PRIORS:
            raise ValueError(f"prior: expected None or 'own_gauge', got {self.prior!r}")
        if self.model == "poly" and self.prior is not None:
            raise ValueError("model: 'poly' fits the measured load directions only; use prior=None with it")
        if int(self.block_size) < 1:
            raise ValueError(f"block_size: expected a positive number of samples, got {self.block_size!r}")
        self.block_size = int(self.block_size)
        self.allow_rank_deficient = bool(self.allow_rank_deficient)

    # ---------------------------------------------------------------- checks
    def _check_sessions(self, spec: MethodSpec, sessions: list[CalibrationSession]) -> None:
        net_ok = spec.inputs == "all" and spec.output_frame == "face" and NET_LOAD_FLANGE not in spec.flanges
        for k, s in enumerate(sessions):
            if s.flange not in spec.flanges and not (net_ok and s.flange == NET_LOAD_FLANGE):
                extra = f" ('{NET_LOAD_FLANGE}' sessions may be added beside them, for the net loads)" if net_ok else ""
                raise ValueError(
                    f"sessions[{k}].flange: method '{spec.name}' needs a flange in {spec.flanges}, got {s.flange!r}{extra}"
                )
            if s.core != sessions[0].core:
                raise ValueError(f"sessions[{k}].core: expected the same cube as sessions[0] ({sessions[0].core!r})")
        main = [(k, s) for k, s in enumerate(sessions) if s.flange in spec.flanges]
        if not main:
            raise ValueError(
                f"sessions: method '{spec.name}' needs at least one session with a flange in {spec.flanges}; "
                f"'{NET_LOAD_FLANGE}' sessions only add the net-load directions"
            )
        if not spec.mixed_mounts:
            k0, s0 = main[0]
            for k, s in main[1:]:
                if s.connected_face != s0.connected_face:
                    raise ValueError(
                        f"sessions[{k}].connected_face: method '{spec.name}' fits one mount at a time; "
                        f"got faces {s0.connected_face} and {s.connected_face} (calibrate them separately)"
                    )
                if spec.output_frame == "reference" and not np.allclose(s.T_core_ati, s0.T_core_ati, atol=1e-12):
                    raise ValueError(
                        f"sessions[{k}].T_core_ati: method '{spec.name}' fits in the reference frame, "
                        "so every session needs the same T_core_ati"
                    )

    def _output_faces(self, spec, sessions, carried_any: np.ndarray | None) -> tuple[int, ...]:
        if spec.outputs == "all":
            return FACES
        if spec.outputs == "free":
            c = next(s for s in sessions if s.flange in spec.flanges).connected_face
            return tuple(i for i in FACES if i != c)
        return tuple(i for i in FACES if carried_any[i - 1])

    # ---------------------------------------------------------------- fit
    def fit(self, sessions) -> "Calibrator":
        """Fit from one session or a list of sessions; returns ``self``.

        BLAS/LAPACK run single-threaded during the fit: its QR folds cache-sized chunks,
        which threads only slow down (and, on a busy machine, by ten times or more).
        """
        self._check_settings()
        with _threadpools().limit(limits=1):
            return self._fit(sessions)

    def _fit(self, sessions) -> "Calibrator":
        spec = get_method(self.method)
        sessions = _as_sessions(sessions)
        self._check_sessions(spec, sessions)
        n_int = len(sessions)
        mounts = [MountGeometry(s) for s in sessions]
        # the polynomial features are monomials of counts less a zero known before the pass: each
        # session's opening tare (its first stretch at rest); the linear fit takes the means of all
        # samples at rest in its one pass
        zeros = [_poly_zero(s, self.block_size) for s in sessions] if self.model != "linear" and self.prior is None else None
        # one pass: checks, tare moments, targets and their Gram (excitation, load rank), the
        # Gram of the affine design [offset column of each session | counts − tare mean | targets],
        # the error model's subsample; a second (QR) pass only where the Gram route is in doubt
        st, (tare_means, gauge_cov, ref_covs, ref_n), subsample = self._stream(spec, sessions, mounts, zeros)
        out_faces = st.joint_faces or self._output_faces(spec, sessions, st.carried_any)
        if not out_faces:
            raise ValueError("loaded: no face carried load in the sessions; nothing to calibrate")
        self._check_excitation(out_faces, st.gram)
        load_rank = _load_rank(st.gram, FACES)  # dimension of the 36-d space of face wrenches the loads span
        center = np.mean(tare_means, axis=0)
        weights = np.full(n_int, 1.0 / n_int)
        fit = _Solution(np.zeros((6 * len(out_faces), N_GAUGES)), np.full((6, 6), np.nan))
        own_C, own_b = self._solve_own(spec, st, out_faces, n_int, center, weights, fit)
        if st.joint is None:
            fit.matrix[:] = own_C
            fit.offsets = _own_offsets(tare_means, out_faces, own_C, own_b)
        else:
            self._solve_joint(st, out_faces, load_rank, own_C, gauge_cov, tare_means, center, weights, fit)
        choice, corr_fit, linear_fit = self._poly_step(st.poly, out_faces, None if zeros is None else [z[0] for z in zeros], fit,
                                                       group=6 if spec.output_frame == "reference" else 3)
        self.offsets_ = fit.offsets
        self.tare_means_ = tare_means
        self.n_samples_ = st.n_used
        s0 = next(s for s in sessions if s.flange in spec.flanges)
        meta = self._meta(spec, sessions, st, out_faces, load_rank, fit, choice, corr_fit)
        meta["reference_noise_at_rest"] = reference_noise_at_rest(ref_covs, ref_n)
        cal = Calibration(spec.name, fit.matrix, out_faces, spec.output_frame, np.mean(fit.offsets, axis=0), s0.core,
                          s0.T_core_ati, meta, correction=corr_fit, model=choice,
                          linear_fit=linear_fit)
        em = fit_error_model(cal, fit.groups, subsample, mounts, tare_means, ref_covs, gauge_cov)
        beyond = None
        if corr_fit is not None and st.poly.beyond_moment is not None:  # to each face's frame
            X = cal._face_from_output[np.asarray(out_faces) - 1]
            beyond = X @ st.poly.beyond_moment @ X.transpose(0, 2, 1)
        cal.covariance = CalibrationCovariance(groups=em.groups, gauge_cov=gauge_cov,
                                               variance_coef=em.variance_coef, residual_corr=em.residual_corr,
                                               scale=em.scale, beyond_cov=beyond)
        self.calibration_ = cal
        return self

    def _stream(self, spec, sessions, mounts, zeros):
        """The one pass (:class:`GramPass`), then the factors: ``(_Streams, (tare_means, gauge_cov, ref_covs, ref_n), subsample)``.

        ``zeros`` (:func:`_poly_zero` of each session, or None for no polynomial correction): the
        polynomial features' zero and scale.

        Where a Gram factor is in doubt (``GramQR.trouble``: ill-conditioned or rank-deficient
        designs) the fit takes a second pass with the streamed Householder QR instead.
        """
        n_int = len(sessions)
        need_own = spec.inputs == "own" or self.prior == "own_gauge"
        joint_faces = self._output_faces(spec, sessions, None) if spec.inputs == "all" else ()
        poly = None
        if zeros is not None:  # a provisional scale (the first blocks' RMS about the zero; the fit's is the fitted rows')
            rms = np.sqrt(sum(z[1] for z in zeros) / max(sum(z[2] for z in zeros), 1))
            poly = PolyAccumulator(spec.inputs == "own", joint_faces, n_int, np.where(rms > 0, rms, 1.0),
                                   {s.connected_face for s in sessions if s.flange == "face"}, [len(s) for s in sessions],
                                   other_features=_other_features(spec, sessions),
                                   session_loaded=[s.loaded for s in sessions],
                                   reaction_features="own" if spec.load_connected else "all")
        total_samples = sum(len(s) for s in sessions)
        # the same provisional centres whatever the model, so model="auto" that keeps the linear
        # fit gives it bit for bit
        gp = GramPass(n_int, FACES if need_own else (), total_samples, joint=bool(joint_faces))
        done = 0
        for k, (s, mount) in enumerate(zip(sessions, mounts)):
            lo, hi = s.counts_range
            for b in s.iter_blocks(self.block_size, counts_dtype=None):  # GramPass converts (and checks) chunk by chunk
                check_connected(gp.add(k, b, mount, spec.output_frame, poly, None if zeros is None else zeros[k][0],
                                       limits=(lo, hi)), k, b, s.connected_face)
                done += b.counts.shape[0]
                if self.progress is not None:
                    self.progress(done, total_samples)
        rest = gp.rest_noise()
        own, joint = gp.factors(rest[0], joint_faces)
        st = _Streams(gp.target_gram() * _GRAM_SCALE, gp.carried_any, gp.n_used, own, joint_faces, joint, poly)
        if any(a.trouble() for a in [*own.values(), joint] if a is not None):
            self._stream_qr(spec, sessions, mounts, rest[0], st)
        return st, rest, gp.subsample()

    def _stream_qr(self, spec, sessions, mounts, tare_means, st) -> None:
        """The stable second pass: streamed Householder QR of every design (replaces ``st.own``, ``st.joint``)."""
        n_int = len(sessions)
        qr = _Streams(np.zeros((N_GAUGES, N_GAUGES)), np.zeros(6, dtype=bool), 0,
                      {f: StreamedQR(n_int + 6, 6, flush_rows=self.block_size) for f in st.own},
                      st.joint_faces,
                      StreamedQR(n_int + N_GAUGES, 6 * len(st.joint_faces), flush_rows=self.block_size) if st.joint_faces else None,
                      None)
        for k, (s, mount, center) in enumerate(zip(sessions, mounts, tare_means)):
            for b in s.iter_blocks(self.block_size):
                targets, carries, usable, _ = block_targets(b.reference, b.loaded, mount, spec.output_frame)
                _add_block(qr, k, n_int, b, center, targets, carries, usable)
        st.own, st.joint = qr.own, qr.joint

    def _solve_own(self, spec, st, out_faces, n_int, center, weights, fit):
        """Each output face's own-gauge fit: the block-diagonal ``own_C`` (6F, 36) and intercepts (n_int, 6F)."""
        own = {f: st.own[f] for f in out_faces if f in st.own}
        own_C = np.zeros((6 * len(out_faces), N_GAUGES))  # block-diagonal: own gauges -> own rows
        own_b = np.zeros((n_int, 6 * len(out_faces)))
        for k, (f, acc) in enumerate(own.items()):
            res = self._solve_checked(acc, n_int + _load_rank(st.gram, (f,)), (f,), strict=spec.inputs == "own")
            g = slice(6 * (f - 1), 6 * f)
            own_C[6 * k : 6 * k + 6, g] = res.X[n_int:].T
            own_b[:, 6 * k : 6 * k + 6] = res.X[:n_int]
            if spec.inputs == "own":
                fit.ranks.append(_load_rank(st.gram, (f,)))
                fit.counts_rank.append(res.numerical_rank - n_int)
                fit.residual[f - 1] = res.residual_rms
                fit.groups.append(self._group(res, np.arange(6 * (f - 1), 6 * f), np.arange(6 * k, 6 * k + 6),
                                              center[g], weights))
        return own_C, own_b

    def _solve_joint(self, st, out_faces, load_rank, own_C, gauge_cov, tare_means, center, weights, fit) -> None:
        """The joint fit of every output face from all 36 gauges (with the own-gauge prior where asked)."""
        n_int = len(tare_means)
        joint = st.joint
        res = self._solve_checked(joint, n_int + min(load_rank, 36), out_faces, strict=True)
        C = res.X[n_int:].T
        B = res.X[:n_int]
        offsets = [_offset_from_intercept(C, m, B[k]) for k, m in enumerate(tare_means)]
        if self.prior == "own_gauge" and load_rank < 36:
            C_new = self._fill_unexcited(joint, res, C, own_C, gauge_cov, n_int, 36 - load_rank)
            X_new = np.vstack([np.stack([C_new @ (m - o) for m, o in zip(tare_means, offsets)]), C_new.T])
            D = X_new - res.X
            RD = np.triu(joint.R11) @ D
            res.residual_cp = res.residual_cp + RD.T @ RD
            res.residual_rms = np.sqrt(np.diag(res.residual_cp) / max(res.n_rows, 1))
            C = C_new
        fit.matrix[:] = C
        fit.offsets = offsets
        fit.ranks.append(load_rank)
        fit.counts_rank.append(res.numerical_rank - n_int)
        for k, f in enumerate(out_faces):
            fit.residual[f - 1] = res.residual_rms[6 * k : 6 * k + 6]
        fit.groups.append(self._group(res, np.arange(N_GAUGES), np.arange(6 * len(out_faces)), center, weights))

    def _poly_step(self, poly, out_faces, zeros, fit, group=3):
        """The model choice, and the polynomial correction where chosen: ``(choice, correction, linear_fit)``.

        ``group``: outputs chosen together (3: a face's forces, its torques; 6: a face's wrench, for an
        output frame other than the face's, whose torques mix the forces back in when moved to the face)."""
        choice, corr, linear_fit = ModelChoice(reason="the papers' affine least squares, as requested"), None, None
        if poly is not None:
            choice, sol = poly.fit(out_faces, self.model, fit.matrix, group=group)
            if sol is not None:
                C, B, D, E2 = sol
                linear_fit = (fit.matrix.copy(), np.mean(fit.offsets, axis=0))
                fit.matrix[:] = C
                # the zero-load counts: the features' zeros for the corrected rows, the affine rows' fitted offsets
                fit.offsets = mixed_offsets(C, linear_fit[0], choice.row_alpha, zeros, fit.offsets)
                corr = poly_correction(poly, D, C - linear_fit[0], linear_fit[0], out_faces,
                                       corrected=[a is not None for a in choice.row_alpha])
                _rescale_groups(fit.groups, fit.residual, out_faces, E2, poly)
        elif self.model != "linear":
            choice = ModelChoice(requested=self.model, reason="the papers' affine least squares: prior='own_gauge' "
                                 "fills the unexcited directions of the linear model only")
        return choice, corr, linear_fit

    def _meta(self, spec, sessions, st, out_faces, load_rank, fit, choice, corr) -> dict:
        """The calibration's ``meta``: method, sessions, fit, ranks, net load and coverage."""
        if load_rank >= 36:
            net_load = NET_LOAD_MEASURED
        elif spec.inputs == "own" or self.prior == "own_gauge":
            net_load = NET_LOAD_PRIOR
        else:
            net_load = NET_LOAD_UNIDENTIFIED
        s0 = next(s for s in sessions if s.flange in spec.flanges)
        return {
            "method": spec.name,
            "paper": spec.paper,
            "flanges": sorted({s.flange for s in sessions}),
            "connected_faces": sorted({s.connected_face for s in sessions}),
            "date": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
            "n_sessions": len(sessions),
            "n_samples": int(sum(len(s) for s in sessions)),
            "n_samples_fitted": int(st.n_used),
            "fit": "affine least squares: counts beside one offset column per session, unloaded samples as "
                   "zero-wrench rows (C = W S⁺)" + ("" if corr is None else ", with a polynomial correction of "
                                                   "each face's gauges (ridge chosen by cross-validation)"),
            "model": choice.name,
            "fit_residual_rms": fit.residual.tolist(),
            "load_rank": fit.ranks,
            "counts_rank": fit.counts_rank,
            "prior": self.prior,
            "net_load": net_load,
            "load_directions": {
                "measured": int(load_rank),
                "from_prior": int(36 - load_rank) if net_load == NET_LOAD_PRIOR else 0,
                "not_identified": int(36 - load_rank) if net_load == NET_LOAD_UNIDENTIFIED else 0,
            },
            "simulated": any(bool(s.meta.get("simulated", False)) for s in sessions),
            # which face axes and whether the net load the training loads measured (_coverage.py)
            "coverage": measured_directions(st.gram, out_faces, spec.output_frame, s0.core).to_meta(),
        } | ({} if corr is None or st.poly is None or st.poly.box_scale is None else {
            # per gauge, the correction's box over the trained range: > 1 where the polynomial, held out, beat
            # its extensions and is trusted out to the reach tested (_cv.trust_polynomial)
            "correction_box_scale": [float(v) for v in st.poly.box_scale]})

    @staticmethod
    def _group(res, inputs, rows, center, weights) -> CovarianceGroup:
        dof = max(res.n_rows - res.rank, 1)
        return CovarianceGroup(inputs, rows, res.design_pinv, res.residual_cp / dof, center, weights, dof)

    @staticmethod
    def _fill_unexcited(joint, res, C, own_C, gauge_cov, n_int, n_free) -> np.ndarray:
        """``C`` with its response to the ``n_free`` unexcited counts directions taken from ``own_C``.

        In counts whitened by the gauge noise at rest (``z = L⁻¹ s``, ``Σ_g = L Lᵀ``), the
        directions the loads excite are those the targets explain: the leading
        eigenvectors of ``Zᵀ P_T Z`` (the counts projected on the span of the targets, the
        offset columns projected out; read off the QR of ``[offsets | S | T]``). The other
        ``n_free`` carry noise only; there the response is the own-gauge fit's, elsewhere
        the least-squares fit's (unchanged).
        """
        R = np.triu(joint.R11)[n_int:, n_int:]  # Rᵀ R = Gram of the counts less their per-session means
        R12 = joint.R12[n_int:]
        G_ST = R.T @ R12
        G_TT = R12.T @ R12 + res.residual_cp
        w = np.linalg.eigvalsh(gauge_cov) if np.all(np.isfinite(gauge_cov)) else np.zeros(N_GAUGES)
        if w[0] > 1e-12 * max(w[-1], 1e-300):
            L = np.linalg.cholesky(gauge_cov)
        else:  # noise-free data: scale by the columns' norms
            L = np.diag(np.where(np.linalg.norm(R, axis=0) > 0, np.linalg.norm(R, axis=0), 1.0))
        Gz = np.linalg.solve(L, G_ST)  # L⁻¹ Sᵀ T
        M = Gz @ np.linalg.pinv(G_TT, rcond=RANK_RTOL, hermitian=True) @ Gz.T  # L⁻¹ Sᵀ P_T S L⁻ᵀ
        _, V = np.linalg.eigh(0.5 * (M + M.T))
        V = V[:, :n_free]  # (36, n_free): whitened directions the targets do not explain
        LV = L @ V
        LinvV = np.linalg.solve(L.T, V)  # L⁻ᵀ V: the projector is L V Vᵀ L⁻¹ in counts
        return C + (own_C - C) @ LV @ LinvV.T

    def _solve_checked(self, acc, rank, faces, *, strict):
        """Solve one accumulator, refusing too few samples or dead channels when ``strict``."""
        p = acc.p
        if acc.n_rows < p:
            raise ValueError(
                f"sessions: only {acc.n_rows} usable samples for face(s) {list(faces)}, expected at least {p}"
            )
        res = acc.solve()
        if strict and res.numerical_rank < min(rank, p) and not self.allow_rank_deficient:
            raise RankDeficientError(
                f"counts: the gauge data for face(s) {list(faces)} span fewer than the {rank} "
                f"dimensions the loads and offsets span (rank {res.numerical_rank} < {rank}); "
                "a gauge channel may be dead or stuck; pass allow_rank_deficient=True for a minimum-norm fit",
                faces=faces,
            )
        return res

    def _check_excitation(self, out_faces, gram) -> None:
        problems = []
        for f in out_faces:
            G = gram[6 * (f - 1) : 6 * f, 6 * (f - 1) : 6 * f]
            w, V = np.linalg.eigh(G)
            if w[-1] <= 0:
                problems.append((f, ["all six directions (the face carried no load)"]))
                continue
            weak = np.sqrt(np.clip(w, 0, None) / w[-1]) < EXCITATION_RTOL
            if weak.any():
                problems.append((f, [_direction_name(V[:, k]) for k in np.flatnonzero(weak)]))
        if not problems:
            return
        text = "; ".join(f"face {f}: {', '.join(names)}" for f, names in problems)
        msg = f"loaded: loads did not excite every wrench direction — {text}"
        if self.allow_rank_deficient:
            warnings.warn(msg + " (minimum-norm least squares: those directions are not calibrated)",
                          RankDeficientWarning, stacklevel=3)
        else:
            raise ExcitationError(msg + "; load those directions, or pass allow_rank_deficient=True for a minimum-norm fit",
                                  dict(problems))

    def predict(self, counts, offset=None) -> np.ndarray:
        """``Calibration.wrenches`` of the fitted calibration: (N, 6, 6) face frames."""
        if not hasattr(self, "calibration_"):
            raise RuntimeError("Calibrator: call fit(sessions) before predict(counts)")
        return self.calibration_.wrenches(counts, offset=offset)


def calibrate(sessions, method, **kwargs) -> Calibration:
    """Fit ``C = W S⁺`` for ``method`` from one session or a list; see :class:`Calibrator`.

    Parameters
    ----------
    sessions : CalibrationSession or list of CalibrationSession
        Sessions under the method's flange; for ``total``, ``unloaded_frame`` and
        ``quasi_total`` also ``frame_hole`` sessions, which measure the net-load directions.
    method : str
        ``face_to_face``, ``quasi_total``, ``total``, ``loaded_frame`` or ``unloaded_frame``.
    **kwargs
        ``prior``, ``allow_rank_deficient``, ``block_size``, ``progress`` (see :class:`Calibrator`).

    Returns
    -------
    Calibration
    """
    return Calibrator(method, **kwargs).fit(sessions).calibration_

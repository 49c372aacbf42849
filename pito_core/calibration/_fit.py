"""The one least-squares core behind the five methods: ``calibrate`` and ``Calibrator``."""

from __future__ import annotations

import datetime as _dt
import warnings

import numpy as np

from ..frames import FACES
from ._calibration import Calibration
from ._lstsq import RANK_RTOL, StreamedQR
from ._methods import MethodSpec, get_method
from ._session import CalibrationSession, _few
from ._targets import MountGeometry, block_targets

__all__ = ["calibrate", "Calibrator", "RankDeficientWarning", "session_offsets", "AXES"]

AXES = ("fx", "fy", "fz", "tx", "ty", "tz")

#: A face's loads must excite each wrench direction with at least this fraction of
#: the strongest direction (scaled: forces by 15 N, torques by 0.1 N·m full scale).
EXCITATION_RTOL = 1e-3
#: Default ``min_snr``: where the loads span fewer than 36 dimensions, a counts direction
#: follows the data when its RMS signal exceeds this many times the gauge noise at rest,
#: the faces' own-gauge fits otherwise (docs/calibration.md, step 5).
DEFAULT_MIN_SNR = 30.0
#: Full-scale loads used to put forces and torques on one footing (N, N·m).
FULL_SCALE = np.array([15.0, 15.0, 15.0, 0.1, 0.1, 0.1])
_GRAM_SCALE = np.outer(np.tile(1 / FULL_SCALE, 6), np.tile(1 / FULL_SCALE, 6))


class RankDeficientWarning(UserWarning):
    """A face's loads did not excite every wrench direction; a minimum-norm fit was used."""


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
    total = np.zeros(36)
    total_sq = np.zeros(36)
    n = 0
    shift = None  # first unloaded sample: sums of squares about it do not cancel catastrophically
    lo, hi = session.counts_range
    for b in session.iter_blocks(block_size):
        bad = ~np.isfinite(b.counts).all(axis=1)
        if bad.any():
            raise ValueError(f"counts: NaN or inf at sample indices {_few(np.flatnonzero(bad) + b.start)}")
        bad = ~np.isfinite(b.reference).all(axis=1)
        if bad.any():
            raise ValueError(f"reference: NaN or inf at sample indices {_few(np.flatnonzero(bad) + b.start)}")
        sat = ((b.counts <= lo) | (b.counts >= hi)).any(axis=1)
        if sat.any():
            raise ValueError(
                f"counts: saturated (at or beyond the ADC range [{lo}, {hi}]) at sample indices "
                f"{_few(np.flatnonzero(sat) + b.start)}"
            )
        free = ~b.loaded.any(axis=1)
        if free.any():
            c = b.counts[free]
            if shift is None:
                shift = c[0].copy()
            c = c - shift
            total += c.sum(axis=0)
            total_sq += (c**2).sum(axis=0)
            n += c.shape[0]
    if n == 0:
        raise ValueError("loaded: the session has no unloaded samples (rows of all False) to take the offsets from")
    mean = total / n
    var = np.maximum(total_sq / n - mean**2, 0.0)
    return mean + shift, np.sqrt(var)


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


class Calibrator:
    """Fit a calibration matrix from sessions (scikit-learn-like estimator).

    Parameters
    ----------
    method : str
        One of ``face_to_face``, ``quasi_total``, ``total``, ``loaded_frame``,
        ``unloaded_frame`` (SPEC "Calibration methods").
    allow_rank_deficient : bool
        If a face's loads did not excite all six wrench directions, fit the
        minimum-norm solution and warn (:class:`RankDeficientWarning`) instead of
        raising ``ValueError``.
    block_size : int
        Samples per block: memory is bounded by this, not by the number of samples.
    progress : callable, optional
        Called as ``progress(done, total)`` in samples during the fit.
    min_snr : float
        Only where the loads span fewer than the 36 gauge dimensions (type-1 and type-3
        flanges): a direction of the counts follows the data when its RMS signal exceeds
        ``min_snr`` × the gauge noise at rest, and each face's own-gauge fit otherwise, so
        loads never seen in calibration (a free grasp's net load) are still measured.
        ``min_snr=0`` gives the papers' plain least squares ``C = W S⁺``: lower error on
        loads like the calibration's, but blind to net loads (docs/calibration.md).

    Attributes
    ----------
    calibration_ : Calibration
        The fitted calibration (after :meth:`fit`).
    offsets_ : list of ndarray (36,)
        Unloaded counts of each session, counts.
    n_samples_ : int
        Samples used in the fit.
    """

    def __init__(self, method, *, allow_rank_deficient: bool = False, block_size: int = 65536, progress=None,
                 min_snr: float = DEFAULT_MIN_SNR):
        self.method = get_method(method).name
        self.allow_rank_deficient = bool(allow_rank_deficient)
        if int(block_size) < 1:
            raise ValueError(f"block_size: expected a positive number of samples, got {block_size!r}")
        self.block_size = int(block_size)
        self.progress = progress
        if not float(min_snr) >= 0:
            raise ValueError(f"min_snr: expected a signal-to-noise ratio ≥ 0, got {min_snr!r}")
        self.min_snr = float(min_snr)

    # ---------------------------------------------------------------- checks
    def _check_sessions(self, spec: MethodSpec, sessions: list[CalibrationSession]) -> None:
        for k, s in enumerate(sessions):
            if s.flange not in spec.flanges:
                raise ValueError(
                    f"sessions[{k}].flange: method '{spec.name}' needs a flange in {spec.flanges}, got {s.flange!r}"
                )
            if s.core != sessions[0].core:
                raise ValueError(f"sessions[{k}].core: expected the same cube as sessions[0] ({sessions[0].core!r})")
        if not spec.mixed_mounts:
            s0 = sessions[0]
            for k, s in enumerate(sessions[1:], 1):
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

    def _output_faces(self, spec, sessions, carried_any: np.ndarray) -> tuple[int, ...]:
        if spec.outputs == "all":
            return FACES
        if spec.outputs == "free":
            c = sessions[0].connected_face
            return tuple(i for i in FACES if i != c)
        return tuple(i for i in FACES if carried_any[i - 1])

    # ---------------------------------------------------------------- fit
    def fit(self, sessions) -> "Calibrator":
        """Fit from one session or a list of sessions; returns ``self``."""
        spec = get_method(self.method)
        sessions = _as_sessions(sessions)
        self._check_sessions(spec, sessions)
        total_samples = sum(len(s) for s in sessions)

        # pass 1: offsets and noise at rest (refusing NaN, inf and saturated samples)
        stats = [session_tare_stats(s, self.block_size) for s in sessions]
        offsets = [m for m, _ in stats]
        # gauge noise at rest, pooled over sessions: the coordinates in which signal and
        # noise directions separate (used when the loads span fewer than 36 dimensions)
        noise = np.sqrt(np.mean([sd**2 for _, sd in stats], axis=0))
        noise = noise if np.all(noise > 0) else None
        mounts = [MountGeometry(s) for s in sessions]

        # pass 2: targets, their Gram matrix (excitation, load rank) and streamed QR.
        # Each face's own-gauge fit (face_to_face's 6×6 blocks) is the result for "own"
        # methods, and the prior for "all" methods under flanges that leave the loads
        # fewer than 36 dimensions (type 1: the connected face idle; type 3: balanced).
        gram = np.zeros((36, 36))  # joint Gram of the scaled targets of all faces
        carried_any = np.zeros(6, dtype=bool)
        n_used = 0
        need_own = spec.inputs == "own" or any(s.flange in ("frame", "face") for s in sessions)
        own = {f: StreamedQR(6, 6, flush_rows=self.block_size) for f in FACES} if need_own else {}
        joint_faces = self._output_faces(spec, sessions, None) if spec.inputs == "all" else ()
        joint = StreamedQR(36, 6 * len(joint_faces), flush_rows=self.block_size) if joint_faces else None
        idx = [f - 1 for f in joint_faces]
        done = 0
        for k, (s, mount, offset) in enumerate(zip(sessions, mounts, offsets)):
            for b in s.iter_blocks(self.block_size):
                targets, carries, usable, bad = block_targets(b.reference, b.loaded, mount, spec.output_frame)
                if bad.any():
                    raise ValueError(
                        f"sessions[{k}].loaded: the connected face {s.connected_face} cannot be loaded with "
                        f"flange 'frame', yet it is marked loaded at sample indices {_few(np.flatnonzero(bad) + b.start)}"
                    )
                every = usable.all()
                n_used += int(usable.sum())
                carried_any |= (carries & usable[:, None]).any(axis=0)
                t = (targets if every else targets[usable]).reshape(-1, 36)
                gram += (t.T @ t) * _GRAM_SCALE
                S = b.counts - offset
                unloaded = ~b.loaded.any(axis=1)
                for f, acc in own.items():
                    rows = usable & (carries[:, f - 1] | unloaded)
                    acc.add(S[rows, 6 * (f - 1) : 6 * f], targets[rows, f - 1])
                if joint is not None:
                    if every:  # the common case: no copies of the whole block
                        B = targets.reshape(-1, 36) if joint_faces == FACES else targets[:, idx, :].reshape(-1, 6 * len(idx))
                        joint.add(S, B)
                    else:
                        joint.add(S[usable], targets[usable][:, idx, :].reshape(-1, 6 * len(joint_faces)))
                done += b.counts.shape[0]
                if self.progress is not None:
                    self.progress(done, total_samples)
        out_faces = joint_faces or self._output_faces(spec, sessions, carried_any)
        if not out_faces:
            raise ValueError("loaded: no face carried load in the sessions; nothing to calibrate")
        self._check_excitation(out_faces, gram)
        all_rank = _load_rank(gram, out_faces) if spec.inputs == "all" else 0
        own = {f: own[f] for f in out_faces if f in own}

        matrix = np.zeros((6 * len(out_faces), 36))
        residual = np.full((6, 6), np.nan)
        ranks = []
        own_X = np.zeros((36, 6 * len(out_faces)))  # block-diagonal: own gauges -> own rows
        for k, (f, acc) in enumerate(own.items()):
            rank = _load_rank(gram, (f,))
            res = self._solve_checked(acc, rank, (f,), deficient=f in self._deficient_faces, strict=spec.inputs == "own",
                                      col_scale=None if noise is None else noise[6 * (f - 1) : 6 * f])
            own_X[6 * (f - 1) : 6 * f, 6 * k : 6 * k + 6] = res.X
            if spec.inputs == "own":
                ranks.append(res.rank)
                residual[f - 1] = res.residual_rms
        if joint is None:
            matrix[:] = own_X.T
        else:
            # loads spanning r < 36 dimensions: fit those r exactly (the noise-only
            # directions are dropped, not fitted), and act as the faces' own-gauge fits
            # on the rest (e.g. the net load, which a face flange always balances)
            rank = min(all_rank, 36)
            if self.min_snr == 0:  # the papers' plain least squares
                res = self._solve_checked(joint, rank, out_faces, deficient=False, strict=True)
            elif rank < 36 and noise is not None:
                # noisy data: ridge towards the own-gauge fit, in noise units (a direction
                # needs an RMS signal of min_snr × the noise at rest to follow the data)
                ridge = joint.n_rows * self.min_snr**2
                res = self._solve_checked(joint, rank, out_faces, deficient=False, strict=True,
                                          prior=own_X if own else None, col_scale=noise, ridge=ridge)
            else:  # full-rank loads, or noise-free data: keep the r load directions exactly
                res = self._solve_checked(joint, rank, out_faces, deficient=rank < 36, strict=True,
                                          prior=own_X if rank < 36 and own else None)
            matrix[:] = res.X.T
            ranks.append(res.rank)
            for k, f in enumerate(out_faces):
                residual[f - 1] = res.residual_rms[6 * k : 6 * k + 6]

        self.offsets_ = offsets
        self.n_samples_ = n_used
        s0 = sessions[0]
        meta = {
            "method": spec.name,
            "paper": spec.paper,
            "flanges": sorted({s.flange for s in sessions}),
            "connected_faces": sorted({s.connected_face for s in sessions}),
            "date": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
            "n_sessions": len(sessions),
            "n_samples": int(total_samples),
            "n_samples_fitted": int(n_used),
            "fit_residual_rms": residual.tolist(),
            "load_rank": ranks,
            "min_snr": self.min_snr,
            "simulated": any(bool(s.meta.get("simulated", False)) for s in sessions),
        }
        self.calibration_ = Calibration(
            method=spec.name,
            matrix=matrix,
            output_faces=out_faces,
            output_frame=spec.output_frame,
            offset=np.mean(offsets, axis=0),
            core=s0.core,
            T_core_ati=s0.T_core_ati,
            meta=meta,
        )
        return self

    def _solve_checked(self, acc, rank, faces, *, deficient, strict, prior=None, col_scale=None, ridge=None):
        """Solve one accumulator, refusing too few samples or dead channels when ``strict``."""
        p = acc.p
        if acc.n_rows < p:
            raise ValueError(
                f"sessions: only {acc.n_rows} usable samples for face(s) {list(faces)}, expected at least {p}"
            )
        res = acc.solve(rank=rank if deficient else None, prior=prior, col_scale=col_scale, ridge=ridge)
        if strict and res.numerical_rank < min(rank, p) and not self.allow_rank_deficient:
            raise ValueError(
                f"counts: the gauge data for face(s) {list(faces)} span fewer than the {rank} "
                f"dimensions the loads span (rank {res.numerical_rank} < {rank}); "
                "a gauge channel may be dead or stuck; pass allow_rank_deficient=True for a minimum-norm fit"
            )
        return res

    def _check_excitation(self, out_faces, gram) -> None:
        problems = []
        self._deficient_faces = set()
        for f in out_faces:
            G = gram[6 * (f - 1) : 6 * f, 6 * (f - 1) : 6 * f]
            w, V = np.linalg.eigh(G)
            if w[-1] <= 0:
                problems.append((f, "all six directions (the face carried no load)"))
                continue
            weak = np.sqrt(np.clip(w, 0, None) / w[-1]) < EXCITATION_RTOL
            if weak.any():
                names = ", ".join(_direction_name(V[:, k]) for k in np.flatnonzero(weak))
                problems.append((f, names))
        self._deficient_faces = {f for f, _ in problems}
        if not problems:
            return
        text = "; ".join(f"face {f}: {names}" for f, names in problems)
        msg = f"loaded: loads did not excite every wrench direction — {text}"
        if self.allow_rank_deficient:
            warnings.warn(msg + " (minimum-norm fit used)", RankDeficientWarning, stacklevel=3)
        else:
            raise ValueError(msg + "; load those directions, or pass allow_rank_deficient=True for a minimum-norm fit")

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
    method : str
        ``face_to_face``, ``quasi_total``, ``total``, ``loaded_frame`` or ``unloaded_frame``.
    **kwargs
        ``allow_rank_deficient``, ``block_size``, ``progress``, ``min_snr`` (see :class:`Calibrator`).

    Returns
    -------
    Calibration
    """
    return Calibrator(method, **kwargs).fit(sessions).calibration_

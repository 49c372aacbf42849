"""Figures of merit of the seed papers, as data: RMSE, face identification, comparison
series, inverse condition numbers, and the equilibrium of a free grasp."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..defaults import LOADED_FORCE_N, LOADED_TORQUE_NM
from ..frames import invert_pose, wrench_adjoint
from ._calibration import Calibration
from ._fit import AXES, _as_sessions, session_offsets
from ._targets import MountGeometry, block_targets

__all__ = ["Evaluation", "evaluate", "inverse_condition_table", "identify_loaded_faces", "equilibrium", "Equilibrium",
           "DEFAULT_FORCE_THRESHOLD", "DEFAULT_TORQUE_THRESHOLD", "PAPER_IDENTIFICATION_RULE",
           "calibration_uncertainty", "UNCERTAINTY_WORDS"]

#: The papers' identification rule per kind of load: single-face loads are identified by the
#: force norm, squeeze loads (two or more faces, equal and opposite forces) by the torque norm.
PAPER_IDENTIFICATION_RULE = {"single": "force", "squeeze": "torque"}
_RULE_WORDS = {"force": "by force (‖F‖ > {f} N)", "torque": "by torque (‖T‖ > {t} N·m)",
               "either": "by force or torque (‖F‖ > {f} N or ‖T‖ > {t} N·m)"}

#: A face counts as loaded when the norm of its force exceeds this, N (``pito_core.defaults``).
DEFAULT_FORCE_THRESHOLD = LOADED_FORCE_N
#: … or the norm of its torque exceeds this, N·m.
DEFAULT_TORQUE_THRESHOLD = LOADED_TORQUE_NM
#: Comparison series kept for plots (evenly subsampled beyond this).
MAX_SERIES = 5000


def identify_loaded_faces(face_wrenches, force_threshold=DEFAULT_FORCE_THRESHOLD,
                          torque_threshold=DEFAULT_TORQUE_THRESHOLD, by="either"):
    """Which faces are loaded, from the norms of their forces and/or torques.

    Parameters
    ----------
    face_wrenches : array-like, shape (N, 6, 6)
        Wrench on each face (face frames), N and N·m; NaN rows never count as loaded.
    force_threshold : float
        N.
    torque_threshold : float
        N·m.
    by : {"force", "torque", "either"}
        Norm(s) compared with the thresholds.

    Returns
    -------
    loaded : ndarray of bool, shape (N, 6)
    """
    W = np.asarray(face_wrenches, dtype=float)
    if W.ndim != 3 or W.shape[1:] != (6, 6):
        raise ValueError(f"face_wrenches: expected shape (N, 6, 6), got {W.shape}")
    fn = np.linalg.norm(W[..., :3], axis=-1)
    tn = np.linalg.norm(W[..., 3:], axis=-1)
    with np.errstate(invalid="ignore"):
        if by == "force":
            out = fn > force_threshold
        elif by == "torque":
            out = tn > torque_threshold
        elif by == "either":
            out = (fn > force_threshold) | (tn > torque_threshold)
        else:
            raise ValueError(f"by: expected 'force', 'torque' or 'either', got {by!r}")
    return out & np.isfinite(fn)


class _Acc:
    """Running sums of squared errors per (face, axis)."""

    def __init__(self, shape):
        self.sse = np.zeros(shape)
        self.n = np.zeros(shape)

    def add(self, err, where=None):
        e = np.where(np.isfinite(err), err, 0.0)
        ok = np.isfinite(err)
        self.sse += (e**2).sum(axis=0)
        self.n += ok.sum(axis=0)

    def rmse(self):
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(self.n > 0, np.sqrt(self.sse / np.maximum(self.n, 1)), np.nan)


@dataclass
class Evaluation:
    """Figures of merit of one calibration on held-out sessions (SI units).

    Attributes
    ----------
    method : str
    rmse_single : ndarray (6, 6)
        RMSE of the wrench on the loaded face, face i at row i-1, axes
        ``[fx, fy, fz, tx, ty, tz]`` (N, N·m), over single-face loads. NaN: no data.
    rmse_crosstalk : ndarray (6, 6)
        RMSE on the faces that carried nothing during single-face loads (ideally 0).
    rmse_squeeze : ndarray (6,)
        RMSE of the resultant of the loaded faces against the reference, squeeze
        (several faces) loads, in the reference frame.
    n_single, n_squeeze : int
        Samples behind those figures.
    identification : dict
        Face identification accuracy: ``single`` and ``squeeze``, by ``force``,
        ``torque`` and ``either`` (fractions of samples whose identified set of loaded
        faces equals the true one), the thresholds, and per-face accuracies.
    comparison : dict
        Per-axis series for plots: ``predicted (M, 6)`` and ``reference (M, 6)`` in the
        reference frame (N, N·m), ``kind (M,)`` ("single"/"squeeze"), ``face (M,)``
        (loaded face or 0 for squeeze) — subsampled to at most ``MAX_SERIES``.
    identified : dict
        ``force_norm (M, 6)`` N and ``torque_norm (M, 6)`` N·m of every face for the
        same samples as ``comparison``, and ``true_loaded (M, 6)``.
    inverse_condition_number : float
    face_inverse_condition_numbers : ndarray (6,)
    uncertainty95 : ndarray (6, 6) or None
        Half-width of the 95 % interval per face and axis from the calibration's own
        covariance (:func:`calibration_uncertainty`); None for calibrations without one.
    """

    method: str
    rmse_single: np.ndarray
    rmse_crosstalk: np.ndarray
    rmse_squeeze: np.ndarray
    n_single: int
    n_squeeze: int
    identification: dict
    comparison: dict
    identified: dict
    inverse_condition_number: float
    face_inverse_condition_numbers: np.ndarray
    simulated: bool = False
    sessions: list = field(default_factory=list)
    uncertainty95: np.ndarray | None = None

    def identification_headline(self) -> list[dict]:
        """The papers' face identification figures: single-face loads by force, squeeze by torque.

        Returns
        -------
        list of dict
            One per kind of load present: ``kind`` ("single"/"squeeze"), ``rule``
            ("force"/"torque"), ``accuracy`` (fraction of samples whose identified set of
            loaded faces is exactly right), ``n`` (samples) and ``text`` (the figure and its
            rule in words, e.g. "single-face loads: 99.8 % identified by force (‖F‖ > 0.5 N)").
        """
        idn = self.identification
        out = []
        for kind, rule in PAPER_IDENTIFICATION_RULE.items():
            d = idn.get(kind) or {}
            acc = d.get(rule)
            if not d.get("n") or acc is None:
                continue
            words = _RULE_WORDS[rule].format(f=idn.get("force_threshold_N"), t=idn.get("torque_threshold_Nm"))
            label = "single-face loads" if kind == "single" else "squeeze loads"
            out.append({"kind": kind, "rule": rule, "accuracy": float(acc), "n": int(d["n"]),
                        "text": f"{label}: {100 * acc:.1f} % of {d['n']} samples identified {words}"})
        return out

    def rmse_force(self) -> np.ndarray:
        """(6,) RMS over the three force axes of each loaded face, N."""
        return _rms_rows(self.rmse_single[:, :3])

    def rmse_torque(self) -> np.ndarray:
        """(6,) RMS over the three torque axes of each loaded face, N·m."""
        return _rms_rows(self.rmse_single[:, 3:])

    def to_dict(self, series: bool = False) -> dict:
        """JSON-ready figures (NaN → None); ``series=True`` adds the comparison series."""

        def clean(a):
            a = np.asarray(a, dtype=float)
            return np.where(np.isfinite(a), a, np.nan).tolist() if a.ndim else (float(a) if np.isfinite(a) else None)

        def nan_to_none(x):
            if isinstance(x, list):
                return [nan_to_none(v) for v in x]
            if isinstance(x, float) and not np.isfinite(x):
                return None
            return x

        d = {
            "method": self.method,
            "units": {"force": "N", "torque": "N·m"},
            "axes": list(AXES),
            "simulated": self.simulated,
            "sessions": self.sessions,
            "rmse_single": nan_to_none(clean(self.rmse_single)),
            "rmse_crosstalk": nan_to_none(clean(self.rmse_crosstalk)),
            "rmse_squeeze": nan_to_none(clean(self.rmse_squeeze)),
            "n_single": self.n_single,
            "n_squeeze": self.n_squeeze,
            "identification": nan_to_none(_jsonable(self.identification)),
            "identification_headline": self.identification_headline(),
            "inverse_condition_number": self.inverse_condition_number,
            "face_inverse_condition_numbers": nan_to_none(clean(self.face_inverse_condition_numbers)),
            "uncertainty95": None if self.uncertainty95 is None else nan_to_none(clean(self.uncertainty95)),
            "uncertainty95_meaning": UNCERTAINTY_WORDS,
        }
        if series:
            d["comparison"] = {k: np.asarray(v).tolist() for k, v in self.comparison.items()}
        return d


def _rms_rows(a: np.ndarray) -> np.ndarray:
    """RMS over each row's finite entries; NaN for a row with none."""
    ok = np.isfinite(a)
    n = ok.sum(axis=1)
    sq = np.where(ok, a, 0.0) ** 2
    return np.where(n > 0, np.sqrt(sq.sum(axis=1) / np.maximum(n, 1)), np.nan)


def _jsonable(x):
    if isinstance(x, dict):
        return {k: _jsonable(v) for k, v in x.items()}
    if isinstance(x, np.ndarray):
        return x.tolist()
    if isinstance(x, np.generic):
        return x.item()
    return x


def evaluate(calibration: Calibration, sessions, *, tare: bool = True,
             force_threshold: float = DEFAULT_FORCE_THRESHOLD,
             torque_threshold: float = DEFAULT_TORQUE_THRESHOLD, block_size: int = 65536,
             seed: int = 0) -> Evaluation:
    """Evaluate ``calibration`` on held-out ``sessions`` (the papers' figures of merit).

    Parameters
    ----------
    calibration : Calibration
    sessions : CalibrationSession or list
        Held-out data: single-face loads (one loaded face) and/or squeeze loads (two or
        more). Any mount; targets follow the load paths of docs/conventions.md.
    tare : bool
        Use each session's own unloaded samples as the offset (as the papers tare
        before each run); otherwise the calibration's offset.
    force_threshold, torque_threshold : float
        Face identification thresholds, N and N·m.

    Returns
    -------
    Evaluation
    """
    if not isinstance(calibration, Calibration):
        raise ValueError(f"calibration: expected a Calibration, got {type(calibration).__name__}")
    sessions = _as_sessions(sessions)
    single, cross, squeeze = _Acc((6, 6)), _Acc((6, 6)), _Acc((6,))
    rng = np.random.default_rng(seed)
    series = {"predicted": [], "reference": [], "kind": [], "face": [], "force_norm": [], "torque_norm": [],
              "true_loaded": []}
    id_counts = {k: {m: [0, 0] for m in ("force", "torque", "either")} for k in ("single", "squeeze")}
    per_face = {m: [np.zeros(6), np.zeros(6)] for m in ("force", "torque", "either")}
    n_single = n_squeeze = 0
    total_rows = sum(len(s) for s in sessions)
    keep_p = min(1.0, MAX_SERIES / max(total_rows, 1))
    for s in sessions:
        offset = session_offsets(s, block_size) if tare else None
        mount = MountGeometry(s)
        X_ati_face = mount.X_ati_face  # face frame -> S_A
        evaluable = np.ones(6, dtype=bool)
        if s.flange in ("face", "frame"):
            evaluable[s.connected_face - 1] = False  # carries the reaction, or nothing
        for b in s.iter_blocks(block_size):
            pred = calibration.wrenches(b.counts, offset=offset)
            targets, carries, usable, _ = block_targets(b.reference, b.loaded, mount, "face")
            n_loaded = b.loaded.sum(axis=1)
            # a direct load on a type-3 flange's face goes into the flange: no face senses it,
            # so such samples cannot be compared with the reference
            sensed = ~b.loaded[:, s.connected_face - 1] if s.flange == "face" else np.ones(len(n_loaded), bool)
            one = usable & (n_loaded == 1)
            # single-face loads: error on the face carrying the load and on the others
            if one.any():
                err = pred[one] - targets[one]
                car = carries[one]
                single.add(np.where(car[:, :, None], err, np.nan))
                cross.add(np.where(~car[:, :, None], err, np.nan))
                n_single += int(one.sum())
            # squeeze: resultant of the loaded faces (in S_A) against the reference
            many = (n_loaded >= 2) & sensed
            resultant = np.einsum("fij,nfj->ni", X_ati_face, np.where(b.loaded[:, :, None], pred, 0.0))
            if many.any():
                squeeze.add(resultant[many] - b.reference[many])
                n_squeeze += int(many.sum())
            # identification against the loaded mask, on the evaluable faces
            true = b.loaded[:, evaluable]
            loaded_rows = n_loaded >= 1
            for mode in ("force", "torque", "either"):
                got = identify_loaded_faces(pred, force_threshold, torque_threshold, by=mode)[:, evaluable]
                hit = (got == true).all(axis=1)
                for kind, rows in (("single", one & loaded_rows), ("squeeze", many)):
                    id_counts[kind][mode][0] += int(hit[rows].sum())
                    id_counts[kind][mode][1] += int(rows.sum())
                per_face[mode][0][evaluable] += (got == true)[loaded_rows].sum(axis=0)
                per_face[mode][1][evaluable] += loaded_rows.sum()
            # comparison series (subsampled)
            pick = ((one & sensed) | many) & (rng.random(len(one)) < keep_p)
            if pick.any():
                single_pred = np.where(one[:, None], resultant, np.nan)
                series["predicted"].append(np.where(many[:, None], resultant, single_pred)[pick])
                series["reference"].append(b.reference[pick])
                series["kind"].append(np.where(many[pick], "squeeze", "single"))
                series["face"].append(np.where(one[pick], np.argmax(b.loaded[pick], axis=1) + 1, 0))
                series["force_norm"].append(np.linalg.norm(pred[pick][..., :3], axis=-1))
                series["torque_norm"].append(np.linalg.norm(pred[pick][..., 3:], axis=-1))
                series["true_loaded"].append(b.loaded[pick])
    cat = {k: (np.concatenate(v) if v else np.zeros((0,) + ((6,) if k not in ("kind", "face") else ())))
           for k, v in series.items()}
    identification = {
        kind: {mode: (h / n if n else None) for mode, (h, n) in modes.items()} | {"n": modes["either"][1]}
        for kind, modes in id_counts.items()
    }
    identification["per_face"] = {
        mode: np.where(n > 0, h / np.maximum(n, 1), np.nan).tolist() for mode, (h, n) in per_face.items()
    }
    identification["force_threshold_N"] = force_threshold
    identification["torque_threshold_Nm"] = torque_threshold
    return Evaluation(
        method=calibration.method,
        rmse_single=single.rmse(),
        rmse_crosstalk=cross.rmse(),
        rmse_squeeze=squeeze.rmse(),
        n_single=n_single,
        n_squeeze=n_squeeze,
        identification=identification,
        comparison={k: cat[k] for k in ("predicted", "reference", "kind", "face")},
        identified={k: cat[k] for k in ("force_norm", "torque_norm", "true_loaded")},
        inverse_condition_number=calibration.inverse_condition_number,
        face_inverse_condition_numbers=calibration.face_inverse_condition_numbers(),
        simulated=bool(calibration.meta.get("simulated")) or any(bool(s.meta.get("simulated")) for s in sessions),
        sessions=[repr(s) for s in sessions],
        uncertainty95=calibration_uncertainty(calibration, sessions, seed=seed),
    )


#: What :attr:`Evaluation.uncertainty95` is, in words (CLI, app, JSON).
UNCERTAINTY_WORDS = ("± = 95 % interval (1.96 σ) of each face's wrench from the calibration's own covariance "
                     "(fit residuals and design, gauge noise), median over the held-out loaded samples")


def calibration_uncertainty(calibration: Calibration, sessions, max_samples: int = 2000, seed: int = 0):
    """Half-width of the 95 % interval per face and axis, from the calibration's covariance.

    Parameters
    ----------
    calibration : Calibration
    sessions : CalibrationSession or list
        Samples at which the covariance is evaluated (only loaded samples are used).
    max_samples : int
        At most this many samples (evenly random) are used.

    Returns
    -------
    ndarray, shape (6, 6), or None
        ``[i-1, a]`` = 1.96 × the median standard deviation of face i's axis ``a`` (N for
        forces, N·m for torques); NaN for faces without output. None when the calibration
        has no covariance (files of format version 1) or no sample is loaded.
    """
    if getattr(calibration, "covariance", None) is None:
        return None
    rng = np.random.default_rng(seed)
    picked = []
    for s in _as_sessions(sessions):
        loaded = np.asarray(s.loaded).any(axis=1)
        idx = np.flatnonzero(loaded)
        if idx.size:
            picked.append(np.asarray(s.counts, dtype=float)[idx])
    if not picked:
        return None
    counts = np.concatenate(picked)
    if len(counts) > max_samples:
        counts = counts[np.sort(rng.choice(len(counts), max_samples, replace=False))]
    _, cov = calibration.wrenches(counts, return_cov=True)
    sd = np.sqrt(np.clip(np.diagonal(cov, axis1=-2, axis2=-1), 0, None))  # (N, 6, 6)
    return 1.96 * np.median(sd, axis=0)


def inverse_condition_table(calibrations) -> list[dict]:
    """The PITO paper's Table I as rows: inverse condition number per method and mount.

    Parameters
    ----------
    calibrations : iterable of Calibration

    Returns
    -------
    rows : list of dict
        ``method``, ``connected_faces`` (list), ``flanges`` (list),
        ``inverse_condition_number`` (σmin/σmax of the whole matrix) and
        ``face_inverse_condition_numbers`` (six values, None where no output).
    """
    rows = []
    for cal in calibrations:
        per_face = cal.face_inverse_condition_numbers()
        rows.append({
            "method": cal.method,
            "connected_faces": list(cal.meta.get("connected_faces", [])),
            "flanges": list(cal.meta.get("flanges", [])),
            "inverse_condition_number": cal.inverse_condition_number,
            "face_inverse_condition_numbers": [None if not np.isfinite(v) else float(v) for v in per_face],
        })
    return rows


@dataclass
class Equilibrium:
    """Equilibrium of a free grasp, per sample (SI units).

    Attributes
    ----------
    force_sum : ndarray (N, 3)
        ΣF_i of the loads on the faces, core frame, N.
    force_sum_norm : ndarray (N,)
        ‖ΣF_i‖, N — equals the weight ``m g`` in quasi-static equilibrium.
    weight : float
        ``m g``, N.
    torque_cog : ndarray (N, 3)
        ΣT_i about the centre of gravity, core frame, N·m.
    torque_cog_norm : ndarray (N,)
        ‖ΣT_i‖ about the centre of gravity, N·m — zero in quasi-static equilibrium.
    """

    force_sum: np.ndarray
    force_sum_norm: np.ndarray
    weight: float
    torque_cog: np.ndarray
    torque_cog_norm: np.ndarray


def equilibrium(face_wrenches, core, mass, cog=(0.0, 0.0, 0.0), g=9.81) -> Equilibrium:
    """Equilibrium check of a free grasp from the wrench on each face.

    Parameters
    ----------
    face_wrenches : array-like, shape (N, 6, 6)
        Wrench on each face in face frames, N and N·m (NaN faces are skipped).
    core : CubeCore
    mass : float
        Mass of the object (core + patches), kg.
    cog : array-like, shape (3,)
        Centre of gravity in the core frame, m.
    g : float
        Gravitational acceleration, m/s².

    Returns
    -------
    Equilibrium
    """
    W = np.asarray(face_wrenches, dtype=float)
    if W.ndim != 3 or W.shape[1:] != (6, 6):
        raise ValueError(f"face_wrenches: expected shape (N, 6, 6), got {W.shape}")
    if not float(mass) > 0:
        raise ValueError(f"mass: expected a positive mass in kg, got {mass!r}")
    cog = np.asarray(cog, dtype=float)
    if cog.shape != (3,):
        raise ValueError(f"cog: expected shape (3,), got {cog.shape}")
    T_cog = np.eye(4)
    T_cog[:3, 3] = cog
    # wrench in face frame -> frame at the cog with core axes: T_face_cog = inv(T_core_face) @ T_core_cog
    X = np.stack([wrench_adjoint(invert_pose(T) @ T_cog) for T in core.face_poses()])
    total = np.einsum("fij,nfj->ni", X, np.nan_to_num(W))
    return Equilibrium(
        force_sum=total[:, :3],
        force_sum_norm=np.linalg.norm(total[:, :3], axis=1),
        weight=float(mass) * g,
        torque_cog=total[:, 3:],
        torque_cog_norm=np.linalg.norm(total[:, 3:], axis=1),
    )

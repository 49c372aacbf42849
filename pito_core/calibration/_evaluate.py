"""Figures of merit of the seed papers on held-out sessions, as data: RMSE, face
identification and comparison series (:class:`Evaluation`, :func:`evaluate`)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ._calibration import Calibration
from ._fit import AXES, _as_sessions, session_offsets
from ._interval import UNCERTAINTY_WORDS, calibration_uncertainty, interval_caveat
from ._metrics import (
    DEFAULT_FORCE_THRESHOLD, DEFAULT_TORQUE_THRESHOLD, PAPER_IDENTIFICATION_RULE, _RULE_WORDS, _Acc, _rms_rows,
    identify_loaded_faces,
)
from ._targets import MountGeometry, block_targets

__all__ = ["Evaluation", "evaluate", "MAX_SERIES"]

#: Comparison series kept for plots (evenly subsampled beyond this).
MAX_SERIES = 5000


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
        faces equals the true one: for single-face loads the labelled face if the
        reference's load on it exceeds the threshold, so a load passing near zero is
        not counted as a miss), the thresholds, per-face accuracies (``per_face``) and,
        over single-face loads, the accuracy by loaded face (``by_loaded_face``, six
        fractions per mode, NaN where that face was not loaded; ``by_loaded_face_n``).
    comparison : dict
        Per-axis series for plots: ``predicted (M, 6)`` and ``reference (M, 6)`` in the
        reference frame (N, N·m), ``kind (M,)`` ("single"/"squeeze"), ``face (M,)``
        (loaded face or 0 for squeeze) — subsampled to at most ``MAX_SERIES``.
    identified : dict
        ``force_norm (M, 6)`` N and ``torque_norm (M, 6)`` N·m of every face for the
        same samples as ``comparison``, ``true_loaded (M, 6)`` (by force, as above) and
        ``evaluable (M, 6)``: the faces identification scores (not a ``face`` flange's face, which
        carries reactions, nor a ``frame`` flange's, which carries nothing).
    inverse_condition_number : float
    face_inverse_condition_numbers : ndarray (6,)
    uncertainty95 : ndarray (6, 6) or None
        Half-width of the 95 % interval per face and axis from the calibration's own
        covariance (:func:`calibration_uncertainty`); None for calibrations without one.
    uncertainty95_caveat : str or None
        Why those intervals may be short, in one line (:func:`interval_caveat`), or None.
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
    uncertainty95_caveat: str | None = None

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
            "uncertainty95_caveat": self.uncertainty95_caveat,
        }
        if series:
            d["comparison"] = {k: np.asarray(v).tolist() for k, v in self.comparison.items()}
        return d


def _jsonable(x):
    if isinstance(x, dict):
        return {k: _jsonable(v) for k, v in x.items()}
    if isinstance(x, np.ndarray):
        return x.tolist()
    if isinstance(x, np.generic):
        return x.item()
    return x


class _Tally:
    """Running figures of :func:`evaluate` over the blocks of the held-out sessions."""

    def __init__(self, force_threshold, torque_threshold, keep_p, seed):
        self.force_threshold, self.torque_threshold, self.keep_p = force_threshold, torque_threshold, keep_p
        self.single, self.cross, self.squeeze = _Acc((6, 6)), _Acc((6, 6)), _Acc((6,))
        self.rng = np.random.default_rng(seed)
        self.series = {"predicted": [], "reference": [], "kind": [], "face": [], "force_norm": [], "torque_norm": [],
                       "true_loaded": [], "evaluable": []}
        self.id_counts = {k: {m: [0, 0] for m in ("force", "torque", "either")} for k in ("single", "squeeze")}
        self.per_face = {m: [np.zeros(6), np.zeros(6)] for m in ("force", "torque", "either")}
        self.by_loaded = {m: [np.zeros(6), np.zeros(6)] for m in ("force", "torque", "either")}
        self.n_single = self.n_squeeze = 0

    def add(self, pred, b, s, mount, evaluable) -> None:
        """One block ``b`` of session ``s``: predicted face wrenches ``pred`` (n, 6, 6) against its targets."""
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
            self.single.add(np.where(car[:, :, None], err, np.nan))
            self.cross.add(np.where(~car[:, :, None], err, np.nan))
            self.n_single += int(one.sum())
        # squeeze: resultant of the loaded faces (in S_A) against the reference
        many = (n_loaded >= 2) & sensed
        resultant = np.einsum("fij,nfj->ni", mount.X_ati_face, np.where(b.loaded[:, :, None], pred, 0.0))
        if many.any():
            self.squeeze.add(resultant[many] - b.reference[many])
            self.n_squeeze += int(many.sum())
        truth = {mode: self._truth(targets, b.loaded, one, mode) for mode in ("force", "torque", "either")}
        self._identify(pred, truth, b.loaded, n_loaded, one, many, evaluable)
        # comparison series (subsampled)
        pick = ((one & sensed) | many) & (self.rng.random(len(one)) < self.keep_p)
        if pick.any():
            self._keep(pick, pred, resultant, b, one, many, truth["force"], evaluable)

    def _truth(self, targets, loaded, one, mode) -> np.ndarray:
        """``(n, 6)`` bool: the faces truly loaded, by ``mode``'s norms and thresholds.

        Single-face samples: the labelled face, if the reference's load on it exceeds the
        threshold (a load passing near zero — a ramp, a release — is a load no calibration
        can identify, so it is not counted as one). Squeeze samples: the labels."""
        true = loaded.copy()
        if one.any():
            above = identify_loaded_faces(np.nan_to_num(targets[one]), self.force_threshold, self.torque_threshold,
                                          by=mode)
            true[one] &= above
        return true

    def _identify(self, pred, truth, loaded, n_loaded, one, many, evaluable) -> None:
        """Identification against the true loads (:meth:`_truth`), on the evaluable faces."""
        loaded_rows = n_loaded >= 1
        face = np.argmax(loaded, axis=1)
        for mode in ("force", "torque", "either"):
            true = truth[mode][:, evaluable]
            got = identify_loaded_faces(pred, self.force_threshold, self.torque_threshold, by=mode)[:, evaluable]
            hit = (got == true).all(axis=1)
            for kind, rows in (("single", one & loaded_rows), ("squeeze", many)):
                self.id_counts[kind][mode][0] += int(hit[rows].sum())
                self.id_counts[kind][mode][1] += int(rows.sum())
            self.per_face[mode][0][evaluable] += (got == true)[loaded_rows].sum(axis=0)
            self.per_face[mode][1][evaluable] += loaded_rows.sum()
            rows = one & loaded_rows
            np.add.at(self.by_loaded[mode][0], face[rows], hit[rows])
            np.add.at(self.by_loaded[mode][1], face[rows], 1)

    def _keep(self, pick, pred, resultant, b, one, many, true_loaded, evaluable) -> None:
        series = self.series
        single_pred = np.where(one[:, None], resultant, np.nan)
        series["predicted"].append(np.where(many[:, None], resultant, single_pred)[pick])
        series["reference"].append(b.reference[pick])
        series["kind"].append(np.where(many[pick], "squeeze", "single"))
        series["face"].append(np.where(one[pick], np.argmax(b.loaded[pick], axis=1) + 1, 0))
        series["force_norm"].append(np.linalg.norm(pred[pick][..., :3], axis=-1))
        series["torque_norm"].append(np.linalg.norm(pred[pick][..., 3:], axis=-1))
        series["true_loaded"].append(true_loaded[pick])
        series["evaluable"].append(np.broadcast_to(evaluable, (int(pick.sum()), 6)))

    def identification(self) -> dict:
        """:attr:`Evaluation.identification`."""
        identification = {
            kind: {mode: (h / n if n else None) for mode, (h, n) in modes.items()} | {"n": modes["either"][1]}
            for kind, modes in self.id_counts.items()
        }
        identification["per_face"] = {
            mode: np.where(n > 0, h / np.maximum(n, 1), np.nan).tolist() for mode, (h, n) in self.per_face.items()
        }
        identification["by_loaded_face"] = {
            mode: np.where(n > 0, h / np.maximum(n, 1), np.nan).tolist() for mode, (h, n) in self.by_loaded.items()
        }
        identification["by_loaded_face_n"] = self.by_loaded["force"][1].astype(int).tolist()
        identification["force_threshold_N"] = self.force_threshold
        identification["torque_threshold_Nm"] = self.torque_threshold
        return identification

    def concatenated(self) -> dict:
        """The kept series, each concatenated over the blocks."""
        return {k: (np.concatenate(v) if v else np.zeros((0,) + ((6,) if k not in ("kind", "face") else ())))
                for k, v in self.series.items()}


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
    total_rows = sum(len(s) for s in sessions)
    tally = _Tally(force_threshold, torque_threshold, min(1.0, MAX_SERIES / max(total_rows, 1)), seed)
    for s in sessions:
        offset = session_offsets(s, block_size) if tare else None
        mount = MountGeometry(s)
        evaluable = np.ones(6, dtype=bool)
        if s.flange in ("face", "frame"):
            evaluable[s.connected_face - 1] = False  # carries the reaction, or nothing
        for b in s.iter_blocks(block_size):
            tally.add(calibration.wrenches(b.counts, offset=offset), b, s, mount, evaluable)
    cat = tally.concatenated()
    return Evaluation(
        method=calibration.method,
        rmse_single=tally.single.rmse(),
        rmse_crosstalk=tally.cross.rmse(),
        rmse_squeeze=tally.squeeze.rmse(),
        n_single=tally.n_single,
        n_squeeze=tally.n_squeeze,
        identification=tally.identification(),
        comparison={k: cat[k] for k in ("predicted", "reference", "kind", "face")},
        identified={k: cat[k] for k in ("force_norm", "torque_norm", "true_loaded", "evaluable")},
        inverse_condition_number=calibration.inverse_condition_number,
        face_inverse_condition_numbers=calibration.face_inverse_condition_numbers(),
        simulated=bool(calibration.meta.get("simulated")) or any(bool(s.meta.get("simulated")) for s in sessions),
        sessions=[repr(s) for s in sessions],
        uncertainty95=calibration_uncertainty(calibration, sessions, seed=seed, tare=tare),
        uncertainty95_caveat=interval_caveat(calibration),
    )

"""Face identification and the plain figures behind the papers' tables: which faces are
loaded (force/torque norms against thresholds), running RMSE sums, inverse condition numbers."""

from __future__ import annotations

import numpy as np

from ..defaults import LOADED_FORCE_N, LOADED_TORQUE_NM

__all__ = ["identify_loaded_faces", "inverse_condition_table", "DEFAULT_FORCE_THRESHOLD", "DEFAULT_TORQUE_THRESHOLD",
           "PAPER_IDENTIFICATION_RULE"]

#: The papers' identification rule per kind of load: single-face loads are identified by the
#: force norm, squeeze loads (two or more faces, equal and opposite forces) by the torque norm.
PAPER_IDENTIFICATION_RULE = {"single": "force", "squeeze": "torque"}
_RULE_WORDS = {"force": "by force (‖F‖ > {f} N)", "torque": "by torque (‖T‖ > {t} N·m)",
               "either": "by force or torque (‖F‖ > {f} N or ‖T‖ > {t} N·m)"}

#: A face counts as loaded when the norm of its force exceeds this, N (``pito_core.defaults``).
DEFAULT_FORCE_THRESHOLD = LOADED_FORCE_N
#: … or the norm of its torque exceeds this, N·m.
DEFAULT_TORQUE_THRESHOLD = LOADED_TORQUE_NM


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


def _rms_rows(a: np.ndarray) -> np.ndarray:
    """RMS over each row's finite entries; NaN for a row with none."""
    ok = np.isfinite(a)
    n = ok.sum(axis=1)
    sq = np.where(ok, a, 0.0) ** 2
    return np.where(n > 0, np.sqrt(sq.sum(axis=1) / np.maximum(n, 1)), np.nan)



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

"""The 95 % interval of each face's wrench on held-out samples, from the calibration's own covariance."""

from __future__ import annotations

import numpy as np

from ._calibration import Calibration
from ._fit import _as_sessions

__all__ = ["calibration_uncertainty", "UNCERTAINTY_WORDS"]

#: What :attr:`Evaluation.uncertainty95` is, in words (CLI, app, JSON).
UNCERTAINTY_WORDS = ("± = 95 % interval (1.96 σ) of each face's true wrench from the calibration's own covariance "
                     "(fit residuals and design, gauge noise; the reference's noise, measured in the tare, taken out), "
                     "median over the held-out loaded samples, with the offset the RMSE uses (by default each "
                     "session's own tare)")


def calibration_uncertainty(calibration: Calibration, sessions, max_samples: int = 2000, seed: int = 0,
                            tare: bool = False):
    """Half-width of the 95 % interval per face and axis, from the calibration's covariance.

    Parameters
    ----------
    calibration : Calibration
    sessions : CalibrationSession or list
        Samples at which the covariance is evaluated (only loaded samples are used).
    max_samples : int
        At most this many samples (evenly random) are used.
    tare : bool
        Each session's samples with the calibration tared on its own unloaded samples (as
        :func:`evaluate` computes its RMSE); otherwise with the calibration's own offset.

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
    picked = []  # (calibration in use, loaded samples' counts)
    for s in _as_sessions(sessions):
        loaded = np.asarray(s.loaded).any(axis=1)
        idx = np.flatnonzero(loaded)
        if idx.size:
            counts = np.asarray(s.counts, dtype=float)
            cal = calibration.tare(counts[~loaded]) if tare and (~loaded).any() else calibration
            picked.append((cal, counts[idx]))
    if not picked:
        return None
    n = sum(len(c) for _, c in picked)
    keep = np.sort(rng.choice(n, max_samples, replace=False)) if n > max_samples else np.arange(n)
    sd, start = [], 0
    for cal, counts in picked:
        mine = keep[(keep >= start) & (keep < start + len(counts))] - start
        start += len(counts)
        if mine.size:
            _, cov = cal.wrenches(counts[mine], return_cov=True)
            sd.append(np.sqrt(np.clip(np.diagonal(cov, axis1=-2, axis2=-1), 0, None)))  # (N, 6, 6)
    return 1.96 * np.median(np.concatenate(sd), axis=0)

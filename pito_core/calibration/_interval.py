"""The 95 % interval of each face's wrench on held-out samples, from the calibration's own covariance."""

from __future__ import annotations

import numpy as np

from ._calibration import Calibration
from ._fit import _as_sessions

__all__ = ["calibration_uncertainty", "UNCERTAINTY_WORDS"]

#: What :attr:`Evaluation.uncertainty95` is, in words (CLI, app, JSON).
UNCERTAINTY_WORDS = ("± = 95 % interval (1.96 σ) of each face's true wrench from the calibration's own covariance "
                     "(fit residuals and design, gauge noise; the reference's noise, measured in the tare, taken out), "
                     "median over the held-out loaded samples")


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

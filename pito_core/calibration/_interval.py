"""The 95 % interval of each face's wrench on held-out samples, from the calibration's own covariance."""

from __future__ import annotations

import numpy as np

from ..defaults import TARE_STILL_FORCE_STD_N, TARE_STILL_TORQUE_STD_NM
from ._calibration import Calibration
from ._fit import _as_sessions
from ._targets import MountGeometry, block_targets

__all__ = ["calibration_uncertainty", "interval_caveat", "UNCERTAINTY_WORDS"]

#: What :attr:`Evaluation.uncertainty95` is, in words (CLI, app, JSON).
UNCERTAINTY_WORDS = ("± = 95 % interval (1.96 σ) of each face's true wrench from the calibration's own covariance "
                     "(fit residuals and design, the error against load; the reference's noise, measured in the tare, taken out), "
                     "median over the held-out single-face loads where the face carries (the RMSE's samples), with "
                     "the offset the RMSE uses (by default each session's own tare)")


def interval_caveat(calibration) -> str | None:
    """What a user must know before trusting the calibration's intervals, in one line, or None: its training
    reference's noise at rest above the tare's stillness limits (``meta["reference_noise_at_rest"]``, written by
    ``calibrate``; files without it: None)."""
    rn = calibration.meta.get("reference_noise_at_rest") or {}
    if rn.get("within_limits", True):
        return None
    return (f"the training reference's noise at rest, up to {max(rn['force_std_N']):.3f} N and "
            f"{max(rn['torque_std_Nm']) * 1000:.2f} mN·m, is above the limits the intervals were checked within "
            f"({TARE_STILL_FORCE_STD_N} N, {TARE_STILL_TORQUE_STD_NM * 1000:g} mN·m): where a face carries, the ± may "
            "be short")


def calibration_uncertainty(calibration: Calibration, sessions, max_samples: int = 2000, seed: int = 0,
                            tare: bool = False):
    """Half-width of the 95 % interval per face and axis, from the calibration's covariance, on the samples
    of :func:`evaluate`'s ``rmse_single``: single-face loads, each face where it carries (its own load, or a
    flange's face its reactions): an interval is of its sample's error, and where a face carries that error
    is its own load's.

    Parameters
    ----------
    calibration : Calibration
    sessions : CalibrationSession or list
        Samples at which the covariance is evaluated (single-face loads only).
    max_samples : int
        At most this many samples (evenly random) are used.
    tare : bool
        Each session's samples with the calibration tared on its own unloaded samples (as
        :func:`evaluate` computes its RMSE); otherwise with the calibration's own offset.

    Returns
    -------
    ndarray, shape (6, 6), or None
        ``[i-1, a]`` = 1.96 × the median standard deviation of face i's axis ``a`` (N for
        forces, N·m for torques) where it carries; NaN for faces without output or such samples.
        None when the calibration has no covariance (files of format version 1) or no sample is
        a single-face load.
    """
    if getattr(calibration, "covariance", None) is None:
        return None
    rng = np.random.default_rng(seed)
    picked = []  # (calibration in use, the samples' counts, which faces carry (n, 6))
    for s in _as_sessions(sessions):
        loaded = np.asarray(s.loaded)
        _, carries, usable, _ = block_targets(np.asarray(s.reference, float), loaded, MountGeometry(s), "face")
        idx = np.flatnonzero(usable & (loaded.sum(axis=1) == 1))
        if idx.size:
            counts = np.asarray(s.counts, dtype=float)
            rest = ~loaded.any(axis=1)
            cal = calibration.tare(counts[rest]) if tare and rest.any() else calibration
            picked.append((cal, counts[idx], carries[idx]))
    if not picked:
        return None
    n = sum(len(c) for _, c, _ in picked)
    keep = np.sort(rng.choice(n, max_samples, replace=False)) if n > max_samples else np.arange(n)
    sd, carry, start = [], [], 0
    for cal, counts, carries in picked:
        mine = keep[(keep >= start) & (keep < start + len(counts))] - start
        start += len(counts)
        if mine.size:
            _, cov = cal.wrenches(counts[mine], return_cov=True)
            sd.append(np.sqrt(np.clip(np.diagonal(cov, axis1=-2, axis2=-1), 0, None)))  # (N, 6, 6)
            carry.append(carries[mine])
    sd, carry = np.concatenate(sd), np.concatenate(carry)
    out = np.full((6, 6), np.nan)  # a face that carries on none of them: NaN
    for f in np.flatnonzero(carry.any(axis=0)):
        out[f] = 1.96 * np.median(sd[carry[:, f], f], axis=0)
    return out

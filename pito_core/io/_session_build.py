"""One way to build a calibration session from paired arrays, with one saturation rule.

The wizard (``app.wizard.model``) and ``pito_core.devices.Acquisition.to_session`` both
build their sessions here: samples with a cube gauge at or beyond its ADC limit, a
saturated reference record, or a non-finite value never enter a calibration.
"""

from __future__ import annotations

import numpy as np

from ..frames import CUBE_ADC_LIMIT, N_GAUGES
from ._session import CalibrationSession

__all__ = ["session_from_arrays", "saturated_samples"]


def saturated_samples(counts, reference, reference_saturated=None) -> np.ndarray:
    """(N,) bool: samples a calibration must not use.

    Parameters
    ----------
    counts : array-like, shape (N, 36)
        Raw gauge counts; a gauge at or beyond ±``CUBE_ADC_LIMIT`` (2²³ − 1) is saturated.
    reference : array-like, shape (N, 6)
        The paired reference, N and N·m; NaN or inf rows are excluded too.
    reference_saturated : array-like of bool, shape (N,), optional
        The reference's own saturation flag, paired to each sample.
    """
    c = np.asarray(counts, dtype=float)
    r = np.asarray(reference, dtype=float)
    bad = (np.abs(c) >= CUBE_ADC_LIMIT).any(axis=1) | ~np.isfinite(c).all(axis=1) | ~np.isfinite(r).all(axis=1)
    if reference_saturated is not None:
        bad |= np.asarray(reference_saturated, dtype=bool)
    return bad


def session_from_arrays(counts, reference, loaded, time=None, *, T_core_ati, flange, connected_face, core=None,
                        meta=None, reference_saturated=None) -> CalibrationSession:
    """A :class:`CalibrationSession` from paired arrays, without the saturated samples.

    Parameters
    ----------
    counts : array-like, shape (N, 36)
        Raw gauge counts (not tared).
    reference : array-like, shape (N, 6)
        Reference ``[fx, fy, fz, tx, ty, tz]`` paired to each sample and tared, N and N·m, in S_A.
    loaded : array-like of bool, shape (N, 6)
        Faces under direct load per sample.
    time : array-like, shape (N,), optional
        Sample times, s.
    T_core_ati, flange, connected_face, core
        As :class:`CalibrationSession`.
    meta : dict, optional
        Session metadata; ``excluded_saturated_samples`` is added.
    reference_saturated : array-like of bool, shape (N,), optional
        See :func:`saturated_samples`.

    Raises
    ------
    ValueError
        Every sample is saturated, or a bad shape (named by field).
    """
    counts = np.asarray(counts)
    reference = np.asarray(reference, dtype=float)
    if counts.ndim != 2 or counts.shape[1] != N_GAUGES:
        raise ValueError(f"counts: expected shape (N, {N_GAUGES}), got {counts.shape}")
    if reference.shape != (counts.shape[0], 6):
        raise ValueError(f"reference: expected shape ({counts.shape[0]}, 6), got {reference.shape}")
    bad = saturated_samples(counts, reference, reference_saturated)
    if bad.all():
        raise ValueError("counts: every sample is saturated (cube ADC limit, reference status) or not finite")
    keep = ~bad
    info = dict(meta or {})
    info["excluded_saturated_samples"] = int(bad.sum())
    t = None if time is None else np.asarray(time, dtype=float)[keep]
    return CalibrationSession(counts[keep], reference[keep], np.asarray(loaded, dtype=bool)[keep], T_core_ati, flange,
                              connected_face, core=core, time=t, meta=info)

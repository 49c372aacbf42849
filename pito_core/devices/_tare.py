"""The one tare: its checks (still, unloaded) and its event, for the wizard, the live view and the recorder.

A tare is right only when nothing moves and nothing loads the cube: then the mean counts are
the zero of every gauge. :func:`check_tare` says whether a window of samples is such a moment
(and why not, in one line); :func:`tare_event` turns the window into the event that
``Pipeline.apply_tare`` applies and a recording replays.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..defaults import (
    TARE_NO_LOAD_FORCE_N, TARE_NO_LOAD_TORQUE_NM, TARE_STILL_FORCE_STD_N, TARE_STILL_TORQUE_STD_NM,
)

__all__ = ["TareCheck", "TareRefused", "check_tare", "tare_event", "MIN_TARE_SAMPLES", "FACE_STILL_FACTOR"]

#: Fewest samples a tare is taken from.
MIN_TARE_SAMPLES = 10
#: The face wrenches' spread may exceed the reference's stillness limits by this factor (the cube's own noise).
FACE_STILL_FACTOR = 4.0


class TareRefused(ValueError):
    """A tare was asked for while the cube moved or carried a load; ``check`` says which."""

    def __init__(self, check: "TareCheck"):
        super().__init__(f"tare refused: {check.reason}")
        self.check = check

    def __reduce__(self):  # pickles as itself (it crosses the pipeline process's boundary)
        return (TareRefused, (self.check,))


@dataclass(frozen=True)
class TareCheck:
    """Whether a window of samples may be a tare, and the figures behind the verdict.

    Attributes
    ----------
    ok : bool
    reason : str
        Why not, in one line ("" when ok).
    n : int
        Samples in the window.
    reference_force_std, reference_torque_std : float
        Largest standard deviation of the reference's force (N) / torque (N·m) axes; NaN without a reference.
    face_load : float
        Largest face force from the calibration's own zero, N (NaN without a calibration).
    face_torque : float
        Largest face torque from it, N·m.
    face : int
        The face carrying ``face_load`` (0 without a calibration).
    """

    ok: bool
    reason: str
    n: int
    reference_force_std: float = float("nan")
    reference_torque_std: float = float("nan")
    face_load: float = float("nan")
    face_torque: float = float("nan")
    face: int = 0


def _reference_spread(reference):
    r = np.asarray(reference, dtype=float)
    r = r[np.isfinite(r).all(axis=1)] if r.ndim == 2 and r.shape[1] == 6 else np.zeros((0, 6))
    if r.shape[0] < MIN_TARE_SAMPLES:
        return float("nan"), float("nan")
    return float(r[:, :3].std(axis=0).max()), float(r[:, 3:].std(axis=0).max())


def check_tare(counts, reference=None, calibration=None) -> TareCheck:
    """Whether ``counts (n, 36)`` (and the paired ``reference (n, 6)``, N and N·m) can be a tare.

    Still: the reference's spread under ``TARE_STILL_FORCE_STD_N`` and ``TARE_STILL_TORQUE_STD_NM``
    (``pito_core.defaults``); with a ``calibration`` (anything with ``wrenches(counts)`` giving face
    wrenches ``(n, 6, 6)`` from its own zero), also each face's spread under ``FACE_STILL_FACTOR``
    times those. Unloaded (needs a calibration): no face reading more than ``TARE_NO_LOAD_FORCE_N``
    / ``TARE_NO_LOAD_TORQUE_NM`` from the calibration's zero — the object's weight on a support
    counts as a load. Without a reference nor a calibration nothing can tell, and the tare is refused.
    """
    c = np.asarray(counts, dtype=float)
    n = int(c.shape[0]) if c.ndim == 2 else 0
    if c.ndim != 2 or c.shape[1] != 36:
        raise ValueError(f"counts: expected shape (n, 36), got {c.shape}")
    if n < MIN_TARE_SAMPLES:
        return TareCheck(False, f"only {n} samples (at least {MIN_TARE_SAMPLES})", n)
    sf, st = _reference_spread(np.zeros((0, 6)) if reference is None else reference)
    fig = {"reference_force_std": sf, "reference_torque_std": st}
    if np.isfinite(sf) and (sf >= TARE_STILL_FORCE_STD_N or st >= TARE_STILL_TORQUE_STD_NM):
        return TareCheck(False, f"the reference moved: spread {sf:.3f} N, {st * 1000:.2f} mN·m (limits "
                                f"{TARE_STILL_FORCE_STD_N} N, {TARE_STILL_TORQUE_STD_NM * 1000:g} mN·m) — hold still", n, **fig)
    if calibration is None:
        if not np.isfinite(sf):
            return TareCheck(False, "no reference and no calibration: nothing tells that the cube is still and "
                                    "unloaded — load a calibration first", n, **fig)
        return TareCheck(True, "", n, **fig)
    W = np.asarray(calibration.wrenches(c), dtype=float)  # (n, 6, 6) from the calibration's own zero
    F = np.linalg.norm(W[..., :3], axis=2)
    T = np.linalg.norm(W[..., 3:], axis=2)
    spread = np.nanmax(W[..., :3].std(axis=0), axis=1)  # (6,) N
    mean_f, mean_t = np.nan_to_num(F.mean(axis=0)), np.nan_to_num(T.mean(axis=0))
    k = int(np.argmax(mean_f))
    fig.update(face_load=float(mean_f[k]), face_torque=float(mean_t.max()), face=k + 1)
    moving = np.nan_to_num(spread) >= FACE_STILL_FACTOR * TARE_STILL_FORCE_STD_N
    if moving.any():
        j = int(np.argmax(np.nan_to_num(spread)))
        return TareCheck(False, f"face {j + 1} is moving: spread {spread[j]:.3f} N (limit "
                                f"{FACE_STILL_FACTOR * TARE_STILL_FORCE_STD_N:g} N) — hold still", n, **fig)
    if mean_f[k] >= TARE_NO_LOAD_FORCE_N or mean_t.max() >= TARE_NO_LOAD_TORQUE_NM:
        j = k if mean_f[k] >= TARE_NO_LOAD_FORCE_N else int(np.argmax(mean_t))
        return TareCheck(False, f"face {j + 1} carries {mean_f[j]:.2f} N, {mean_t[j] * 1000:.1f} mN·m from the "
                                f"calibration's zero (limits {TARE_NO_LOAD_FORCE_N} N, "
                                f"{TARE_NO_LOAD_TORQUE_NM * 1000:g} mN·m) — take every load off the cube, its "
                                "weight on a support included", n, **fig)
    return TareCheck(True, "", n, **fig)


def tare_event(counts, reference, *, from_tick, duration: float, previous_bias, **extra) -> dict:
    """The tare event of a window: ``counts_offset`` (36,) counts, ``reference_bias`` (6,) N and N·m.

    ``reference (n, 6)`` may hold NaN rows (no reference paired): the bias is the mean of the finite
    rows, or ``previous_bias`` without any. ``from_tick`` (µs) is the first cube tick it applies
    to; ``extra`` fields are added (e.g. ``host_time``, ``check``).
    """
    c = np.asarray(counts, dtype=float)
    r = np.asarray(reference, dtype=float).reshape(-1, 6)
    finite = np.isfinite(r).all(axis=1)
    bias = r[finite].mean(axis=0) if finite.any() else np.asarray(previous_bias, dtype=float)
    return {"type": "tare", "counts_offset": c.mean(axis=0).tolist(), "reference_bias": bias.tolist(),
            "duration": float(duration), "from_tick": None if from_tick is None else int(from_tick), **extra}

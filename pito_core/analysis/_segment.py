"""Trials and phases from the normal force on each patch (docs/analysis.md, "Trials").

A patch is *in contact* while its normal force exceeds ``contact_force`` (runs shorter than
``min_contact`` are ignored). A *trial* is a run in which some finger patch (any patch but
the base) is in contact, at least ``min_fingers`` of them at once, lasting at least
``min_duration``. In a trial with a base patch on the table:

========  =====================================================================
load      first finger contact → lift-off (the base's contact ends)
lift      lift-off → lift-off + ``lift_phase``
hold      end of lift → start of replace
replace   touch-down − ``replace_phase`` → touch-down (the base's contact starts again)
release   touch-down → last finger contact ends
========  =====================================================================

Without a base patch (``base_face = 0``) or when the base never leaves the table, the whole
trial is one phase, ``hold`` or ``load`` respectively — or ``release`` for a trial the recording
catches already under way (fingers on at its first sample) on an object resting on its base: only
the letting go is seen.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields

import numpy as np

from .. import defaults

__all__ = ["AnalysisSettings", "Trial", "PHASES", "segment_trials", "trials_from_contacts", "contact_runs"]

#: Phase names in the order they occur.
PHASES = ("load", "lift", "hold", "replace", "release")


@dataclass(frozen=True)
class AnalysisSettings:
    """Thresholds of the segmentation and the metrics (defaults: :mod:`pito_core.defaults`).

    Attributes
    ----------
    contact_force : float
        N (``TRIAL_CONTACT_FORCE_N``).
    min_contact : float
        s (``TRIAL_MIN_CONTACT_S``).
    min_fingers : int
        (``TRIAL_MIN_FINGERS``).
    min_duration : float
        s (``TRIAL_MIN_DURATION_S``).
    base_face : int
        1..6, 0 for none (``TRIAL_BASE_FACE``).
    lift_phase, replace_phase : float
        s (``LIFT_PHASE_S``, ``REPLACE_PHASE_S``).
    path_cutoff : float
        Hz (``CONTACT_PATH_CUTOFF_HZ``).
    single_contact_min : float
        Fraction in [0, 1] (``SINGLE_CONTACT_MIN_FRACTION``).
    mass : float or None
        Mass of the object, kg, for the force residual (None: from the recording or unknown).
    """

    contact_force: float = defaults.TRIAL_CONTACT_FORCE_N
    min_contact: float = defaults.TRIAL_MIN_CONTACT_S
    min_fingers: int = defaults.TRIAL_MIN_FINGERS
    min_duration: float = defaults.TRIAL_MIN_DURATION_S
    base_face: int = defaults.TRIAL_BASE_FACE
    lift_phase: float = defaults.LIFT_PHASE_S
    replace_phase: float = defaults.REPLACE_PHASE_S
    path_cutoff: float = defaults.CONTACT_PATH_CUTOFF_HZ
    single_contact_min: float = defaults.SINGLE_CONTACT_MIN_FRACTION
    mass: float | None = None

    def __post_init__(self):
        for f in fields(self):
            v = getattr(self, f.name)
            if f.name == "mass":
                if v is not None and not (np.isfinite(v) and v > 0):
                    raise ValueError(f"mass: expected > 0 kg or None, got {v!r}")
            elif f.name == "base_face":
                if v not in range(0, 7):
                    raise ValueError(f"base_face: expected 1..6 or 0 (none), got {v!r}")
            elif f.name == "min_fingers":
                if not (isinstance(v, (int, np.integer)) and 1 <= v <= 6):
                    raise ValueError(f"min_fingers: expected an integer 1..6, got {v!r}")
            elif not (np.isfinite(v) and v >= 0):
                raise ValueError(f"{f.name}: expected a finite value >= 0, got {v!r}")
        if not 0 <= self.single_contact_min <= 1:
            raise ValueError(f"single_contact_min: expected a fraction in [0, 1], got {self.single_contact_min!r}")


@dataclass
class Trial:
    """One trial: its span, phases and each patch's contact onset (s, recording time).

    Attributes
    ----------
    index : int
        1-based.
    start, stop : float
        s.
    phases : dict
        Phase name → ``(start, stop)`` in s (only the phases that occur).
    onset : dict
        Face (1..6) → time its contact starts in the trial, s (patches in contact only).
    lift_off, touch_down : float
        s (NaN when it does not occur).
    """

    index: int
    start: float
    stop: float
    phases: dict = field(default_factory=dict)
    onset: dict = field(default_factory=dict)
    lift_off: float = float("nan")
    touch_down: float = float("nan")


def contact_runs(on, time, min_run: float) -> np.ndarray:
    """``on (N,)`` bool with runs (of either value) shorter than ``min_run`` s flipped (debounce)."""
    on = np.asarray(on, bool).copy()
    if on.size < 2:
        return on
    for value in (False, True):  # fill short gaps, then drop short blips
        edges = np.flatnonzero(np.diff(on.astype(np.int8))) + 1
        starts = np.r_[0, edges]
        stops = np.r_[edges, on.size]
        for a, b in zip(starts, stops):
            if on[a] == value and a > 0 and b < on.size and time[b - 1] - time[a] < min_run:
                on[a:b] = not value
    return on


def segment_trials(time, normal_force, settings: AnalysisSettings | None = None) -> list[Trial]:
    """The trials of a recording from each patch's normal force (module docstring).

    Parameters
    ----------
    time : ndarray, shape (N,)
        s, increasing.
    normal_force : ndarray, shape (N, 6)
        Pushing-in normal force on each patch, N (0 where no contact).
    settings : AnalysisSettings, optional

    Returns
    -------
    list of Trial
    """
    s = settings or AnalysisSettings()
    t = np.asarray(time, float)
    fn = np.asarray(normal_force, float)
    if fn.shape != (t.size, 6):
        raise ValueError(f"normal_force: expected shape ({t.size}, 6), got {fn.shape}")
    on = np.stack([contact_runs(fn[:, i] > s.contact_force, t, s.min_contact) for i in range(6)], axis=1)
    return trials_from_contacts(t, on, s)


def trials_from_contacts(time, on, settings: AnalysisSettings | None = None) -> list[Trial]:
    """The trials from each patch's (debounced) contact state ``on (N, 6)`` bool at ``time (N,)`` s."""
    s = settings or AnalysisSettings()
    t = np.asarray(time, float)
    on = np.asarray(on, bool)
    if on.shape != (t.size, 6):
        raise ValueError(f"on: expected shape ({t.size}, 6), got {on.shape}")
    fingers = [i for i in range(6) if i + 1 != s.base_face]
    n_on = on[:, fingers].sum(axis=1)
    grasp = contact_runs(n_on > 0, t, s.min_contact)
    edges = np.flatnonzero(np.diff(np.r_[0, grasp.astype(np.int8), 0]))
    trials = []
    for a, b in zip(edges[::2], edges[1::2]):
        if t[b - 1] - t[a] < s.min_duration or n_on[a:b].max() < s.min_fingers:
            continue
        tr = Trial(len(trials) + 1, float(t[a]), float(t[b - 1]))
        for i in range(6):
            k = np.flatnonzero(on[a:b, i])
            if k.size:
                tr.onset[i + 1] = float(t[a + k[0]])
        _phases(tr, t[a:b], on[a:b, s.base_face - 1] if s.base_face else None, s)
        if a == 0 and list(tr.phases) == ["load"]:  # caught mid-release: resting, the fingers only let go
            tr.phases = {"release": tr.phases["load"]}
        trials.append(tr)
    return trials


def _phases(tr: Trial, t, base_on, s: AnalysisSettings) -> None:
    """Fill ``tr.phases``, ``lift_off``, ``touch_down`` from the base patch's contact in the trial."""
    if base_on is None or not base_on[0]:
        tr.phases["hold"] = (tr.start, tr.stop)
        return
    off = np.flatnonzero(~base_on)
    if not off.size:
        tr.phases["load"] = (tr.start, tr.stop)
        return
    tr.lift_off = float(t[off[0]])
    back = np.flatnonzero(base_on[off[0]:])
    tr.touch_down = float(t[off[0] + back[0]]) if back.size else float("nan")
    end_air = tr.touch_down if back.size else tr.stop
    lift_end = min(tr.lift_off + s.lift_phase, end_air)
    replace_start = max(lift_end, end_air - s.replace_phase) if back.size else end_air
    tr.phases["load"] = (tr.start, tr.lift_off)
    tr.phases["lift"] = (tr.lift_off, lift_end)
    if replace_start > lift_end:
        tr.phases["hold"] = (lift_end, replace_start)
    if back.size:
        tr.phases["replace"] = (replace_start, tr.touch_down)
        tr.phases["release"] = (tr.touch_down, tr.stop)

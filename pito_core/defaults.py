"""User-facing defaults of pito, named by meaning, in one place.

The core, the CLI (``--help`` prints these values) and the app read them from here, so
the same quantity never carries two defaults in two rooms. Tolerances (numerical slack,
not user-facing) live in each package's ``_tol`` module instead.

Wrench component order is ``[fx, fy, fz, tx, ty, tz]``: N and N·m.
"""

from __future__ import annotations

__all__ = [
    "FULL_SCALE_FORCE_N",
    "FULL_SCALE_TORQUE_NM",
    "FULL_SCALE_FRAME_TORQUE_NM",
    "FULL_SCALE_FACE",
    "FULL_SCALE_FRAME",
    "IDENTIFY_FORCE_N",
    "SHOW_CONTACT_FORCE_N",
    "LOADED_FORCE_N",
    "LOADED_TORQUE_NM",
    "TARE_STILL_FORCE_STD_N",
    "TARE_STILL_TORQUE_STD_NM",
    "TARE_NO_LOAD_FORCE_N",
    "TARE_NO_LOAD_TORQUE_NM",
    "TRIAL_CONTACT_FORCE_N",
    "TRIAL_MIN_CONTACT_S",
    "TRIAL_MIN_FINGERS",
    "TRIAL_MIN_DURATION_S",
    "TRIAL_BASE_FACE",
    "LIFT_PHASE_S",
    "REPLACE_PHASE_S",
    "CONTACT_PATH_CUTOFF_HZ",
    "SINGLE_CONTACT_MIN_FRACTION",
]

#: A tare is still when the reference's standard deviation over it stays under these (N, N·m)
#: (the wizard's and the live view's tare: ``pito_core.pipeline.check_tare``).
TARE_STILL_FORCE_STD_N = 0.05
TARE_STILL_TORQUE_STD_NM = 0.0005
#: A tare is unloaded when no face reads more than these from the calibration's own zero (N, N·m);
#: the face wrenches' spread over the tare must stay under the stillness limits times 4 (cube noise).
TARE_NO_LOAD_FORCE_N = 0.5
TARE_NO_LOAD_TORQUE_NM = 0.01

#: Calibration load range of one face, per force axis, N (the papers' protocol: ±15 N).
FULL_SCALE_FORCE_N = 15.0
#: Calibration load range of one face, per torque axis, N·m (the papers' protocol: ±0.1 N·m).
FULL_SCALE_TORQUE_NM = 0.1
#: Scale of the moments through the frame's screw joints about the core centre, N·m
#: (~0.4 N·m for a 15 N force on a face of a 50 mm cube).
FULL_SCALE_FRAME_TORQUE_NM = 0.4
#: Full scale of one face, face frame, ``[fx, fy, fz, tx, ty, tz]`` in N and N·m.
FULL_SCALE_FACE = (FULL_SCALE_FORCE_N,) * 3 + (FULL_SCALE_TORQUE_NM,) * 3
#: Full scale of the total load through the frame, core frame, N and N·m.
FULL_SCALE_FRAME = (FULL_SCALE_FORCE_N,) * 3 + (FULL_SCALE_FRAME_TORQUE_NM,) * 3

#: Force (N) below which ``pito_core.contact.solve`` locates no contact (``valid = False``):
#: the smallest force whose line of action is still worth solving for.
IDENTIFY_FORCE_N = 0.05
#: Force (N) below which the live view, the live pipeline and recordings' replays show no
#: contact on a face (above the noise of a calibrated face at rest).
SHOW_CONTACT_FORCE_N = 0.3
#: A face counts as loaded, when evaluating a calibration, if its force norm exceeds this, N …
LOADED_FORCE_N = 0.5
#: … or its torque norm exceeds this, N·m.
LOADED_TORQUE_NM = 0.01

# ---- grasp analysis (pito_core.analysis, `pito analyze`, docs/analysis.md) ----
#: A patch is in contact (trial segmentation, contact onset) while the normal force of its
#: contact exceeds this, N.
TRIAL_CONTACT_FORCE_N = 0.5
#: In-contact or out-of-contact runs shorter than this are ignored (debounce), s.
TRIAL_MIN_CONTACT_S = 0.05
#: A trial is a grasp in which at least this many finger patches (patches other than the
#: base) are in contact at once.
TRIAL_MIN_FINGERS = 2
#: Trials shorter than this (first finger contact to last finger release) are dropped, s.
TRIAL_MIN_DURATION_S = 0.5
#: The face whose patch rests on the table between lifts (lift-off: its contact ends;
#: replace: it starts again). 0 for a free grasp (no table): the whole trial is ``hold``.
TRIAL_BASE_FACE = 6
#: Length of the ``lift`` phase after lift-off (the object accelerates), s.
LIFT_PHASE_S = 0.4
#: Length of the ``replace`` phase before the base touches the table again, s.
REPLACE_PHASE_S = 0.4
#: Cut-off of the zero-phase low-pass filter applied to each contact path before its length
#: and spread are measured (the solver's noise would otherwise add up along the path), Hz.
CONTACT_PATH_CUTOFF_HZ = 5.0
#: A phase is *plausible* only if every contact in it is flagged a single contact
#: (``single_contact``) in at least this fraction of its samples in contact.
SINGLE_CONTACT_MIN_FRACTION = 0.95

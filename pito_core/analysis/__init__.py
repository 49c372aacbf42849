"""Grasp science: trials, grasp metrics and tidy tables for a recording; a study on Dask.

>>> from pito_core.analysis import analyze_recording          # doctest: +SKIP
>>> a = analyze_recording("grasp.pitorec")                    # the recording's own calibration
>>> a.phases[["trial", "phase", "grip_force_N", "load_force_N", "internal_force_N"]]

The metrics (docs/analysis.md) are pure numpy (:mod:`._grasp`); the tables need ``pandas``
and a study ``dask[distributed]`` (the optional extra ``pito[analysis]``): both are imported
only where they are used, and a missing one raises ImportError naming the extra.
"""

from ._analyze import GraspAnalysis, analyze_contacts, analyze_recording, recording_contacts, require_pandas
from ._grasp import grasp_decomposition, net_wrench, normal_tangential
from ._metrics import GRAVITY_MS2, PATCH_COLUMNS, PHASE_COLUMNS
from ._segment import PHASES, AnalysisSettings, Trial, contact_runs, segment_trials, trials_from_contacts
from ._series import ContactArrays, GraspSeries, grasp_series, smooth_paths

__all__ = [
    "AnalysisSettings",
    "ContactArrays",
    "GRAVITY_MS2",
    "GraspAnalysis",
    "GraspSeries",
    "PATCH_COLUMNS",
    "PHASES",
    "PHASE_COLUMNS",
    "Trial",
    "analyze_contacts",
    "analyze_recording",
    "contact_runs",
    "grasp_decomposition",
    "grasp_series",
    "net_wrench",
    "normal_tangential",
    "recording_contacts",
    "require_pandas",
    "segment_trials",
    "smooth_paths",
    "trials_from_contacts",
]

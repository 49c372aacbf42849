"""Grasp science: trials, grasp metrics and tidy tables for a recording; a study on Dask.

>>> from pito_core.analysis import analyze_recording          # doctest: +SKIP
>>> a = analyze_recording("grasp.pitorec")                    # the recording's own calibration
>>> a.phases[["trial", "phase", "grip_force_N", "load_force_N", "internal_force_N"]]

The metrics are pure numpy (:mod:`._grasp`, docs/analysis.md); the tables need ``pandas`` and
a study ``dask[distributed]`` (the optional extra ``pito[analysis]``), imported only where
they are used: a missing one raises ImportError naming the extra.

The settings, the column descriptions and the grasp functions load at once (``pito --help``
reads them); the recording path (pipeline, scipy.signal), the figures (matplotlib) and the
study (Dask) load on first use of one of their names (PEP 562 module ``__getattr__``), so
``pito`` starts without them.
"""

import importlib

from ._grasp import grasp_decomposition, net_wrench, normal_tangential
from ._metrics import GRAVITY_MS2, PATCH_COLUMNS, PHASE_COLUMNS
from ._segment import PHASES, AnalysisSettings, Trial, contact_runs, segment_trials, trials_from_contacts

#: What ``write_analysis(figures=…)`` and ``pito analyze --figures`` draw: nothing, one overview figure per
#: recording (the default), or the overview and a figure per trial.
FIGURE_CHOICES = ("none", "overview", "trials")

#: Names loaded on first use → their module.
_LAZY = {
    "GraspAnalysis": "_analyze", "analyze_contacts": "_analyze", "analyze_data": "_analyze",
    "analyze_recording": "_analyze", "recording_contacts": "_analyze", "require_pandas": "_analyze",
    "GraspSeries": "_series", "check_contacts": "_series", "grasp_series": "_series", "smooth_paths": "_series",
    "save_trial_figures": "_figures", "trial_figure": "_figures", "overview_figure": "_figures",
    "save_overview_figure": "_figures",
    "analyze_to_dir": "_output", "atomic_dir": "_output", "export_to_dir": "_output", "output_dir": "_output",
    "write_analysis": "_output", "peak_rss_mib": "_output", "cpu_seconds": "_output",
    "StudyResult": "_study", "local_cluster": "_study", "require_distributed": "_study", "run_serial": "_study",
    "run_study": "_study",
}

__all__ = [
    "FIGURE_CHOICES",
    "AnalysisSettings",
    "GRAVITY_MS2",
    "PATCH_COLUMNS",
    "PHASES",
    "PHASE_COLUMNS",
    "Trial",
    "contact_runs",
    "grasp_decomposition",
    "net_wrench",
    "normal_tangential",
    "segment_trials",
    "trials_from_contacts",
    *sorted(_LAZY),
]


def __getattr__(name):
    if name in _LAZY:
        value = getattr(importlib.import_module(f"{__name__}.{_LAZY[name]}"), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return sorted(__all__)

"""File → Analyse recording: trials, per-trial figures and the grasp metrics tables.

The analysis is :func:`pito_core.analysis.analyze_recording` (the same as ``pito analyze``),
run off the GUI thread with a progress bar and Cancel (:func:`app.tasks.run_task`).
"""

from ._menu import install_analysis_menu

_LAZY = {"AnalysisDialog": "_dialog", "AnalysisResult": "_dialog", "run_analysis": "_dialog", "DataFrameModel": "_table"}


def __getattr__(name):  # the dialog loads the analysis (seconds): only when asked for, not at start-up
    if name in _LAZY:
        from importlib import import_module

        return getattr(import_module(f"{__name__}.{_LAZY[name]}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")

__all__ = ["AnalysisDialog", "AnalysisResult", "DataFrameModel", "install_analysis_menu", "run_analysis"]

"""File → Analyse recording: trials, per-trial figures and the grasp metrics tables.

The analysis is :func:`pito_core.analysis.analyze_recording` (the same as ``pito analyze``),
run off the GUI thread with a progress bar and Cancel (:func:`app.tasks.run_task`).
"""

from ._dialog import AnalysisDialog, AnalysisResult, install_analysis_menu, run_analysis
from ._table import DataFrameModel

__all__ = ["AnalysisDialog", "AnalysisResult", "DataFrameModel", "install_analysis_menu", "run_analysis"]

"""File → Analyse recording…: the menu entry, without loading the analysis until it is opened."""

from __future__ import annotations

from ..file_menu import add_dialog_action

__all__ = ["install_analysis_menu"]


def _make_dialog(window, recording_path):
    # deferred: the analysis (pandas, scipy.signal) costs seconds at start-up and is needed only here
    from ._dialog import AnalysisDialog

    return AnalysisDialog(window, recording_path)


def install_analysis_menu(window):
    """Add File → Analyse recording… to ``window``'s menu bar (creating the File menu if absent)."""
    return add_dialog_action(window, "Analyse recording… (trials, grasp metrics)", _make_dialog, "analysis")

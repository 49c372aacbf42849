"""File → Analyse recording: the analysis in the background, trial list, figures, tables; cancel."""

import pytest

pytest.importorskip("PySide6")

pytestmark = pytest.mark.gui


def test_dialog_analyses_in_the_background_and_shows_each_trial(qtbot, lift_recording, tmp_path):
    from app.analysis import AnalysisDialog

    path, task, _ = lift_recording
    dlg = AnalysisDialog(recording=str(path))
    qtbot.addWidget(dlg)
    seen = []
    t = dlg.start()
    t.progressed.connect(lambda f, s: seen.append(f))
    qtbot.waitUntil(lambda: dlg.result is not None or "failed" in dlg.status.text(), timeout=120000)
    assert "failed" not in dlg.status.text(), dlg.status.text()
    assert dlg.trials.count() == task.n_trials and "SIMULATED" in dlg.status.text()
    assert dlg.trials.item(0).text().startswith("Trial 1: ")
    assert not dlg.figure.pixmap().isNull()
    assert dlg.phases_model.rowCount() == 5 and dlg.patches_model.rowCount() > 0
    dlg.trials.setCurrentRow(2)
    assert set(dlg.phases_model.frame["trial"]) == {3}
    from PySide6.QtCore import Qt

    header = [dlg.phases_model.headerData(i, Qt.Orientation.Horizontal) for i in range(dlg.phases_model.columnCount())]
    assert "grip_force_N" in header and "plausible" in header
    written = dlg._save(str(tmp_path))
    assert {p.name for p in written} >= {"phases.csv", "patches.csv", "trial_01.png"}
    assert seen and seen == sorted(seen)


def test_cancel_delivers_nothing_and_bad_input_names_the_field(qtbot, lift_recording, tmp_path):
    from app.analysis import AnalysisDialog

    path, _, _ = lift_recording
    dlg = AnalysisDialog(recording=str(path))
    qtbot.addWidget(dlg)
    t = dlg.start()
    t.cancel()
    qtbot.waitUntil(lambda: not t.running, timeout=10000)
    qtbot.wait(200)
    assert dlg.result is None and dlg.run_button.isEnabled()
    dlg.recording.setText(str(tmp_path / "missing.pitorec"))
    assert dlg.start() is None and dlg.status.text().startswith("Recording:")


def test_menu_action_opens_the_dialog(qtbot):
    from PySide6.QtWidgets import QMainWindow

    from app.analysis import AnalysisDialog, install_analysis_menu

    win = QMainWindow()
    qtbot.addWidget(win)
    action = install_analysis_menu(win)
    action.trigger()
    assert isinstance(win.analysis_dialog, AnalysisDialog) and win.analysis_dialog.isVisible()
    win.analysis_dialog.close()

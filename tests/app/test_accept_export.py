"""Accept and Export on the results page (issue 21, defects 7 and 11): accepting applies the
calibration to the live view (the header names it) and disables the button; Export says where
the report went, with a link to open the folder; the save dialog proposes ``.pitocal``."""

import numpy as np
import pytest

pytestmark = pytest.mark.needs_display


@pytest.fixture
def window(qtbot, styled):
    from app.window import MainWindow

    w = MainWindow(demo=False)
    qtbot.addWidget(w)
    yield w
    w.shutdown()
    w.release_views()


def test_accept_applies_to_the_live_view_and_disables(window, fitted, qtbot):
    from pito_core.io import calibration_hash, short_hash

    cal, ev = fitted
    page = window.wizard.pages["results"]
    window.model.set_result(cal, ev)
    page.refresh()
    assert page.accept_btn.isEnabled() and window.calibration is None
    page.accept_btn.click()
    assert window.calibration is cal
    assert short_hash(calibration_hash(cal)) in window.cal_label.text() and "wizard" in window.cal_label.text()
    assert not page.accept_btn.isEnabled() and "live view" in page.accept_btn.text()
    qtbot.waitUntil(lambda: window.feed.calibration is cal, timeout=3000)  # no source: kept for the next one


def test_export_says_where_the_report_went(window, fitted, qtbot, tmp_path):
    cal, ev = fitted
    page = window.wizard.pages["results"]
    window.model.set_result(cal, ev)
    page.accept()
    page.export(tmp_path / "report")
    qtbot.waitUntil(lambda: not page.exporting, timeout=60000)
    text = page.exported_label.text()
    assert page.exported_label.isVisibleTo(page) and str(tmp_path / "report") in text and "Open folder" in text
    assert "report.md" in text and "identification.png" in text
    assert "report exported to" in page.values["status"].text()  # survives the refresh at the task's end


def test_save_proposes_pitocal(window, fitted, monkeypatch, tmp_path):
    from PySide6.QtWidgets import QFileDialog

    cal, ev = fitted
    page = window.wizard.pages["results"]
    window.model.set_result(cal, ev)
    page.accept()
    seen = {}

    def fake(parent, title, name, filt):
        seen.update(name=name, filter=filt)
        return str(tmp_path / "mine"), filt

    monkeypatch.setattr(QFileDialog, "getSaveFileName", fake)
    path = page.save()
    assert seen["name"].endswith(".pitocal") and "*.pitocal" in seen["filter"]
    assert path.endswith(".pitocal") and (tmp_path / "mine.pitocal").exists()


@pytest.mark.slow
def test_a_refit_forgets_the_file_and_the_report_of_the_previous_fit(window, fitted, qtbot, tmp_path):
    """Issue 45, point 3: after "Use the papers' linear fit (refit)" the status no longer says saved
    nor exported — that file and that report hold the previous calibration."""
    from pito_core.sim import simulate_calibration

    cal, ev = fitted
    page = window.wizard.pages["results"]
    window.model.set_mount(method="loaded_frame", flange="frame_hole", connected_face=6)
    window.model.set_result(cal, ev)
    page.accept()
    page.save(tmp_path / "first.pitocal")
    page.export(tmp_path / "report")
    qtbot.waitUntil(lambda: not page.exporting, timeout=60000)
    status = page.values["status"].text()
    assert "saved to first.pitocal" in status and "report exported to" in status
    session = simulate_calibration("frame_hole", 6, k=150, seed=3)  # SIMULATED
    page.model_box.linear.blockSignals(True)
    page.model_box.linear.setChecked(True)  # the refit's model, fitted on the given session
    page.model_box.linear.blockSignals(False)
    page.compute(session)
    qtbot.waitUntil(lambda: not page.fitting and window.model.calibration is not cal, timeout=120000)
    status = page.values["status"].text()
    assert window.model.calibration.model.name == "linear"
    assert "saved" not in status and "exported" not in status, status
    assert "awaiting your decision" in status and not page.exported_label.isVisibleTo(page)
    assert window.model.saved_path is None

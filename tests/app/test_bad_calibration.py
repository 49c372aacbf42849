"""A bad ``--calibration`` file (issue 21, defect 10): a dialog, one line in the terminal (no
traceback), and a window that says prominently it runs without a calibration."""

import pytest

pytestmark = pytest.mark.needs_display


def test_bad_calibration_file_is_a_clear_state(qtbot, styled, tmp_path, monkeypatch, capfd):
    from PySide6.QtWidgets import QMessageBox

    from app.window import MainWindow

    bad = tmp_path / "broken.pitocal"
    bad.write_bytes(b"not an HDF5 file")
    dialogs = []
    monkeypatch.setattr(QMessageBox, "warning", lambda parent, title, text: dialogs.append(text))
    window = MainWindow(demo=False, calibration_path=bad)
    qtbot.addWidget(window)
    window.resize(1440, 900)
    window.show()
    try:
        qtbot.waitUntil(lambda: bool(dialogs), timeout=10000)
        assert str(bad) in dialogs[0] and "without a calibration" in dialogs[0]
        assert window.cal_label.text() == "NO CALIBRATION"
        notice = window.live.notice
        assert notice.isVisible() and "No calibration" in notice.text() and "broken.pitocal" in notice.text()
        assert notice.height() >= 30  # prominent, above the view (not a status bar line behind the task bar)
        err = capfd.readouterr().err
        assert "Traceback" not in err
        lines = [ln for ln in err.splitlines() if "broken.pitocal" in ln]
        assert len(lines) == 1 and lines[0].startswith("pito-app: ")
        # a good calibration afterwards clears the state
        from pito_core.sim import VirtualCube
        from pito_core.calibration import Calibration
        import numpy as np

        cube = VirtualCube()
        cal = Calibration("ideal", cube.ideal_calibration(), range(1, 7), "face", cube.offset, cube.core, np.eye(4))
        window.set_calibration(cal, "ideal (SIMULATED)")
        assert not notice.isVisible() and "ideal" in window.cal_label.text()
    finally:
        window.shutdown()
        window.release_views()

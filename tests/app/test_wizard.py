"""The whole calibration wizard on the simulators: real drivers over the pty / UDP simulators,
through every page, to a saved calibration that ``pito evaluate`` accepts."""

import json

import numpy as np
import pytest

pytestmark = [pytest.mark.needs_display, pytest.mark.slow]


def image_array(img):
    from PySide6.QtGui import QImage

    if not isinstance(img, QImage):
        img = img.toImage()
    img = img.convertToFormat(QImage.Format.Format_RGB888)
    w, h = img.width(), img.height()
    buf = np.frombuffer(img.constBits(), dtype=np.uint8, count=img.bytesPerLine() * h)
    return buf.reshape(h, img.bytesPerLine())[:, : 3 * w].reshape(h, w, 3).copy()


def region_of(window, widget):
    from PySide6.QtCore import QPoint

    p = widget.mapTo(window, QPoint(0, 0))
    return p.y(), p.y() + widget.height(), p.x(), p.x() + widget.width()


def test_wizard_end_to_end_on_the_simulators(qtbot, styled, tmp_path):
    from app.scene import grab_window
    from app.window import MainWindow
    from app.wizard.driver import complete_loading, finish, run_to_page
    from pito_core.calibration import CalibrationSession, evaluate, load_calibration
    from pito_core.cli import main as pito
    from pito_core.sim import simulate_calibration

    # the simulated devices at twice real time (2 kHz streams through the same drivers and pipeline): the
    # operator's waits halve (108 → 61 s)
    window = MainWindow(demo=True, demo_period=0.6, demo_speed=2.0, wizard_k=600, demo_k=800)
    qtbot.addWidget(window)
    window.resize(1440, 900)
    window.show()
    qtbot.waitExposed(window)
    cal_path = tmp_path / "wizard.h5"
    report = tmp_path / "report"
    try:
        run_to_page(window, "load", k=600, timeout=150)
        # the loading page: every face done, its 3D view drawn (not blank)
        load = window.wizard.pages["load"]
        assert load.is_ready() and window.wizard.next.isEnabled()
        img = image_array(grab_window(window))  # the 3D views are native windows
        y0, y1, x0, x1 = region_of(window, load.scene)
        assert img[y0:y1, x0:x1].std() > 10 and len(np.unique(img[y0:y1, x0:x1].reshape(-1, 3), axis=0)) > 50
        # undo works and takes Next away until the face is covered again
        model = window.model
        face = model.current_face
        n = len(model.captures[face].captures)
        load.undo.click()
        assert len(model.captures[face].captures) == n - 1
        if n - 1 < model.rules.min_captures:
            assert not load.is_ready()
        complete_loading(window, timeout=150)  # the simulated operator covers the face again
        finish(window, save_path=cal_path, report_dir=report)
        assert window.wizard.current_name == "results"
        assert model.accepted and cal_path.exists()
        assert window.errors == []
        session = model.session()
        assert session.meta["simulated"] and session.loaded.any(axis=1).sum() >= 6 * 600
    finally:
        window.shutdown()
        window.release_views()

    # the saved file is a calibration that evaluates well on new simulated data of the same cube
    cal = load_calibration(cal_path)
    assert cal.method == "loaded_frame" and cal.has_output.all()
    held = simulate_calibration("frame_hole", 6, k=300, seed=11)
    held_path = tmp_path / "held_out.h5"
    held.save(held_path)
    assert pito(["evaluate", str(cal_path), str(held_path)]) == 0
    ev = evaluate(cal, CalibrationSession.load(held_path))
    # as good as an offline fit on the same simulated cube (~0.2–0.4 N, 1–2.5 mN·m per face)
    assert np.nanmax(ev.rmse_force()) < 1.0  # N, against ±15 N full scale
    assert np.nanmax(ev.rmse_torque()) < 0.006  # N·m, against ±0.1 N·m
    # the exported report: figures and numbers
    for name in ("report.md", "numbers.json", "rmse.png", "identification.png", "comparison.png"):
        assert (report / name).stat().st_size > 0
    numbers = json.loads((report / "numbers.json").read_text())
    assert numbers["calibration"]["method"] == "loaded_frame" and numbers["info"]["simulated"] is True


def test_method_page_explains_every_method(qtbot, styled):
    from app.wizard.model import WizardModel
    from app.wizard.wizard import CalibrationWizard
    from pito_core.calibration import METHODS

    model = WizardModel()
    wiz = CalibrationWizard(model)
    qtbot.addWidget(wiz)
    try:
        check_method_and_mount_pages(wiz, model, METHODS)
    finally:
        for name in ("mount", "load"):
            wiz.pages[name].scene.close_scene()


def check_method_and_mount_pages(wiz, model, METHODS):
    page = wiz.pages["method"]
    assert set(page.buttons) == set(METHODS)
    page.buttons["quasi_total"].setChecked(True)
    assert model.method == "quasi_total" and model.flange == "frame"
    assert model.faces == (1, 2, 3, 4, 5)
    page.face.setValue(2)
    assert model.connected_face == 2 and 2 not in model.faces
    # the mount page follows the model, and Next waits for the operator's confirmation
    wiz.go("mount")
    assert not wiz.next.isEnabled()
    wiz.pages["mount"].confirm.setChecked(True)
    assert wiz.next.isEnabled()
    model.set_mount(method="total")  # a change of mount asks for a new confirmation
    assert model.flange == "face" and not wiz.next.isEnabled()

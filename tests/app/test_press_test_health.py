"""Issue 13: the press-test dialog and the status-bar health indicator (driven with synthetic bundles)."""

import time
from types import SimpleNamespace

import numpy as np
import pytest

pytest.importorskip("PySide6")

from app.health import HealthIndicator  # noqa: E402
from app.press_test import PressTestDialog  # noqa: E402
from pito_core.calibration import Calibration  # noqa: E402
from pito_core.frames import CubeCore  # noqa: E402
from pito_core.selftest import PRESS_PROTOCOL  # noqa: E402
from pito_core.sim import random_sensor  # noqa: E402


@pytest.fixture(scope="module")
def qapp():
    from PySide6.QtWidgets import QApplication

    return QApplication.instance() or QApplication([])


def test_health_indicator_says_stalled_and_counts(qapp):
    ind = HealthIndicator()
    ok = {"devices": {"pito": {"stalled": False}, "netft": None}}
    ind.on_bundle(SimpleNamespace(stats=ok, time=np.zeros(3)))
    ind.refresh()
    assert ind.text().startswith("devices ok")
    bad = {"devices": {"pito": {"stalled": True, "since_data_s": 0.15, "stalls": 1}, "netft": None}}
    ind.on_bundle(SimpleNamespace(stats=bad, time=np.zeros(0)))
    ind.refresh()
    assert "cube stalled" in ind.text() and ind.stalls == 1
    ind.on_bundle(SimpleNamespace(stats=ok, time=np.zeros(3)))
    ind.refresh()
    assert ind.text().startswith("devices ok") and "stalls: 1" in ind.text()
    ind.last_data = time.monotonic() - 1.0  # no bundle with samples for 1 s: the watchdog says so
    ind.refresh()
    assert "stalled" in ind.text() and ind.stalls == 2


def test_press_test_dialog_names_a_flipped_axis(qapp):
    sensor = random_sensor(3, condition=(1.0, 3.0), noise=(0.5, 1.0))
    M = np.linalg.inv(sensor.sensitivity)
    M[6 * 3 + 2] *= -1  # face 4 fz flipped
    cal = Calibration("total", M, range(1, 7), "face", sensor.offset, CubeCore(), np.eye(4))
    dlg = PressTestDialog(None, cal)
    rng = np.random.default_rng(0)

    def feed(W):
        dlg.on_bundle(SimpleNamespace(counts=sensor.offset + W.reshape(-1, 36) @ sensor.sensitivity.T
                                      + rng.normal(size=(len(W), 36))))

    dlg.advance()
    feed(np.zeros((40, 6, 6)))
    dlg.timer.stop()
    dlg._finish_phase()
    for st in PRESS_PROTOCOL:
        dlg.advance()
        W = np.zeros((40, 6, 6))
        W[:, st.face - 1] = np.asarray(st.direction, float) * (5.0 if st.action == "press" else 0.08)
        feed(W)
        dlg.timer.stop()
        dlg._finish_phase()
    assert dlg.result is not None and not dlg.result.passed
    assert dlg.result.findings == ["face 4: fz is flipped: the press read fz = " + dlg.result.findings[0].split("fz = ")[1]]
    assert "FAILED" in dlg.instruction.text()

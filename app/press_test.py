"""Tools → Press test: the guided units-and-signs self-test of the loaded calibration.

The dialog records 1 s at rest, then walks the operator through :data:`pito_core.selftest.PRESS_PROTOCOL`
(press face i along its normal, then twist it), recording the raw counts of each step for
``STEP_S`` seconds from the live bundles, and shows :func:`pito_core.selftest.check_press_test`'s
verdict: passed, or which axis of which face is flipped or swapped. The logic is in pito_core.
"""

from __future__ import annotations

import numpy as np
from PySide6.QtCore import QTimer
from PySide6.QtWidgets import QDialog, QHBoxLayout, QLabel, QPlainTextEdit, QPushButton, QVBoxLayout

from pito_core.frames import N_GAUGES
from pito_core.selftest import PRESS_PROTOCOL, check_press_test

__all__ = ["PressTestDialog", "install_press_test_menu", "STEP_S", "REST_S"]

#: Seconds recorded per step, and at rest before the test.
STEP_S = 2.0
REST_S = 1.0


class PressTestDialog(QDialog):
    """Guided press test. ``on_bundle(bundle)`` feeds it live counts; ``calibration`` is checked."""

    def __init__(self, parent, calibration, steps=PRESS_PROTOCOL):
        super().__init__(parent)
        self.setWindowTitle("Press test: units and signs of the calibration")
        self.calibration = calibration
        self.steps = tuple(steps)
        self.rest = None
        self.recorded: list[np.ndarray] = []
        self._buf: list[np.ndarray] | None = None
        self._phase = "idle"  # idle, rest, step, done
        self.result = None
        lay = QVBoxLayout(self)
        self.instruction = QLabel()
        self.instruction.setWordWrap(True)
        self.progress = QLabel()
        self.report = QPlainTextEdit()
        self.report.setReadOnly(True)
        row = QHBoxLayout()
        self.go = QPushButton("Start (keep the cube still)")
        self.close_button = QPushButton("Close")
        row.addWidget(self.go)
        row.addStretch(1)
        row.addWidget(self.close_button)
        lay.addWidget(self.instruction)
        lay.addWidget(self.progress)
        lay.addWidget(self.report, 1)
        lay.addLayout(row)
        self.go.clicked.connect(self.advance)
        self.close_button.clicked.connect(self.close)
        self.timer = QTimer(self)
        self.timer.setSingleShot(True)
        self.timer.timeout.connect(self._finish_phase)
        if calibration is None:
            self.instruction.setText("Load a calibration first (Live view → calibration): the press test checks it.")
            self.go.setEnabled(False)
        else:
            self.instruction.setText(
                f"{len(self.steps) // 2} faces × (press along the normal, then twist counter-clockwise seen from "
                "outside). First 1 s at rest: keep the cube still and press Start.")

    # ------------------------------------------------------------ data
    def on_bundle(self, bundle) -> None:
        counts = getattr(bundle, "counts", None)
        if self._buf is not None and counts is not None and len(counts):
            self._buf.append(np.asarray(counts, dtype=float))

    def _take(self) -> np.ndarray:
        buf, self._buf = self._buf or [], None
        return np.concatenate(buf) if buf else np.zeros((0, N_GAUGES))

    # ------------------------------------------------------------ flow
    def advance(self) -> None:
        """Record the next phase (rest, then each step) for its duration."""
        self.go.setEnabled(False)
        self._buf = []
        if self.rest is None:
            self._phase = "rest"
            self.progress.setText(f"recording {REST_S:g} s at rest…")
            self.timer.start(int(REST_S * 1000))
        else:
            step = self.steps[len(self.recorded)]
            self._phase = "step"
            self.progress.setText(f"recording {STEP_S:g} s: {step.instruction}")
            self.timer.start(int(STEP_S * 1000))

    def _finish_phase(self) -> None:
        data = self._take()
        if self._phase == "rest":
            if not len(data):
                self.report.appendPlainText("no samples at rest: are the devices streaming?")
                self.go.setEnabled(True)
                return
            self.rest = data
        else:
            if not len(data):
                self.report.appendPlainText("no samples in this step: repeat it")
                self.go.setEnabled(True)
                return
            self.recorded.append(data)
        if len(self.recorded) == len(self.steps):
            self.evaluate()
            return
        step = self.steps[len(self.recorded)]
        self.instruction.setText(f"Step {len(self.recorded) + 1}/{len(self.steps)}: {step.instruction} "
                                 "Press the button, then load the face for 2 s.")
        self.go.setText(f"Record: face {step.face} {step.action}")
        self.progress.setText("")
        self.go.setEnabled(True)

    def evaluate(self):
        self._phase = "done"
        self.result = check_press_test(self.calibration, self.rest, self.recorded, self.steps)
        self.instruction.setText(self.result.summary())
        self.report.appendPlainText("\n".join(c.finding for c in self.result.checks))
        self.go.setText("Done")
        self.go.setEnabled(False)
        return self.result


def install_press_test_menu(window):
    """Add Tools → Press test (units and signs)… to ``window``'s menu bar."""
    bar = window.menuBar()
    menu = next((a.menu() for a in bar.actions() if a.menu() is not None and a.text().replace("&", "") == "Tools"), None)
    if menu is None:
        menu = bar.addMenu("&Tools")
    action = menu.addAction("Press test (units and signs of the calibration)…")

    def show():
        dlg = PressTestDialog(window, getattr(window, "calibration", None))
        window.feed.bundle.connect(dlg.on_bundle)
        dlg.finished.connect(lambda *_: window.feed.bundle.disconnect(dlg.on_bundle))
        window.press_test_dialog = dlg
        dlg.show()

    action.triggered.connect(show)
    window.press_test_action = action
    return action

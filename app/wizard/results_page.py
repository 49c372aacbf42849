"""Step 6: results — held-out RMSE, face identification, comparison; accept, redo, save, export."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_qtagg import FigureCanvasQTAgg
from matplotlib.figure import Figure
from PySide6.QtCore import Qt
from PySide6.QtGui import QGuiApplication
from PySide6.QtWidgets import (
    QComboBox, QFileDialog, QGridLayout, QGroupBox, QHBoxLayout, QLabel, QPushButton,
)

from pito_core.calibration import calibrate

from .. import report
from .page import WizardPage

__all__ = ["ResultsPage", "fit_and_evaluate"]


def fit_and_evaluate(session, method: str, holdout: float = 0.25, seed: int = 0):
    """Fit ``method`` on a training split of ``session`` and evaluate it on the held-out rest.

    Returns ``(calibration, evaluation, note)``; ``note`` says if a minimum-norm fit was needed.
    """
    from pito_core.calibration import evaluate

    # blocks of 50 samples: every kept capture (a few hundred still samples) feeds both sides,
    # so the fit keeps every loaded direction and the held-out samples test it on new noise
    train, test = session.split(holdout=holdout, block=50, seed=seed)
    note = ""
    try:
        cal = calibrate(train, method)
    except ValueError as exc:
        if "excite" not in str(exc) and "rank" not in str(exc):
            raise
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            cal = calibrate(train, method, allow_rank_deficient=True)
        note = f"minimum-norm fit — {exc}"
    return cal, evaluate(cal, test), note


class ResultsPage(WizardPage):
    title = "6 · Results"
    help = ("The calibration was fitted on 75 % of the kept samples and checked on the held-out rest. "
            "Accept it, or redo a face whose error is too high; then save the calibration and export the report.")

    def __init__(self, model, parent=None):
        super().__init__(model, parent)
        grid_l = QGridLayout()
        nums = QGroupBox("Figures of merit")
        grid = QGridLayout(nums)
        self.values = {}
        for r, (key, text) in enumerate((
            ("method", "Method"),
            ("icn", "Inverse condition number σmin/σmax"),
            ("samples", "Samples: fitted / held out"),
            ("force", "Worst face force RMSE"),
            ("torque", "Worst face torque RMSE"),
            ("ident", "Face identification (held out)"),
            ("status", "Status"),
        )):
            grid.addWidget(QLabel(text), r, 0)
            lab = QLabel("—")
            lab.setObjectName("value")
            lab.setWordWrap(True)
            grid.addWidget(lab, r, 1)
            self.values[key] = lab
        self.fig_rmse = Figure(figsize=(6.4, 2.6), dpi=90)
        self.canvas_rmse = FigureCanvasQTAgg(self.fig_rmse)
        self.fig_ident = Figure(figsize=(3.6, 3.0), dpi=90)
        self.canvas_ident = FigureCanvasQTAgg(self.fig_ident)
        self.fig_comp = Figure(figsize=(6.4, 3.0), dpi=90)
        self.canvas_comp = FigureCanvasQTAgg(self.fig_comp)
        grid_l.addWidget(nums, 0, 0)
        grid_l.addWidget(self.canvas_ident, 1, 0)
        grid_l.addWidget(self.canvas_rmse, 0, 1)
        grid_l.addWidget(self.canvas_comp, 1, 1)
        grid_l.setColumnStretch(0, 2)
        grid_l.setColumnStretch(1, 3)
        grid_l.setRowStretch(0, 1)
        grid_l.setRowStretch(1, 1)
        self.body.addLayout(grid_l, 1)
        buttons = QHBoxLayout()
        self.accept_btn = QPushButton("Accept calibration")
        self.accept_btn.setObjectName("primary")
        self.redo_face = QComboBox()
        self.redo_btn = QPushButton("Redo face")
        self.save_btn = QPushButton("Save calibration…")
        self.export_btn = QPushButton("Export report…")
        for w in (self.accept_btn, QLabel("  "), self.redo_face, self.redo_btn):
            buttons.addWidget(w)
        buttons.addStretch(1)
        buttons.addWidget(self.save_btn)
        buttons.addWidget(self.export_btn)
        self.body.addLayout(buttons)
        self.accept_btn.clicked.connect(self.accept)
        self.redo_btn.clicked.connect(self._redo_clicked)
        self.save_btn.clicked.connect(lambda: self.save())
        self.export_btn.clicked.connect(lambda: self.export())
        self.note = ""
        #: set by the wizard: go back to the loading page for a face
        self.redo_requested = None

    # ------------------------------------------------------------ compute
    def enter(self) -> None:
        if self.model.calibration is None:
            self.compute()
        self.refresh()

    def compute(self) -> None:
        QGuiApplication.setOverrideCursor(Qt.CursorShape.WaitCursor)
        try:
            cal, ev, self.note = fit_and_evaluate(self.model.session(), self.model.method)
            self.model.set_result(cal, ev)
        except ValueError as exc:
            self.note = str(exc)
            self.model.set_result(None, None)
        finally:
            QGuiApplication.restoreOverrideCursor()

    def refresh(self) -> None:
        m = self.model
        cal, ev = m.calibration, m.evaluation
        self.redo_face.clear()
        for f in m.faces:
            self.redo_face.addItem(f"face {f}", f)
        has = cal is not None and ev is not None
        for b in (self.accept_btn, self.save_btn, self.export_btn):
            b.setEnabled(has)
        self.save_btn.setEnabled(has and m.accepted)
        self.export_btn.setEnabled(has and m.accepted)
        if not has:
            self.values["status"].setText(f"✘ fit failed: {self.note}")
            self.set_ready(False)
            return
        f, t = ev.rmse_force(), ev.rmse_torque()
        worst_f = int(np.nanargmax(f)) + 1 if np.isfinite(f).any() else None
        worst_t = int(np.nanargmax(t)) + 1 if np.isfinite(t).any() else None
        self.values["method"].setText(f"{cal.method}  (faces {', '.join(map(str, cal.output_faces))} out, "
                                      f"{'SIMULATED' if m.simulated else 'real'} devices)")
        self.values["icn"].setText(f"{cal.inverse_condition_number:.3e}")
        self.values["samples"].setText(f"{cal.meta.get('n_samples_fitted', '?')} / {ev.n_single}")
        self.values["force"].setText(f"{np.nanmax(f):.3f} N (face {worst_f})" if worst_f else "n/a")
        self.values["torque"].setText(f"{np.nanmax(t) * 1000:.2f} mN·m (face {worst_t})" if worst_t else "n/a")
        acc = (ev.identification.get("single") or {}).get("either")
        self.values["ident"].setText(f"{100 * acc:.1f} % of samples" if acc is not None else "n/a")
        status = "✔ accepted" if m.accepted else "awaiting your decision"
        if m.saved_path:
            status += f" — saved to {Path(m.saved_path).name}"
        if self.note:
            status += " — minimum-norm fit: some directions were weakly loaded (see tooltip)"
        self.values["status"].setText(status)
        self.values["status"].setToolTip(self.note)
        if worst_f:
            self.redo_face.setCurrentIndex(max(0, self.redo_face.findData(worst_f)))
        report.rmse_figure(ev, self.fig_rmse)
        report.identification_figure(ev, self.fig_ident)
        report.comparison_figure(ev, self.fig_comp)
        for c in (self.canvas_rmse, self.canvas_ident, self.canvas_comp):
            c.draw_idle()
        self.set_ready(m.accepted)

    # ------------------------------------------------------------ actions
    def accept(self) -> None:
        self.model.accepted = True
        self.refresh()

    def _redo_clicked(self) -> None:
        face = self.redo_face.currentData()
        if face is not None:
            self.redo(int(face))

    def redo(self, face: int) -> None:
        """Drop the face's captures and go back to loading it."""
        self.model.clear_face(face)
        self.model.set_current_face(face)
        if self.redo_requested is not None:
            self.redo_requested(face)

    def save(self, path=None):
        """Save the accepted calibration to ``path`` (asks if None); returns the path or None."""
        if self.model.calibration is None:
            return None
        if path is None:
            path, _ = QFileDialog.getSaveFileName(self, "Save calibration", f"pito-{self.model.method}.h5",
                                                  "PITO calibration (*.h5)")
            if not path:
                return None
        self.model.calibration.save(path)
        self.model.saved_path = str(path)
        self.refresh()
        return path

    def export(self, folder=None):
        """Export the report (figures + numbers) to ``folder`` (asks if None); returns report.md's path."""
        m = self.model
        if m.calibration is None:
            return None
        if folder is None:
            folder = QFileDialog.getExistingDirectory(self, "Export the report into a folder")
            if not folder:
                return None
        info = {
            "method": m.method, "flange": m.flange, "connected face": m.connected_face,
            "faces loaded": ", ".join(map(str, m.faces)), "samples per face (k)": m.rules.k,
            "simulated": m.simulated, "calibration file": m.saved_path or "(not saved)",
        }
        return report.export_report(folder, m.calibration, m.evaluation, info)

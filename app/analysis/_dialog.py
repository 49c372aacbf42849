"""The analysis dialog: pick a recording, analyse it in the background, browse trials, figures, tables."""

from __future__ import annotations

import io
from dataclasses import dataclass
from pathlib import Path

from PySide6.QtCore import Qt
from PySide6.QtGui import QPixmap
from PySide6.QtWidgets import (
    QDialog, QFileDialog, QHBoxLayout, QLabel, QLineEdit, QListWidget, QPushButton, QScrollArea, QSplitter,
    QTableView, QTabWidget, QVBoxLayout, QWidget,
)

from pito_core.calibration import load_calibration
from pito_core.analysis import analyze_recording, trial_figure, write_analysis

from ..tasks import TaskBar, run_task
from ._table import DataFrameModel
from ..fonts import use_app_font_in_matplotlib

use_app_font_in_matplotlib()  # the app's font in this module's figures (app/fonts.py)

__all__ = ["AnalysisDialog", "AnalysisResult", "run_analysis"]


@dataclass
class AnalysisResult:
    """The analysis and one PNG (bytes) per trial, made off the GUI thread."""

    analysis: object
    figures: list


def run_analysis(recording, calibration_path=None, progress=None) -> AnalysisResult:
    """Analyse ``recording`` and draw every trial's figure; ``progress(fraction, text)`` (cancels by raising)."""
    progress = progress or (lambda f, t: None)
    cal = load_calibration(calibration_path) if calibration_path else None
    a = analyze_recording(recording, cal, calibration_source=calibration_path,
                          progress=lambda f, t: progress(0.8 * f, t))
    pngs = []
    for k, tr in enumerate(a.trials):
        progress(0.8 + 0.2 * k / max(len(a.trials), 1), f"figure of trial {tr.index}")
        buf = io.BytesIO()
        trial_figure(a, tr).savefig(buf, format="png", dpi=80)
        pngs.append(buf.getvalue())
    progress(1.0, "done")
    return AnalysisResult(a, pngs)


def _trial_label(a, tr) -> str:
    ph = a.phases[a.phases["trial"] == tr.index]
    bad = [str(p) for p in ph.loc[ph["plausible"].eq(False).fillna(False), "phase"]]
    text = f"Trial {tr.index}: {tr.start:.2f}–{tr.stop:.2f} s, faces {' '.join(map(str, sorted(tr.onset)))}"
    return text + (f"  ⚠ not single contacts: {', '.join(bad)}" if bad else "")


class AnalysisDialog(QDialog):
    """Analyse a recording: trial list, per-trial figure, phases and patches tables; Save writes them."""

    def __init__(self, parent=None, recording: str | None = None):
        super().__init__(parent)
        self.setWindowTitle("Analyse a recording: trials and grasp metrics")
        self.resize(1100, 800)
        self.task = None
        self.result: AnalysisResult | None = None
        self.recording = QLineEdit(recording or "")
        self.calibration = QLineEdit("")
        self.calibration.setPlaceholderText("the recording's own (optional)")
        self.run_button = QPushButton("Analyse")
        self.run_button.clicked.connect(self.start)
        self.save_button = QPushButton("Save tables and figures…")
        self.save_button.setEnabled(False)
        self.save_button.clicked.connect(self._save)
        top = QHBoxLayout()
        for w in (QLabel("Recording"), self.recording, self._browse(self.recording, "PITO recording (*.pitorec)"),
                  QLabel("Calibration"), self.calibration, self._browse(self.calibration, "Calibration (*.h5 *.hdf5)"),
                  self.run_button, self.save_button):
            top.addWidget(w, 1 if isinstance(w, QLineEdit) else 0)
        self.bar = TaskBar()
        self.status = QLabel("")
        self.status.setWordWrap(True)
        self.trials = QListWidget()
        self.trials.currentRowChanged.connect(self.show_trial)
        self.figure = QLabel("")
        self.figure.setAlignment(Qt.AlignmentFlag.AlignCenter)
        scroll = QScrollArea()
        scroll.setWidget(self.figure)
        scroll.setWidgetResizable(True)
        self.phases_model, self.patches_model = DataFrameModel(), DataFrameModel()
        self.tables = QTabWidget()
        for name, model in (("Phases", self.phases_model), ("Patches", self.patches_model)):
            view = QTableView()
            view.setModel(model)
            self.tables.addTab(view, name)
        split = QSplitter(Qt.Orientation.Vertical)
        upper = QSplitter(Qt.Orientation.Horizontal)
        upper.addWidget(self.trials)
        upper.addWidget(scroll)
        upper.setSizes([300, 800])
        split.addWidget(upper)
        split.addWidget(self.tables)
        lay = QVBoxLayout(self)
        lay.addLayout(top)
        lay.addWidget(self.bar)
        lay.addWidget(self.status)
        lay.addWidget(split, 1)

    def _browse(self, edit, filt) -> QWidget:
        b = QPushButton("…")

        def pick():
            path, _ = QFileDialog.getOpenFileName(self, "Open", "", f"{filt};;All files (*)")
            if path:
                edit.setText(path)

        b.clicked.connect(pick)
        return b

    def start(self):
        """Analyse in the background; returns the :class:`~app.tasks.Task` (None on bad input)."""
        rec = self.recording.text().strip()
        if not rec or not Path(rec).is_file():
            self.status.setText(f"Recording: file not found: {rec!r}")
            return None
        cal = self.calibration.text().strip() or None
        self.run_button.setEnabled(False)
        self.status.setText("Analysing…")
        self.task = run_task(lambda progress: run_analysis(rec, cal, progress), "Analysing", on_done=self._done,
                             on_failed=self._failed, bar=self.bar, owner=self)
        self.task.ended.connect(lambda: self.run_button.setEnabled(True))
        return self.task

    def _done(self, result: AnalysisResult) -> None:
        self.result = result
        a = result.analysis
        self.trials.clear()
        self.trials.addItems([_trial_label(a, tr) for tr in a.trials])
        sim = " — SIMULATED recording" if a.simulated else ""
        self.status.setText(f"{len(a.trials)} trials, {a.meta['n_samples']} samples; {a.meta.get('note', '')}{sim}")
        self.save_button.setEnabled(True)
        if a.trials:
            self.trials.setCurrentRow(0)
        else:
            self.phases_model.set_frame(a.phases)
            self.patches_model.set_frame(a.patches)

    def _failed(self, message: str) -> None:
        self.status.setText(f"Analysis failed: {message}")

    def show_trial(self, row: int) -> None:
        """Show trial ``row`` (0-based): its figure and its rows of both tables."""
        if self.result is None or not 0 <= row < len(self.result.figures):
            return
        pix = QPixmap()
        pix.loadFromData(self.result.figures[row], "PNG")
        self.figure.setPixmap(pix)
        a, index = self.result.analysis, self.result.analysis.trials[row].index
        self.phases_model.set_frame(a.phases[a.phases["trial"] == index])
        self.patches_model.set_frame(a.patches[a.patches["trial"] == index])

    def _save(self, directory=None) -> list:
        if self.result is None:
            return []
        directory = directory or QFileDialog.getExistingDirectory(self, "Save into folder")
        if not directory:
            return []
        written = write_analysis(self.result.analysis, directory)
        self.status.setText(f"Wrote {len(written)} files into {directory}")
        return written




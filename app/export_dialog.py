"""File → Export: a recording to NWB, ROS 2 MCAP, CSV or MATLAB .mat, with a progress bar.

The export runs in the thread pool (:func:`app.tasks.run_task`): the raw streams, then one
streamed pass of the pipeline and the contacts into NWB and MCAP (bounded memory); a
:class:`~app.tasks.TaskBar` shows the progress and can cancel. Files and their contents are those of ``pito export`` (docs/interop.md).
"""

from __future__ import annotations

from pathlib import Path

from PySide6.QtWidgets import (
    QCheckBox, QDialog, QDialogButtonBox, QFileDialog, QFormLayout, QHBoxLayout, QLabel, QLineEdit, QPushButton,
    QVBoxLayout, QWidget,
)

import pito_core.interop  # the writers (MCAP, NWB; scipy) load at the first export, not with the window
from pito_core.calibration import load_calibration
from pito_core.io import RecordingChunks, export_recording_files
from pito_core.pipeline import recording_times

from .file_menu import add_dialog_action
from .filetypes import CALIBRATION_FILTER
from .tasks import TaskBar, run_task

__all__ = ["ExportDialog", "export_recording", "install_export_menu", "FORMATS"]

#: Format key → (label, file suffix).
FORMATS = {"nwb": ("NWB (Neurodata Without Borders)", ".nwb"), "mcap": ("ROS 2 MCAP", ".mcap"),
           "csv": ("CSV (raw streams)", "_pito.csv"), "mat": ("MATLAB .mat (raw streams)", ".mat")}


def export_recording(recording, formats, out_prefix, calibration_path=None, subject_id=None, experimenter=None,
                     progress=None) -> list[str]:
    """Write ``recording`` in each of ``formats`` (keys of :data:`FORMATS`) next to ``out_prefix``; the paths written.

    ``progress(fraction, text)`` as :func:`app.tasks.run_task` gives it (raises when cancelled).
    """
    progress = progress or (lambda f, t: None)
    unknown = set(formats) - set(FORMATS)
    if unknown or not formats:
        raise ValueError(f"formats: expected some of {sorted(FORMATS)}, got {sorted(formats)}")
    out = []
    prefix = str(out_prefix)
    if "csv" in formats or "mat" in formats:
        rec = RecordingChunks(recording)  # read block by block: bounded memory at any length
        # the one time base of every export (device clock), as `pito export` writes it
        out += export_recording_files(rec, prefix if "csv" in formats else None,
                                      prefix + ".mat" if "mat" in formats else None, recording_times(rec))
        progress(0.05, "raw streams written")
    if "nwb" in formats or "mcap" in formats:
        cal = None
        if calibration_path:
            cal = load_calibration(calibration_path)
        meta = {k: v for k, v in (("subject_id", subject_id), ("experimenter", [experimenter] if experimenter else None))
                if v}
        # one streamed pass to both files, as `pito export`: bounded memory at any length
        pito_core.interop.export_files(recording, nwb=prefix + ".nwb" if "nwb" in formats else None,
                     mcap=prefix + ".mcap" if "mcap" in formats else None, calibration=cal,
                     calibration_source=calibration_path, nwb_metadata=meta, progress=progress)
        out += [prefix + s for s in (".nwb", ".mcap") if s[1:] in formats]
    progress(1.0, "done")
    return out


class ExportDialog(QDialog):
    """Pick a recording, the formats, an optional calibration; Export runs in the background."""

    def __init__(self, parent=None, recording: str | None = None):
        super().__init__(parent)
        self.setWindowTitle("Export a recording")
        self.task = None
        self.written: list[str] = []
        form = QFormLayout()
        self.recording = QLineEdit(recording or "")
        form.addRow("Recording", self._with_browse(self.recording, self._pick_recording))
        self.calibration = QLineEdit("")
        self.calibration.setPlaceholderText("the recording's own (optional: recompute with another file)")
        form.addRow("Calibration", self._with_browse(self.calibration, self._pick_calibration))
        self.prefix = QLineEdit("")
        self.prefix.setPlaceholderText("output path without suffix (default: next to the recording)")
        form.addRow("Output", self.prefix)
        self.checks = {}
        for key, (label, suffix) in FORMATS.items():
            self.checks[key] = QCheckBox(f"{label}  ({suffix})")
            self.checks[key].setChecked(key in ("nwb", "mcap"))
            form.addRow("" if key != "nwb" else "Formats", self.checks[key])
        self.subject = QLineEdit("")
        form.addRow("Subject id (NWB)", self.subject)
        self.experimenter = QLineEdit("")
        form.addRow("Experimenter (NWB)", self.experimenter)
        self.bar = TaskBar()
        self.status = QLabel("")
        self.status.setWordWrap(True)
        self.buttons = QDialogButtonBox(QDialogButtonBox.StandardButton.Close)
        self.export_button = self.buttons.addButton("Export", QDialogButtonBox.ButtonRole.ActionRole)
        self.export_button.clicked.connect(self.start)
        self.buttons.rejected.connect(self.reject)
        lay = QVBoxLayout(self)
        lay.addLayout(form)
        lay.addWidget(self.bar)
        lay.addWidget(self.status)
        lay.addWidget(self.buttons)

    def _with_browse(self, edit, pick) -> QWidget:
        w = QWidget()
        h = QHBoxLayout(w)
        h.setContentsMargins(0, 0, 0, 0)
        h.addWidget(edit, 1)
        b = QPushButton("…")
        b.clicked.connect(pick)
        h.addWidget(b)
        return w

    def _pick_recording(self) -> None:
        path, _ = QFileDialog.getOpenFileName(self, "Recording", "", "PITO recording (*.pitorec);;All files (*)")
        if path:
            self.recording.setText(path)

    def _pick_calibration(self) -> None:
        path, _ = QFileDialog.getOpenFileName(self, "Calibration", "", CALIBRATION_FILTER)
        if path:
            self.calibration.setText(path)

    def formats(self) -> list[str]:
        return [k for k, c in self.checks.items() if c.isChecked()]

    def start(self):
        """Start the export in the background; returns the :class:`~app.tasks.Task` (None on bad input)."""
        rec = self.recording.text().strip()
        if not rec or not Path(rec).is_file():
            self.status.setText(f"Recording: file not found: {rec!r}")
            return None
        if not self.formats():
            self.status.setText("Formats: tick at least one")
            return None
        prefix = self.prefix.text().strip() or str(Path(rec).with_suffix(""))
        args = dict(formats=self.formats(), out_prefix=prefix, calibration_path=self.calibration.text().strip() or None,
                    subject_id=self.subject.text().strip(), experimenter=self.experimenter.text().strip())
        self.export_button.setEnabled(False)
        self.status.setText("Exporting…")
        self.task = run_task(lambda progress: export_recording(rec, progress=progress, **args), "Exporting",
                             on_done=self._done, on_failed=self._failed, bar=self.bar, owner=self)
        return self.task

    def _done(self, paths) -> None:
        self.written = list(paths)
        self.export_button.setEnabled(True)
        self.status.setText("Wrote " + ", ".join(paths))

    def _failed(self, message: str) -> None:
        self.export_button.setEnabled(True)
        self.status.setText(f"Export failed: {message}")


def install_export_menu(window):
    """Add File → Export recording… to ``window``'s menu bar (creating the File menu if absent)."""
    return add_dialog_action(window, "Export recording… (NWB, MCAP, CSV, .mat)", ExportDialog, "export")

"""Step 6: results — held-out RMSE, face identification, comparison; accept, redo, save, export."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from PySide6.QtCore import Qt
from PySide6.QtGui import QImage, QPixmap
from PySide6.QtWidgets import (
    QComboBox, QFileDialog, QGridLayout, QGroupBox, QHBoxLayout, QLabel, QPushButton,
)

from pito_core.calibration import RankDeficientError, calibrate

from .. import report
from ..tasks import TaskBar, run_in_process, run_task
from .model_choice import ModelChoiceBox
from .page import WizardPage

__all__ = ["ResultsPage", "fit_and_evaluate", "render_figures"]

#: samples per block of the streamed QR in the wizard's fit (keeps each GIL-holding LAPACK call short)
FIT_BLOCK = 8192


def fit_and_evaluate(session, method: str, holdout: float = 0.25, seed: int = 0, progress=None, model: str = "auto"):
    """Fit ``method`` on a training split of ``session`` and evaluate it on the held-out rest.

    Returns ``(calibration, evaluation, note)``; ``note`` says if a minimum-norm fit was needed.
    ``progress(fraction, text)``, if given, is called between the steps (and may raise to cancel).
    """
    from pito_core.calibration import evaluate

    progress = progress or (lambda *_: None)
    progress(0.0, "splitting the samples")
    # blocks of 50 samples: every kept capture (a few hundred still samples) feeds both sides,
    # so the fit keeps every loaded direction and the held-out samples test it on new noise
    train, test = session.split(holdout=holdout, block=50, seed=seed)
    n_fit = train.counts.shape[0]
    progress(0.1, f"fitting {method} on {n_fit} samples")
    # small blocks: LAPACK holds the GIL through each block's QR, and the GUI thread needs it
    # every few ms; the fit's own progress is also where a cancel stops it
    fit_options = {"block_size": FIT_BLOCK, "model": model,
                   "progress": lambda done, total: progress(0.1 + 0.6 * done / max(total, 1),
                                                            f"fitting {method}: {done} / {total} samples")}
    note = ""
    try:
        cal = calibrate(train, method, **fit_options)
    except RankDeficientError as exc:  # unexcited directions or dead channels: fit minimum-norm, say so
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            cal = calibrate(train, method, allow_rank_deficient=True, **fit_options)
        note = f"minimum-norm fit — {exc}"
    progress(0.75, f"evaluating on {test.counts.shape[0]} held-out samples")
    ev = evaluate(cal, test)
    progress(1.0, "done")
    return cal, ev, note


def fit_job(session, method: str, sizes: dict, model: str = "auto", progress=None):
    """Fit, evaluate and draw the figures (any process): ``(calibration, evaluation, note, images)``."""
    cal, ev, note = fit_and_evaluate(session, method, progress=progress, model=model)
    if progress is not None:
        progress(0.9, "drawing the figures")
    return cal, ev, note, render_figures(ev, sizes)


def render_figures(evaluation, sizes: dict) -> dict:
    """The results figures of ``evaluation`` as RGBA images ``(h, w, 4) uint8`` (Agg, any thread).

    ``sizes``: name (``rmse``, ``ident``, ``comp``) → ``(width, height)`` px.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    draw = {"rmse": report.rmse_figure, "ident": report.identification_figure, "comp": report.comparison_figure}
    out = {}
    for name, (w, h) in sizes.items():
        fig = Figure(figsize=(w / 90, h / 90), dpi=90)
        canvas = FigureCanvasAgg(fig)
        draw[name](evaluation, fig)
        canvas.draw()
        out[name] = np.asarray(canvas.buffer_rgba()).copy()
    return out


class FigureImage(QLabel):
    """A figure drawn elsewhere, shown as an image (no drawing on the GUI thread)."""

    def __init__(self, size):
        super().__init__()
        self._default = size
        self.setMinimumSize(200, 150)
        self.setAlignment(Qt.AlignmentFlag.AlignCenter)
        self.image = None

    def target_size(self) -> tuple[int, int]:
        """Pixels to draw at: the widget's size once laid out, else the default."""
        w, h = self.width(), self.height()
        return (w, h) if w > 250 and h > 180 else self._default

    def set_image(self, rgba) -> None:
        """Show ``rgba`` ``(h, w, 4) uint8``, scaled down (aspect kept) if the label is smaller: never clipped."""
        self.image = np.ascontiguousarray(rgba)
        h, w = self.image.shape[:2]
        qimg = QImage(self.image.data, w, h, 4 * w, QImage.Format.Format_RGBA8888).copy()
        self._pixmap = QPixmap.fromImage(qimg)
        self._fit()

    def _fit(self) -> None:
        pm = getattr(self, "_pixmap", None)
        if pm is None:
            return
        if pm.width() > self.width() or pm.height() > self.height():
            pm = pm.scaled(self.size(), Qt.AspectRatioMode.KeepAspectRatio, Qt.TransformationMode.SmoothTransformation)
        self.setPixmap(pm)

    def resizeEvent(self, event):  # noqa: N802
        super().resizeEvent(event)
        self._fit()


class ResultsPage(WizardPage):
    """Wizard step 6: fit on 75 % of the kept samples, evaluate on the held-out rest, accept or redo.

    Figures of merit in N and N·m (RMSE per axis), inverse condition numbers (dimensionless).

    Parameters
    ----------
    model : app.wizard.model.WizardModel
        The wizard's state (method, mount, captures); the page reads and sets it.
    parent : QWidget, optional
    """
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
        # figures are drawn (Agg) in the worker thread with the fit, shown here as images
        self.canvas_rmse = FigureImage((576, 234))
        self.canvas_ident = FigureImage((324, 270))
        self.canvas_comp = FigureImage((576, 270))
        self._images_for = None  # the evaluation the shown images belong to
        grid_l.addWidget(nums, 0, 0)
        grid_l.addWidget(self.canvas_ident, 1, 0)
        grid_l.addWidget(self.canvas_rmse, 0, 1)
        grid_l.addWidget(self.canvas_comp, 1, 1)
        grid_l.setColumnStretch(0, 2)
        grid_l.setColumnStretch(1, 3)
        grid_l.setRowStretch(0, 1)
        grid_l.setRowStretch(1, 1)
        self.body.addLayout(grid_l, 1)
        self.model_box = ModelChoiceBox()  # which model, why, and a switch to the papers' linear fit
        self.model_box.requested_changed.connect(lambda _: self.compute())
        self.body.addWidget(self.model_box)
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
        self.taskbar = TaskBar()  # the fit runs in a worker thread: progress and Cancel here
        self.body.addWidget(self.taskbar)
        self.task = None
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

    def _figure_sizes(self) -> dict:
        return {name: w.target_size() for name, w in
                (("rmse", self.canvas_rmse), ("ident", self.canvas_ident), ("comp", self.canvas_comp))}

    def _render_figures(self, ev) -> None:
        """Draw the three figures of ``ev`` in a worker thread; show them when done."""
        sizes = self._figure_sizes()
        self._images_for = ev

        def done(images):
            if self._images_for is ev:
                self._show_images(images)

        self.figure_task = run_task(lambda progress: render_figures(ev, sizes), "Drawing the figures", done,
                                    lambda msg: self.values["status"].setText(f"✘ figures: {msg}"), owner=self)

    def _show_images(self, images: dict) -> None:
        for name, w in (("rmse", self.canvas_rmse), ("ident", self.canvas_ident), ("comp", self.canvas_comp)):
            w.set_image(images[name])

    @property
    def fitting(self) -> bool:
        return self.task is not None and self.task.running

    def compute(self, session=None) -> None:
        """Fit and evaluate in a worker thread (the window stays live); the result arrives by signal.

        ``session`` defaults to the wizard's kept samples."""
        if self.fitting:
            self.task.cancel()
        session = self.model.session() if session is None else session
        method = self.model.method
        self.note = ""

        def done(result):
            cal, ev, self.note, images = result
            self._images_for = ev
            self._show_images(images)
            self.model.set_result(cal, ev)
            self.refresh()

        def failed(message):
            self.note = message
            self.model.set_result(None, None)
            self.refresh()

        sizes = self._figure_sizes()
        # in a child process: the fit's LAPACK calls hold the GIL for long stretches
        self.task = run_in_process(fit_job, (session, method, sizes, self.model_box.requested),
                                   f"Fitting {method} on {session.counts.shape[0]} samples", done, failed,
                                   bar=self.taskbar, owner=self)
        self.task.ended.connect(self.refresh)

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
        self.export_btn.setEnabled(has and m.accepted and not self.exporting)
        if not has:
            if self.fitting:
                self.values["status"].setText("fitting in the background… (the window stays live; Cancel below)")
            elif self.task is not None and self.task.cancelled:
                self.values["status"].setText("fit cancelled — go back to the loading step, or reopen this page to fit again")
            else:
                self.values["status"].setText(f"✘ fit failed: {self.note}")
            self.set_ready(False)
            return
        self.model_box.show_choice(cal.model)
        f, t = ev.rmse_force(), ev.rmse_torque()
        worst_f = int(np.nanargmax(f)) + 1 if np.isfinite(f).any() else None
        worst_t = int(np.nanargmax(t)) + 1 if np.isfinite(t).any() else None
        self.values["method"].setText(f"{cal.method}  (faces {', '.join(map(str, cal.output_faces))} out, "
                                      f"{'SIMULATED' if m.simulated else 'real'} devices)")
        self.values["icn"].setText(f"{cal.inverse_condition_number:.3e}")
        self.values["samples"].setText(f"{cal.meta.get('n_samples_fitted', '?')} / {ev.n_single}")
        self.values["force"].setText(f"{np.nanmax(f):.3f} N (face {worst_f})" if worst_f else "n/a")
        self.values["torque"].setText(f"{np.nanmax(t) * 1000:.2f} mN·m (face {worst_t})" if worst_t else "n/a")
        head = ev.identification_headline()  # the papers' rule: single by force, squeeze by torque
        self.values["ident"].setText("; ".join(h["text"] for h in head) if head else "n/a")
        self.values["ident"].setWordWrap(True)
        unc = ev.uncertainty95
        if unc is not None and worst_f and worst_t:
            self.values["force"].setText(self.values["force"].text()
                                         + f", ± {np.nanmax(unc[worst_f - 1, :3]):.3f} N (95 %, calibration's own)")
            self.values["torque"].setText(self.values["torque"].text()
                                          + f", ± {np.nanmax(unc[worst_t - 1, 3:]) * 1000:.2f} mN·m (95 %)")
        self.values["method"].setText(self.values["method"].text()
                                      + f"; net force of a free grasp: {cal.meta.get('net_load', 'not recorded')}")
        status = "✔ accepted" if m.accepted else "awaiting your decision"
        if m.saved_path:
            status += f" — saved to {Path(m.saved_path).name}"
        if self.note:
            status += " — minimum-norm fit: some directions were weakly loaded (see tooltip)"
        self.values["status"].setText(status)
        self.values["status"].setToolTip(self.note)
        if worst_f:
            self.redo_face.setCurrentIndex(max(0, self.redo_face.findData(worst_f)))
        if self._images_for is not ev:
            self._render_figures(ev)
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
        cal, ev = m.calibration, m.evaluation

        def work(progress):
            progress(None, f"figures and numbers into {folder}")
            return report.export_report(folder, cal, ev, info)

        def done(path):
            self.exported_path = path
            self.values["status"].setText(f"report exported to {path}")

        self.export_task = run_task(work, "Exporting the report", done,
                                    lambda msg: self.values["status"].setText(f"✘ export failed: {msg}"),
                                    bar=self.taskbar, owner=self)
        self.export_task.ended.connect(self.refresh)
        self.refresh()
        return Path(folder) / "report.md"

    @property
    def exporting(self) -> bool:
        t = getattr(self, "export_task", None)
        return t is not None and t.running

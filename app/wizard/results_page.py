"""Step 6: results — held-out RMSE, face identification, comparison; accept, redo, save, export."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from PySide6.QtCore import QTimer, Qt, QUrl, Signal
from PySide6.QtGui import QImage, QPixmap
from PySide6.QtWidgets import (
    QComboBox, QFileDialog, QFrame, QGridLayout, QGroupBox, QHBoxLayout, QLabel, QPushButton, QScrollArea, QSizePolicy,
    QTabWidget,
)

from pito_core.calibration import HOLDOUT, NOT_MEASURED_TEXT, fit_and_evaluate

from pito_core import report
from ..filetypes import CALIBRATION_SAVE_FILTER, CALIBRATION_SUFFIX
from ..tasks import TaskBar, run_in_process, run_task
from .model_choice import ModelChoiceBox
from .page import WizardPage
from ..fonts import use_app_font_in_matplotlib

use_app_font_in_matplotlib()  # the app's font in this module's figures (app/fonts.py)

#: Width of the figures of merit's names, px (wrapped): the values beside them get the rest.
NAME_WIDTH = 190

__all__ = ["ResultsPage", "fit_job", "render_figures", "per_face_text", "identification_text"]

identification_text = report.identification_text  # the page's words are the report's

#: samples per block of the streamed QR in the wizard's fit (keeps each GIL-holding LAPACK call short)
FIT_BLOCK = 8192


def per_face_text(figures, heldout=None, reaction=None, completed=(), measured=None) -> str:
    """Each face's validation RMSE (N, mN·m), one line each.

    A face loaded on the second mount (``completed``) says so, and where its figure is worse than the
    worst of the faces validated on the main mount, says that too (⚠, with both figures). A face without
    fresh loads says what stands for it: ``heldout``, the evaluation of the held-out part of the second
    mount's loads, for its ``completed`` faces (optimistic: no fresh loads), or the reactions it carried on
    the main mount; ``measured`` (6,) bool: the faces the calibration outputs (default all)."""
    lines = []
    hf = ht = None
    if heldout is not None:
        hf, ht = heldout.rmse_force(), heldout.rmse_torque()
    main = [i for i in range(6) if i + 1 not in completed and np.isfinite(figures.rmse_force[i])]
    worst_f = max((figures.rmse_force[i] for i in main), default=float("nan"))
    worst_t = max((figures.rmse_torque[i] for i in main), default=float("nan"))
    main_names = ", ".join(str(i + 1) for i in main)

    def worse(f, t):
        """' ⚠ …' where the force or torque figure exceeds the worst of the main mount's faces, with both figures."""
        said = [f"{what} {x / w:.1f}× their worst ({w * k:.3g} {unit})"
                for what, x, w, k, unit in (("force", f, worst_f, 1.0, "N"), ("torque", t, worst_t, 1e3, "mN·m"))
                if np.isfinite(w) and x > w]
        return f" ⚠ less accurate than faces {main_names}: {'; '.join(said)}" if said else ""

    for i in range(6):
        f, t = figures.rmse_force[i], figures.rmse_torque[i]
        if measured is not None and not measured[i]:
            lines.append(f"{i + 1}: {NOT_MEASURED_TEXT}")
        elif np.isfinite(f):
            where = " — second mount" if i + 1 in completed else ""
            lines.append(f"{i + 1}: {f:.3f} N, {t * 1000:.2f} mN·m{where}{worse(f, t) if where else ''}")
        elif i + 1 in completed and hf is not None and np.isfinite(hf[i]):
            lines.append(f"{i + 1}: {hf[i]:.3f} N, {ht[i] * 1000:.2f} mN·m — second mount, held-out of its "
                         f"captures (no fresh loads: optimistic){worse(hf[i], ht[i])}")
        elif i + 1 == reaction:
            lines.append(f"{i + 1}: reactions only, {figures.reaction_force:.3f} N, "
                         f"{figures.reaction_torque * 1000:.2f} mN·m — not validated under a load of its own")
        else:
            lines.append(f"{i + 1}: not loaded in the validation pass")
    return "\n".join(lines)


def fit_job(sessions, method: str, sizes: dict, validation=None, model: str = "auto", progress=None):
    """Fit, evaluate and draw the figures (any process): ``(calibration, headline, note, heldout, figures, completing,
    images)``.

    The one route of ``pito calibrate`` (:func:`pito_core.calibration.fit_and_evaluate`: the same split
    and figures); ``heldout`` is over every session's held-out samples, ``completing`` over the second
    mount's alone (None without one); a minimum-norm fit (directions the loads left unexcited) is said
    in ``note``.
    """
    # small blocks: LAPACK holds the GIL through each block's QR, and the GUI thread needs it
    # every few ms; the fit's own progress is also where a cancel stops it
    fit = fit_and_evaluate(sessions, method, validation=validation, model=model, rank_deficient="fallback",
                           block_size=FIT_BLOCK, progress=progress)
    completing = fit.heldout_by_session[1] if len(fit.heldout_by_session) > 1 else None
    if progress is not None:
        progress(0.9, "drawing the figures")
    images = render_figures(fit.headline, sizes, {**rmse_options(sessions, validation), "figures": fit.figures})
    return fit.calibration, fit.headline, fit.note, fit.heldout, fit.figures, completing, images


def rmse_options(sessions, validation) -> dict:
    """The RMSE figure's labels: the flange's face as "reactions", and where the figures come from
    (``validation``: a session, a list of them, or None)."""
    main = sessions if hasattr(sessions, "flange") else sessions[0]
    return {"reactions": main.connected_face if main.flange == "face" else None,
            "kind": "validation" if validation else "held-out"}


def render_figures(evaluation, sizes: dict, rmse: dict | None = None) -> dict:
    """The results figures of ``evaluation`` as RGBA images ``(h, w, 4) uint8`` (Agg, any thread).

    ``sizes``: name (``rmse``, ``ident``, ``comp``) → ``(width, height)`` px; ``rmse``: options of
    the RMSE figure (:func:`rmse_options`).
    """
    draw = {"rmse": report.rmse_figure, "ident": report.identification_figure, "comp": report.comparison_figure}
    out = {}
    for name, (w, h) in sizes.items():
        fig = Figure(figsize=(w / report.SCREEN_DPI, h / report.SCREEN_DPI), dpi=report.SCREEN_DPI)  # 9 pt = 12 px
        canvas = FigureCanvasAgg(fig)
        draw[name](evaluation, fig, **(rmse or {})) if name == "rmse" else draw[name](evaluation, fig)
        canvas.draw()
        out[name] = np.asarray(canvas.buffer_rgba()).copy()
    return out


class FigureImage(QLabel):
    """A figure drawn elsewhere, shown as an image (no drawing on the GUI thread).

    It asks to be drawn again at its own size (``redraw_wanted``, debounced) when its size
    moves away from the image's, so the figure is shown at the size it was drawn (9 pt text
    stays 12 px); in between, a larger image is scaled down to fit (never clipped).
    """

    #: emitted (debounced) when the label's size no longer fits its image (:meth:`needs_redraw`)
    redraw_wanted = Signal()

    def __init__(self, size):
        super().__init__()
        self._default = size
        self.setMinimumSize(200, 150)
        self.setSizePolicy(QSizePolicy.Policy.Ignored, QSizePolicy.Policy.Ignored)  # the image never sets the size
        self.setAlignment(Qt.AlignmentFlag.AlignCenter)
        self.image = None
        self._debounce = QTimer(self, singleShot=True, interval=250)
        self._debounce.timeout.connect(self.redraw_wanted)

    def target_size(self) -> tuple[int, int]:
        """Pixels to draw at: the widget's size once laid out, else the default."""
        w, h = self.width(), self.height()
        return (w, h) if w > 250 and h > 180 else self._default

    def needs_redraw(self) -> bool:
        """True if the shown image is larger than the label (shown shrunk) or more than 10 % smaller."""
        if self.image is None:
            return False
        (w, h), (iw, ih) = self.target_size(), self.image.shape[1::-1]
        return iw > w or ih > h or iw < 0.9 * w or ih < 0.9 * h

    def set_image(self, rgba) -> None:
        """Show ``rgba`` ``(h, w, 4) uint8``, scaled down (aspect kept) if the label is smaller: never clipped."""
        self.image = np.ascontiguousarray(rgba)
        h, w = self.image.shape[:2]
        qimg = QImage(self.image.data, w, h, 4 * w, QImage.Format.Format_RGBA8888).copy()
        self._pixmap = QPixmap.fromImage(qimg)
        self._fit()
        if self.needs_redraw():  # drawn for a size the label no longer has
            self._debounce.start()

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
        if self.needs_redraw():
            self._debounce.start()


class ResultsPage(WizardPage):
    """Wizard step 6: fit on 80 % of the kept samples (as ``pito calibrate``), evaluate on the rest and the validation pass.

    Figures of merit in N and N·m (RMSE per axis), inverse condition numbers (dimensionless).

    Parameters
    ----------
    model : app.wizard.model.WizardModel
        The wizard's state (method, mount, captures); the page reads and sets it.
    parent : QWidget, optional
    """
    title = "6 · Results"
    help = (f"The calibration was fitted on {100 * (1 - HOLDOUT):.0f} % of the kept samples (as pito calibrate fits); "
            "its figures come from the validation passes of "
            "fresh loads, on each mount (the held-out rest is a secondary line). "
            "Accept it, or redo a face whose error is too high; then save the calibration and export the report.")

    def __init__(self, model, parent=None):
        super().__init__(model, parent)
        nums = self._figures_of_merit()
        self._figure_tabs()
        self._images_for = None  # the evaluation the shown images belong to
        row = QHBoxLayout()
        row.addWidget(self._scroll(nums), 2)
        row.addWidget(self.figure_tabs, 3)
        self.body.addLayout(row, 1)
        self.model_box = ModelChoiceBox()  # which model, why, and a switch to the papers' linear fit
        self.model_box.requested_changed.connect(lambda _: self.compute())
        self.body.addWidget(self.model_box)
        self._buttons()
        self._exported_label()
        self.taskbar = TaskBar()  # the fit runs in a worker thread: progress and Cancel here
        self.body.addWidget(self.taskbar)
        self.task = None
        self.note = ""
        #: set by the wizard: go back to the loading page for a face
        self.redo_requested = None

    def _figures_of_merit(self) -> QGroupBox:
        """The figures of merit, one row each: ``self.values[key]`` is the label of a row's value."""
        nums = QGroupBox("Figures of merit")
        grid = QGridLayout(nums)
        grid.setColumnStretch(1, 1)
        self.values = {}
        for r, (key, text) in enumerate((
            ("method", "Method"),
            ("icn", "Inverse condition number σmin/σmax"),
            ("samples", "Samples: fitted / validation"),
            ("force", "Worst face force RMSE (validation)"),
            ("torque", "Worst face torque RMSE (validation)"),
            ("per_face", "Every face: force, torque RMSE (validation)"),
            ("ident", "Face identification (validation)"),
            ("reactions", "Connected face on the main mount (reactions only)"),
            ("heldout", "Held-out split of the fit (secondary)"),
            ("coverage", "Measures"),
            ("status", "Status"),
        )):
            name = QLabel(text)
            name.setWordWrap(True)  # a narrow name column: the values get the width (their numbers stay whole)
            name.setFixedWidth(NAME_WIDTH)
            grid.addWidget(name, r, 0, Qt.AlignmentFlag.AlignTop)
            lab = QLabel("—")
            lab.setObjectName("value")
            lab.setWordWrap(True)  # rows grow to their text (height for width), never clipped
            lab.setSizePolicy(QSizePolicy.Policy.Ignored, QSizePolicy.Policy.Minimum)
            lab.setMinimumWidth(170)
            grid.addWidget(lab, r, 1)
            self.values[key] = lab
        grid.setRowStretch(len(self.values), 1)
        return nums

    def _figure_tabs(self) -> None:
        # figures are drawn (Agg) in a worker, at the size of their tab, shown here as images;
        # one tab each so every figure gets the room its 9 pt text needs
        self.canvas_rmse = FigureImage((760, 420))
        self.canvas_ident = FigureImage((760, 420))
        self.canvas_comp = FigureImage((760, 420))
        self.figure_tabs = QTabWidget()
        for w, name in ((self.canvas_rmse, "RMSE per face"), (self.canvas_ident, "Face identification"),
                        (self.canvas_comp, "Against the reference")):
            self.figure_tabs.addTab(w, name)
            w.redraw_wanted.connect(self._redraw_figures)

    def _scroll(self, nums: QGroupBox) -> QScrollArea:
        """``nums`` in a scroll area that keeps its full width."""
        nums_scroll = QScrollArea()  # rows take the height of their wrapped text; scrolls if they need more
        nums_scroll.setWidget(nums)
        nums_scroll.setWidgetResizable(True)
        nums_scroll.setFrameShape(QFrame.Shape.NoFrame)
        nums_scroll.setHorizontalScrollBarPolicy(Qt.ScrollBarPolicy.ScrollBarAlwaysOff)
        # never narrower than the group box: its right edge (and the values' ends) stay in view
        nums_scroll.setMinimumWidth(nums.minimumSizeHint().width() + nums_scroll.verticalScrollBar().sizeHint().width())
        self.nums_scroll = nums_scroll
        return nums_scroll

    def _buttons(self) -> None:
        """Accept, redo a face, save, export."""
        buttons = QHBoxLayout()
        self.accept_btn = QPushButton("Accept calibration")
        self.accept_btn.setObjectName("primary")
        self.redo_face = QComboBox()
        self.redo_face.setSizeAdjustPolicy(QComboBox.SizeAdjustPolicy.AdjustToContents)  # "face 6 (2nd mount)" whole
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

    def _exported_label(self) -> None:
        # after an export: where it went, with a link that opens the folder (and the path to copy)
        self.exported_label = QLabel("")
        self.exported_label.setObjectName("hint")
        self.exported_label.setTextFormat(Qt.TextFormat.RichText)
        self.exported_label.setTextInteractionFlags(Qt.TextInteractionFlag.TextBrowserInteraction)
        self.exported_label.setOpenExternalLinks(True)
        self.exported_label.setVisible(False)
        self.body.addWidget(self.exported_label)

    # ------------------------------------------------------------ compute
    def enter(self) -> None:
        if self.model.calibration is None:
            self.compute()
        self.refresh()

    def _figure_sizes(self) -> dict:
        return {name: w.target_size() for name, w in
                (("rmse", self.canvas_rmse), ("ident", self.canvas_ident), ("comp", self.canvas_comp))}

    def _render_figures(self, ev) -> None:
        """Draw the three figures of ``ev`` in a worker thread, at the labels' sizes; show them when done."""
        sizes = self._figure_sizes()
        self._images_for = ev
        self._render_token = token = object()  # only the newest drawing is shown

        def done(images):
            if self._images_for is ev and self._render_token is token:
                self._show_images(images)

        options = getattr(self, "_rmse_options", None)
        self.figure_task = run_task(lambda progress: render_figures(ev, sizes, options), "Drawing the figures", done,
                                    lambda msg: self.values["status"].setText(f"✘ figures: {msg}"), owner=self)

    def _redraw_figures(self) -> None:
        """A figure's label changed size: draw the figures again at the new sizes (not while fitting)."""
        ev = self.model.evaluation
        if ev is None or self.fitting or self._images_for is not ev:
            return
        if any(w.needs_redraw() for w in (self.canvas_rmse, self.canvas_ident, self.canvas_comp)):
            self._render_figures(ev)

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
        sessions = self.model.training_sessions() if session is None else session
        validation = (self.model.validation_sessions() or None) if session is None else None
        self._rmse_options = rmse_options(sessions, validation)
        method = self.model.method
        self.note = ""

        def done(result):
            cal, ev, self.note, heldout, self.figures, self.completing, images = result
            self._rmse_options["figures"] = self.figures  # the face figures the page shows, redrawn alike
            self.forget_export()  # a report exported before describes the previous fit
            self._images_for = ev
            self._show_images(images)
            self.model.set_result(cal, ev, heldout)
            self.refresh()

        def failed(message):
            self.note = message
            self.forget_export()
            self.model.set_result(None, None)
            self.refresh()

        sizes = self._figure_sizes()
        # in a child process: the fit's LAPACK calls hold the GIL for long stretches
        n = sum(s.counts.shape[0] for s in ([sessions] if hasattr(sessions, "counts") else sessions))
        self.task = run_in_process(fit_job, (sessions, method, sizes, validation, self.model_box.requested),
                                   f"Fitting {method} on {n} samples", done, failed,
                                   bar=self.taskbar, owner=self)
        self.task.ended.connect(self.refresh)

    def refresh(self) -> None:
        m = self.model
        cal, ev = m.calibration, m.evaluation
        self.redo_face.clear()
        for st in m.stages:  # the fitted mounts' faces: the main mount's, then the second mount's
            if st.kind != "validation":
                for f in st.faces:
                    self.redo_face.addItem(f"face {f}" + (" (2nd mount)" if st.kind == "completing" else ""), f)
        has = cal is not None and ev is not None
        for b in (self.accept_btn, self.save_btn, self.export_btn):
            b.setEnabled(has)
        self.accept_btn.setEnabled(has and not m.accepted)  # accepted once: it is the live view's now
        self.accept_btn.setText("✔ Accepted — in use in the live view" if has and m.accepted else "Accept calibration")
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
        self.model_box.show_choice(cal.model, cal.output_faces)
        self._show_figures(cal, ev, m)
        status = "✔ accepted — the live view uses it" if m.accepted else "awaiting your decision"
        if m.saved_path:
            status += f" — saved to {Path(m.saved_path).name}"
        if getattr(self, "exported_path", None):
            status += f" — report exported to {Path(self.exported_path).parent}"
        if self.note:
            status += " — minimum-norm fit: some directions were weakly loaded (see tooltip)"
        self.values["status"].setText(status)
        self.values["status"].setToolTip(self.note)
        if self._worst:
            self.redo_face.setCurrentIndex(max(0, self.redo_face.findData(self._worst)))
        if self._images_for is not ev:
            self._render_figures(ev)
        self.set_ready(m.accepted)

    def _show_figures(self, cal, ev, m) -> None:
        """The headline (validation pass, with 95 % intervals), the reactions, the held-out split, the coverage."""
        v = self.values
        main = m.stages[0]
        reaction = main.connected_face if main.flange == "face" else None
        fig = getattr(self, "figures", None)
        completed = tuple(f for st in m.stages if st.kind == "completing" for f in st.faces)
        self._worst = None
        faces = cal.output_faces
        out = f"faces {faces[0]}–{faces[-1]}" if faces == tuple(range(faces[0], faces[-1] + 1)) else \
            f"faces {', '.join(map(str, faces))}"
        v["method"].setText(f"{cal.method} ({out}, {'SIMULATED' if m.simulated else 'real'})")
        v["icn"].setText(f"{cal.inverse_condition_number:.3e}")
        n_val = f"{fig.n_samples} ({fig.n_captures} captures)" if fig is not None else "none"
        v["samples"].setText(f"{cal.meta.get('n_samples_fitted', '?')} / {n_val}")
        if fig is not None:
            wf, wt = int(np.nanargmax(fig.rmse_force)) + 1, int(np.nanargmax(fig.rmse_torque)) + 1
            self._worst = wf
            v["force"].setText(f"{fig.worst_force:.3f} N (face {wf}), 95\u00a0%: "
                               f"{fig.worst_force_ci[0]:.3f}–{fig.worst_force_ci[1]:.3f}")
            v["torque"].setText(f"{fig.worst_torque * 1000:.2f} mN·m (face {wt}), 95\u00a0%: "
                                f"{fig.worst_torque_ci[0] * 1000:.2f}–{fig.worst_torque_ci[1] * 1000:.2f}")
            v["reactions"].setText(f"face {reaction}: {fig.reaction_force:.2f} N, {fig.reaction_torque * 1000:.1f} mN·m"
                                   if reaction else "—")
            v["per_face"].setText(per_face_text(fig, getattr(self, "completing", None), reaction, completed,
                                                cal.has_output))
            v["reactions"].setToolTip("The flange's face carried the reactions of the other faces' loads, never a "
                                      "load of its own; its error is shown apart, not as a loaded face.")
        else:
            v["force"].setText("n/a (no validation pass)")
            v["torque"].setText("n/a (no validation pass)")
            v["per_face"].setText("n/a (no validation pass)")
            v["reactions"].setText("—")
        note = report.identification_note(ev, reaction)  # what holds the figure down, on the page
        text = identification_text(ev, completed) + (f" — {note}" if note else "")
        if fig is None:  # no fresh loads: the fit's own held-out samples, said as such (they score higher)
            text = f"n/a (no validation pass); on held-out samples of the fit (optimistic): {text}"
        v["ident"].setText(text)
        v["ident"].setToolTip(report.identification_why(ev, reaction))  # why the figure is what it is
        ho = m.heldout
        if ho is not None:
            f, t = ho.rmse_force(), ho.rmse_torque()
            if reaction:
                f, t = f.copy(), t.copy()
                f[reaction - 1] = t[reaction - 1] = np.nan
            v["heldout"].setText(f"{np.nanmax(f):.3f} N, {np.nanmax(t) * 1000:.2f} mN·m (optimistic)"
                                 if np.isfinite(f).any() else "n/a")
            v["heldout"].setToolTip("Samples cut from the same captures as the fit share their errors: optimistic. "
                                    "The validation pass above is what a new session shows.")
        cov = cal.coverage
        v["coverage"].setText("✔ every face and the net load" if cov.complete else "⚠ " + cov.describe())

    # ------------------------------------------------------------ actions
    def accept(self) -> None:
        """Accept the fitted calibration: the main window applies it to the live view (``result_changed``)."""
        self.model.accepted = True
        self.model.result_changed.emit()
        self.refresh()

    def _redo_clicked(self) -> None:
        face = self.redo_face.currentData()
        if face is not None:
            self.redo(int(face))

    def redo(self, face: int) -> None:
        """Drop the face's captures and go back to loading it (on the mount that loads it: the main one, or the second)."""
        m = self.model
        m.set_stage(next((i for i, st in enumerate(m.stages) if st.kind != "validation" and face in st.faces), 0))
        self.model.clear_face(face)
        self.model.set_current_face(face)
        if self.redo_requested is not None:
            self.redo_requested(face)

    def save(self, path=None):
        """Save the accepted calibration to ``path`` (asks if None); returns the path or None."""
        if self.model.calibration is None:
            return None
        if path is None:
            path, _ = QFileDialog.getSaveFileName(self, "Save calibration", f"pito-{self.model.method}{CALIBRATION_SUFFIX}",
                                                  CALIBRATION_SAVE_FILTER)
            if not path:
                return None
            if not Path(path).suffix:
                path += CALIBRATION_SUFFIX
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
        main = m.stages[0]
        info = {
            "method": m.method, "flange": main.flange, "connected face": main.connected_face,
            "faces loaded": ", ".join(map(str, main.faces)), "samples per face (k)": m.base_rules.k,
            "reactions only": f"face {main.connected_face}" if main.flange == "face" else "none",
            "second mount": next((f"{st.flange} on face {st.connected_face}, faces {', '.join(map(str, st.faces))}: "
                                  f"{st.why}" for st in m.stages if st.kind == "completing"), "none"),
            "headline": "validation pass of fresh loads (not fitted)" if m.heldout is not m.evaluation
                        else "held-out samples of the fitted captures",
            "measures": m.calibration.coverage.describe(),
            "simulated": m.simulated, "calibration file": m.saved_path or "(not saved)",
        }
        cal, ev = m.calibration, m.evaluation
        rmse, figures = dict(getattr(self, "_rmse_options", None) or {}), getattr(self, "figures", None)
        rmse["completed"] = tuple(f for st in m.stages if st.kind == "completing" for f in st.faces)

        def work(progress):  # the page's words, intervals and reactions (rmse_options, the validation figures)
            return report.export_report(folder, cal, ev, info, progress=progress, rmse=rmse, figures=figures)

        def done(path):
            self.exported_path = path
            self.show_exported(Path(path))

        self.export_task = run_task(work, "Exporting the report", done,
                                    lambda msg: self.values["status"].setText(f"✘ export failed: {msg}"),
                                    bar=self.taskbar, owner=self)
        self.export_task.ended.connect(self.refresh)
        self.refresh()
        return Path(folder) / "report.md"

    def forget_export(self) -> None:
        """No report exported for the calibration shown (a new fit replaced the one exported)."""
        self.exported_path = None
        self.exported_label.clear()
        self.exported_label.setVisible(False)

    def show_exported(self, report_md: Path) -> None:
        """Say where the report went: its files, the folder's path and a link that opens it."""
        folder = report_md.parent
        names = ", ".join(sorted(p.name for p in folder.iterdir() if p.is_file()))
        url = QUrl.fromLocalFile(str(folder.resolve())).toString()
        self.exported_label.setText(f"✔ Report exported to <b>{folder}</b> ({names}) — <a href=\"{url}\">Open folder</a>")
        self.exported_label.setToolTip(str(report_md))
        self.exported_label.setVisible(True)

    @property
    def exporting(self) -> bool:
        t = getattr(self, "export_task", None)
        return t is not None and t.running

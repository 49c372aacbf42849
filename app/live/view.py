"""Live view: contacts on the patched object, force and equilibrium plots, controls.

The view only *shows* bundles from the live feed (:class:`app.live.feed.LiveFeed`). A bundle
moves the contact glyphs in place and appends its samples to the plots' ring buffers — no
drawing. Drawing is paced by the display, not by the data: a single-shot timer fires at most
``display_rate`` times a second (and only when something new arrived), refreshes the plots
from their rings and asks the 3D view for a frame. The 3D view draws in a thread of its own
(:mod:`app.render_thread`): the glyphs' move is queued to it with the sample time it shows, and
its frame overlaps the plots' paint in the GUI thread. A frame is drawn as soon as data arrive
if the previous one is older than a display period, so pacing adds no latency beyond it.

``scene_time`` and ``force_plot.last_time`` are the times (s, host clock) of the newest sample
the scene and the force plot show (the live-window benchmark reads them back off the screen).
"""

from __future__ import annotations

import time

import numpy as np
from PySide6.QtCore import Qt, QTimer, Signal
from PySide6.QtWidgets import (
    QCheckBox, QComboBox, QDoubleSpinBox, QFormLayout, QGroupBox, QHBoxLayout, QLabel, QPushButton, QSizePolicy, QSlider,
    QSpinBox, QSplitter, QVBoxLayout, QWidget,
)

from pito_core.calibration import NOT_MEASURED_TEXT
from pito_core.contact import reason_names
from pito_core.pipeline import TareSupport

from ..scene import CubeScene
from ..widgets.plots import EquilibriumPlot, FaceForcePlot

__all__ = ["LiveView", "unmeasured_faces_text", "sample_sums", "flagged_text", "DEMO_SCENARIOS"]

#: The demo's scenarios in the live view: (shown, ``DemoWorld`` name).
DEMO_SCENARIOS = (("Demo: grasp loop", "grasp"), ("Demo: at rest on the table", "rest"),
                  ("Demo: two fingers on one patch", "two_fingers"))

#: Why one fingertip cannot explain a contact, by ``SingleContactReason`` name (``pito_core.contact``).
FLAG_WHY = {"outside": "its point falls off the patch", "pulling": "the force pulls",
            "friction": "the sideways force exceeds a fingertip's friction",
            "torsion": "the twist exceeds what a fingertip's friction gives",
            "residual": "the wrench fits no single point", "no_solution": "no point of the patch explains it"}


def flagged_text(contacts, shown) -> str:
    """The red-pink contacts in words: which face and why one fingertip cannot explain its wrench ("" if none)."""
    single = getattr(contacts, "single_contact", None)
    if single is None:
        return ""
    faces = np.flatnonzero(np.asarray(shown, bool) & ~np.asarray(single, bool))
    if not faces.size:
        return ""
    names = reason_names(contacts.single_contact_reason)
    p = contacts.single_contact_p
    parts = [f"face {k + 1}: {FLAG_WHY.get(names[k], names[k] or 'implausible')} (p = {p[k]:.2g})" for k in faces]
    return ("● red-pink contact — one fingertip cannot produce this wrench (two fingers on one patch?): "
            + "; ".join(parts))


def sample_sums(wrenches, core, cog=(0.0, 0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    """‖ΣF‖ (N) and ‖ΣT‖ about ``cog`` (N·m), each ``(n,)``, of face wrenches ``(n, 6, 6)`` (face frames):
    ``pito_core.pipeline``'s ``face_sums`` for every sample (faces with NaN left out)."""
    W = np.asarray(wrenches, dtype=float)
    T = core.face_poses()
    R, p = T[:, :3, :3], T[:, :3, 3]
    ok = np.isfinite(W).all(axis=2)  # (n, 6)
    f = np.where(ok[..., None], np.einsum("kij,nkj->nki", R, np.nan_to_num(W[..., :3])), 0.0)
    m = np.where(ok[..., None], np.einsum("kij,nkj->nki", R, np.nan_to_num(W[..., 3:])), 0.0) + np.cross(p, f)
    F = f.sum(axis=1)
    M = m.sum(axis=1) - np.cross(np.asarray(cog, dtype=float), F)
    return np.linalg.norm(F, axis=1), np.linalg.norm(M, axis=1)


def unmeasured_faces_text(measured, sums: bool = False) -> str:
    """What the calibration does not measure, in words: ``"   face 6: not measured by this calibration"``.

    ``measured`` (6, 6) bool (a bundle's ``measured``); with ``sums`` the net load (‖ΣF‖, ‖ΣT‖) too.
    """
    faces = [] if measured is None else [i + 1 for i in range(6) if not np.all(measured[i])]
    parts = ["‖ΣF‖, ‖ΣT‖"] if sums else []
    if len(faces) == 6:
        parts.append("every face")
    elif faces:
        parts.append(f"face{'s' if len(faces) > 1 else ''} {', '.join(map(str, faces))}")
    return f"   {' and '.join(parts)}: {NOT_MEASURED_TEXT}" if parts else ""


class LiveView(QWidget):
    """The assembled object with its contacts, plus plots and acquisition controls.

    Signals are requests to the owner (the main window posts them to the feed):
    ``tare_requested``, ``pause_toggled(bool)``, ``record_toggled(bool)``,
    ``replay_requested``, ``seek_requested(float)`` (s), ``calibration_requested``,
    ``assembly_requested(str)``.
    """

    tare_requested = Signal()
    undo_tare_requested = Signal()
    pause_toggled = Signal(bool)
    record_toggled = Signal(bool)
    replay_requested = Signal()
    live_requested = Signal()
    seek_requested = Signal(float)
    calibration_requested = Signal()
    assembly_requested = Signal(str)
    scenario_requested = Signal(str)

    def __init__(self, core=None, assemblies=(), parent=None):
        super().__init__(parent)
        self._init_scene_and_plots(core)
        bar, status = self._build_toolbar(assemblies)
        self._build_notice()
        timeline = self._build_timeline()
        options = self._build_display_options()
        self._lay_out(bar, status, options, timeline)
        self._connect_controls()
        self._init_display_pacing()

    def _init_scene_and_plots(self, core) -> None:
        """The 3D scene (its glyph scale), the two plots and the display counters."""
        self.paused = False
        self.scene = CubeScene(core, threaded=True)  # drawn in a thread of its own (app/render_thread.py)
        self.scene.setMinimumSize(640, 480)
        self.force_plot = FaceForcePlot()
        self.equilibrium = EquilibriumPlot(rate=1000.0)  # every sample, as the face plot
        self.bundles_shown = 0
        self.latency = float("nan")
        self.frames = 0  # display ticks that drew something
        self.scene.glyphs.force_scale = 0.0035  # m/N: 12 N (full scale) -> 4.2 cm
        self.cog = np.zeros(3)  # m, core frame: the object's centre of gravity (ΣT about it)
        self.scene.glyphs.ellipsoid_scale = 10.0  # a firm touch's 2σ (~0.3 mm) is seen past the 3.5 mm sphere
        self.scene.frame_glyphs = True  # the camera holds full-scale arrows, for every object

    def _build_toolbar(self, assemblies) -> tuple[QHBoxLayout, QHBoxLayout]:
        """The row of buttons (object, calibration, tare, pause, record, replay) and the tare status line."""
        bar = QHBoxLayout()
        self.assembly = QComboBox()
        self.assembly.addItems(list(assemblies) or ["cube"])
        self.load_cal = QPushButton("Load calibration…")
        self.tare = QPushButton("Tare")
        self.tare.setToolTip("Zero the cube on the last 0.5 s — only when it is still and every load is known:\n"
                             "nothing on it (in a stand), or at rest on the table on the base face below, which then\n"
                             "reads the object's weight (its mass below); refused otherwise, with the load named")
        self.undo_tare = QPushButton("Undo tare")
        self.undo_tare.setEnabled(False)
        self.tare_label = QLabel("Tare: none (no calibration)")
        self.tare_label.setProperty("ok", False)
        self.tare_label.setObjectName("tareStatus")
        self.pause = QPushButton("Pause")
        self.pause.setCheckable(True)
        self.record = QPushButton("● Record")
        self.record.setCheckable(True)
        self.record.setObjectName("record")
        self.replay = QPushButton("Replay…")
        self.back_live = QPushButton("Back to live")
        self.back_live.setVisible(False)
        self.scenario = QComboBox()  # demo only: what the simulated world does
        for text, name in DEMO_SCENARIOS:
            self.scenario.addItem(text, name)
        self.scenario.setToolTip("SIMULATED: what the simulated hand does — the grasp loop, or the object at rest "
                                 "on the table (hands off: try Tare and Undo tare)")
        self.scenario.setVisible(False)
        for w in (QLabel("Object"), self.assembly, self.load_cal, self.tare, self.undo_tare, self.pause, self.record,
                  self.replay, self.back_live, self.scenario):
            bar.addWidget(w)
        bar.addStretch(1)
        self.readout = QLabel("")
        self.readout.setObjectName("value")
        self.readout.setAlignment(Qt.AlignmentFlag.AlignRight | Qt.AlignmentFlag.AlignVCenter)
        bar.addWidget(self.readout)
        # the tare in force (or why one was refused): a line of its own, wrapped, never widening the window
        status = QHBoxLayout()
        self.tare_label.setWordWrap(True)
        self.tare_label.setSizePolicy(QSizePolicy.Policy.Ignored, QSizePolicy.Policy.Preferred)
        status.addWidget(self.tare_label, 1)
        self.flag_note = QLabel("")  # why a contact is red-pink (single_contact False)
        self.flag_note.setObjectName("flagNote")
        self.flag_note.setStyleSheet("QLabel#flagNote { color: #ff3b6b; font-weight: bold; }")
        self.flag_note.setWordWrap(True)
        self.flag_note.setSizePolicy(QSizePolicy.Policy.Ignored, QSizePolicy.Policy.Preferred)
        status.addWidget(self.flag_note, 1)
        return bar, status

    def _build_notice(self) -> None:
        """A notice over the view: what is wrong and what to do (e.g. no calibration)."""
        self.notice = QLabel("")
        self.notice.setObjectName("notice")
        self.notice.setWordWrap(True)
        self.notice.setStyleSheet("QLabel#notice { background: #5a2a22; color: #ffffff; font-size: 11pt;"
                                  " font-weight: bold; border: 1px solid #e74c3c; border-radius: 5px; padding: 8px; }")
        self.notice.setVisible(False)

    def _build_timeline(self) -> QHBoxLayout:
        """The replay timeline: slider and time label."""
        tl = QHBoxLayout()
        self.timeline = QSlider(Qt.Orientation.Horizontal)
        self.timeline.setRange(0, 1000)
        self.timeline.setValue(self.timeline.maximum())  # live: the knob at the live end
        self.timeline.setEnabled(False)
        self.time_label = QLabel("live")
        self.time_label.setMinimumWidth(150)
        tl.addWidget(QLabel("Timeline"))
        tl.addWidget(self.timeline, 1)
        tl.addWidget(self.time_label)
        return tl

    def _build_display_options(self) -> QGroupBox:
        """The "Display" box: contact threshold, arrow and ring scales, torsion rings, ellipsoids."""
        opts = QGroupBox("Display")
        form = QFormLayout(opts)
        self.threshold = QDoubleSpinBox()
        self.threshold.setRange(0.0, 20.0)
        self.threshold.setSingleStep(0.1)
        self.threshold.setSuffix(" N")
        self.force_scale = QDoubleSpinBox()
        self.force_scale.setRange(0.5, 50.0)
        self.force_scale.setSuffix(" mm/N")
        self.torque_scale = QDoubleSpinBox()
        self.torque_scale.setRange(10.0, 2000.0)
        self.torque_scale.setSingleStep(10)
        self.torque_scale.setSuffix(" mm per N·m")
        self.show_torsion = QCheckBox("torsion rings")
        self.show_uncertainty = QCheckBox("uncertainty ellipsoids (2σ), drawn ×")
        self.show_uncertainty.setToolTip(
            "The 2σ region of each contact point, from the calibration's own uncertainty (fit and gauge noise).\n"
            "Not drawn when wider than half the face (a light touch: the face cannot place it),\n"
            "nor when it fits inside the white sphere (a firm touch: the point is known better than the sphere).\n"
            "A calibration without an uncertainty record shows none. The line below says which, and why.")
        self.ellipsoid_scale = QSpinBox()
        self.ellipsoid_scale.setRange(1, 50)
        self.ellipsoid_scale.setValue(10)
        self.ellipsoid_scale.setToolTip("Magnification of the drawn ellipsoids: a firm touch places its point to "
                                        "a fraction of a millimetre, inside the contact sphere at ×1")
        self.ellipsoid_note = QLabel("")
        self.ellipsoid_note.setObjectName("hint")
        self.ellipsoid_note.setWordWrap(True)
        self.ellipsoid_note.setVisible(False)
        form.addRow("Hide contacts under", self.threshold)
        form.addRow("Force arrows", self.force_scale)
        form.addRow("Torsion ring radius", self.torque_scale)
        form.addRow(self.show_torsion)
        unc = QHBoxLayout()
        unc.addWidget(self.show_uncertainty)
        unc.addWidget(self.ellipsoid_scale)
        unc.addStretch(1)
        form.addRow(unc)
        form.addRow(self.ellipsoid_note)
        self.mass = QDoubleSpinBox()
        self.mass.setRange(0.0, 50.0)
        self.mass.setDecimals(3)
        self.mass.setSingleStep(0.01)
        self.mass.setSuffix(" kg")
        self.mass.setSpecialValueText("unknown")
        self.mass.setToolTip("The object's mass: its weight on the base face is the load a tare at rest on the table\n"
                             "leaves on that face (unknown: a tare only with nothing on the cube)")
        self.base_face = QComboBox()
        self.base_face.addItems([f"face {i}" for i in range(1, 7)])
        self.base_face.setCurrentIndex(5)
        self.base_face.setToolTip("The face the object stands on when at rest on the table")
        rest = QHBoxLayout()
        rest.addWidget(self.mass)
        rest.addWidget(QLabel("on"))
        rest.addWidget(self.base_face)
        form.addRow("Tare at rest: mass", rest)
        return opts

    def _lay_out(self, bar, status, opts, tl) -> None:
        """Scene beside the plots and options (a splitter), under the toolbar, status and notice."""
        side = QVBoxLayout()
        side.addWidget(self.force_plot, 3)
        side.addWidget(self.equilibrium, 4)
        side.addWidget(opts)
        side_w = QWidget()
        side_w.setLayout(side)
        split = QSplitter()
        split.addWidget(self.scene)
        split.addWidget(side_w)
        split.setStretchFactor(0, 3)
        split.setStretchFactor(1, 2)
        lay = QVBoxLayout(self)
        lay.setContentsMargins(6, 6, 6, 6)
        lay.addLayout(bar)
        lay.addLayout(status)
        lay.addWidget(self.notice)
        lay.addWidget(split, 1)
        lay.addLayout(tl)

    def _connect_controls(self) -> None:
        """Widgets ← glyph settings, then every control's signal to its handler or to this view's signals."""
        self.sync_options()
        self.threshold.valueChanged.connect(self._options_changed)
        self.force_scale.valueChanged.connect(self._options_changed)
        self.torque_scale.valueChanged.connect(self._options_changed)
        self.show_torsion.toggled.connect(self._options_changed)
        self.show_uncertainty.toggled.connect(self._options_changed)
        self.ellipsoid_scale.valueChanged.connect(self._options_changed)
        self.tare.clicked.connect(self.tare_requested)
        self.undo_tare.clicked.connect(self.undo_tare_requested)
        self.pause.toggled.connect(self._pause)
        self.record.toggled.connect(self._record)
        self.replay.clicked.connect(self.replay_requested)
        self.back_live.clicked.connect(self.live_requested)
        self.load_cal.clicked.connect(self.calibration_requested)
        self.assembly.currentTextChanged.connect(self.assembly_requested)
        self.scenario.currentIndexChanged.connect(lambda i: self.scenario_requested.emit(self.scenario.itemData(i)))
        self.timeline.sliderReleased.connect(self._seek)

    def _init_display_pacing(self) -> None:
        """The latest contacts and sums, the pacer (timer and rates) that draws the scene and plots, the readout."""
        self._last_contacts = None
        self._last_contacts_time = float("nan")
        #: the feed hands contacts to the drawing thread itself (:meth:`take_contacts`, set by
        #: the main window while this view is the current tab); on_bundle then only counts them
        self.direct_contacts = False
        self._n_shown = 0
        self._sums = None  # (‖ΣF‖ N, ‖ΣT‖ N·m) of the latest bundle (NaN: not measured by the calibration)
        self._measured = None  # (6, 6) bool: face axes the calibration measures
        #: Hz: most frames a second (scene and plots); the pacer draws only when data are new
        self.display_rate = 60.0
        self.readout_rate = 5.0  # Hz: text that a person reads
        self._pacer = QTimer(self)
        self._pacer.setSingleShot(True)
        self._pacer.setTimerType(Qt.TimerType.PreciseTimer)
        self._pacer.timeout.connect(self.display)
        self._last_display = -1e9
        self._last_readout = -np.inf
        self._readout_text = ""
        self.scene.frame_contacts()

    def tare_support(self):
        """The object at rest as the operator describes it (mass, base face): a ``TareSupport``, or None (mass unknown)."""
        m = self.mass.value()
        return TareSupport(m, self.base_face.currentIndex() + 1) if m > 0 else None

    def set_notice(self, text: str | None) -> None:
        """Show ``text`` prominently above the view (``None`` or empty: hide it)."""
        self.notice.setText(text or "")
        self.notice.setVisible(bool(text))

    # ------------------------------------------------------------ options (glyphs are the model)
    def sync_options(self) -> None:
        """Glyph settings → widgets, signals blocked."""
        g = self.scene.glyphs
        widgets = (self.threshold, self.force_scale, self.torque_scale, self.show_torsion, self.show_uncertainty,
                   self.ellipsoid_scale)
        for w in widgets:
            w.blockSignals(True)
        self.threshold.setValue(g.threshold)
        self.force_scale.setValue(g.force_scale * 1000)
        self.torque_scale.setValue(g.torque_scale * 1000)
        self.show_torsion.setChecked(g.show_torsion)
        self.show_uncertainty.setChecked(g.show_uncertainty)
        self.ellipsoid_scale.setValue(int(round(g.ellipsoid_scale)))
        for w in widgets:
            w.blockSignals(False)

    def _options_changed(self, *_) -> None:
        g = self.scene.glyphs
        g.threshold = self.threshold.value()
        g.force_scale = self.force_scale.value() / 1000
        g.torque_scale = self.torque_scale.value() / 1000
        g.show_torsion = self.show_torsion.isChecked()
        g.show_uncertainty = self.show_uncertainty.isChecked()
        g.ellipsoid_scale = float(self.ellipsoid_scale.value())
        if not g.show_uncertainty:
            self.ellipsoid_note.setVisible(False)
        if self._last_contacts is not None:
            self._show_contacts(self._last_contacts, self.scene_time)
        if self.sender() is self.force_scale:
            self.scene.frame_contacts()  # full-scale arrows stay in view
        self.scene.redraw()

    def _pause(self, on: bool) -> None:
        """Pause freezes the screen (plots, glyphs, readout); acquisition goes on and the plots'
        rings keep filling, so Resume shows the last seconds as they were measured."""
        self.paused = on
        self.pause.setText("Resume" if on else "Pause")
        self.pause_toggled.emit(on)
        if not on:
            if self._last_contacts is not None:
                self._show_contacts(self._last_contacts, self._last_contacts_time)
            self.request_display()

    def _record(self, on: bool) -> None:
        self.record.setText("■ Stop recording" if on else "● Record")
        self.record_toggled.emit(on)

    def _seek(self) -> None:
        dur = self.timeline.property("duration") or 0.0
        self.seek_requested.emit(self.timeline.value() / 1000 * float(dur))

    def set_replay_mode(self, on: bool, duration: float = 0.0) -> None:
        """Replay (the timeline seekable from its start) or live (the knob at the live end, disabled)."""
        self.timeline.blockSignals(True)
        self.timeline.setValue(0 if on else self.timeline.maximum())
        self.timeline.blockSignals(False)
        self.timeline.setEnabled(on)
        self.timeline.setProperty("duration", duration)
        self.back_live.setVisible(on)
        self.record.setEnabled(not on)
        self.time_label.setText("replay" if on else "live")
        self.force_plot.clear_data()
        self.equilibrium.clear_data()

    # ------------------------------------------------------------ data
    @property
    def scene_time(self) -> float:
        """s: time of the newest sample the contact glyphs show (changes with them, in the drawing thread)."""
        return self.scene.contacts_time

    def _show_contacts(self, c, t: float = float("nan")) -> np.ndarray:
        return self.scene.show_contacts(c, t)

    def take_contacts(self, contacts, t: float) -> None:
        """Contacts (sample time ``t``, s) straight from the source's thread (the feed's sink) to the 3D view's next frame.

        Thread-safe; does nothing while paused, when not :attr:`direct_contacts`, or when the
        scene draws in the GUI thread (it is not drawing in a thread of its own yet).
        """
        if self.direct_contacts and not self.paused and self.scene.render_thread is not None:
            self.scene.show_contacts(contacts, t, queue_only=True)
            self.scene.redraw()

    def on_bundle(self, b) -> None:
        """Take one bundle: samples into the plots' rings, the contacts to the 3D view's next frame; a plot frame is requested (no drawing)."""
        if b.replay_position is not None and b.replay_duration:
            if not self.timeline.isSliderDown():
                self.timeline.blockSignals(True)
                self.timeline.setValue(int(1000 * b.replay_position / b.replay_duration))
                self.timeline.blockSignals(False)
            self._replay_text = f"replay {b.replay_position:6.2f} / {b.replay_duration:.2f} s"
        if self.record.isChecked():
            self._record_text = f"■ Stop recording ({b.recorded / 1000:.1f} k samples)"
        arrived = b.arrived_time if b.arrived_time is not None else np.zeros(0)
        if arrived.size == 0 and b.time.size == 0:
            return
        t = b.contacts_time if np.isfinite(b.contacts_time) else b.latest_time
        self._append_plots(b, arrived, t)  # paused too: the rings keep the history, only the screen stops
        if self.paused:
            if b.contacts is not None:
                self._last_contacts, self._last_contacts_time = b.contacts, t
            return
        if np.isfinite(t):
            self.latency = time.monotonic() - t  # s from the newest sample's time to its display
        if b.contacts is not None:
            # to the scene's drawing thread at once (it keeps only the latest for its next frame):
            # the 3D view is not held back by the plots' pacing
            self._last_contacts, self._last_contacts_time = b.contacts, t
            if self.direct_contacts and self.scene.render_thread is not None:
                self._n_shown = int(self.scene.glyphs.visible(b.contacts).sum())  # (already queued by the feed)
            else:
                self._n_shown = int(self._show_contacts(b.contacts, t).sum())
                self.scene.redraw()
        self.bundles_shown += 1
        self.request_display()

    def _append_plots(self, b, arrived, t: float) -> None:
        """The bundle's samples into the plots' rings (no drawing)."""
        if b.wrenches is not None:
            fw = b.arrived_face_wrenches
            every = fw is not None and fw.shape[0] == arrived.size
            if every:
                # every sample as it arrives (its record, paired with the reference, comes later)
                self.force_plot.append(arrived, np.linalg.norm(fw[:, :, :3], axis=2))
            else:
                self.force_plot.append(t, np.linalg.norm(b.wrenches[:, :3], axis=1))
            if b.sum_force is not None:
                self._sums = (float(np.linalg.norm(b.sum_force)), float(np.linalg.norm(b.sum_torque)))
                if np.isfinite(self._sums[0]):  # NaN: the calibration does not measure the net load
                    if every and arrived.size:  # every sample too: no break where the face plot has none
                        self.equilibrium.append(arrived, *sample_sums(fw, self.scene.core, self.cog))
                    else:
                        self.equilibrium.append(t, *self._sums)
            self._measured = b.measured

    def set_tare_status(self, text: str, can_undo: bool) -> None:
        """The tare in force (or why a tare was refused), and whether Undo tare has something to undo."""
        self.tare_label.setText(text)
        self.tare_label.setProperty("ok", text.startswith("Tare: taken") or text.startswith("Tare: the calibration"))
        self.tare_label.style().polish(self.tare_label)
        self.undo_tare.setEnabled(bool(can_undo))

    # ------------------------------------------------------------ drawing, paced by the display
    def request_display(self) -> None:
        """Draw soon: now if the last frame is a display period old, else when it will be."""
        if self._pacer.isActive():
            return
        wait = self._last_display + 1.0 / self.display_rate - time.monotonic()
        self._pacer.start(max(0, int(round(wait * 1000))))

    def display(self) -> None:
        """One frame of the plots: from their rings (decimated to pixels), and the readout (the 3D view draws on its own)."""
        now = time.monotonic()
        self._last_display = now
        if self._sums is not None:
            fs, ts = self._sums
            n = self._n_shown
            self._readout_text = f"{n} contact{'s' if n != 1 else ''}   " + (
                f"‖ΣF‖ {fs:5.2f} N   ‖ΣT‖ {ts * 1000:5.1f} mN·m" + unmeasured_faces_text(self._measured)
                if np.isfinite(fs) else unmeasured_faces_text(self._measured, sums=True).strip())
        if self.force_plot.isVisible():
            self.force_plot.refresh()
            self.equilibrium.refresh()
        if now - self._last_readout >= 1.0 / self.readout_rate:
            self._last_readout = now
            if self._readout_text != self.readout.text():
                self._set_readout(self._readout_text)
            flags = flagged_text(self._last_contacts, self.scene.glyphs.visible(self._last_contacts)) \
                if self._last_contacts is not None else ""
            if flags != self.flag_note.text():
                self.flag_note.setText(flags)
            note = self.scene.glyphs.ellipsoid_note()
            if note != self.ellipsoid_note.text():
                self.ellipsoid_note.setText(note)
                self.ellipsoid_note.setVisible(bool(note))
            rt = getattr(self, "_replay_text", None)
            if rt and self.timeline.isEnabled():
                self.time_label.setText(rt)
            rec = getattr(self, "_record_text", None)
            if rec and self.record.isChecked():
                self.record.setText(rec)
        self.frames += 1

    def _set_readout(self, text: str) -> None:
        """The readout's new text, without laying out the window again unless it needs more room.

        A label whose size may change asks its parent for a new layout on every text, and Qt
        then repaints the whole window (~13 ms of the GUI thread, 5 times a second). Held at a
        fixed size that only grows, right-aligned after the toolbar's stretch, it shows the
        same pixels.
        """
        r = self.readout
        r.setText(text)
        need = r.sizeHint()
        if need.width() > r.minimumWidth() or need.height() != r.minimumHeight() or r.maximumWidth() != r.minimumWidth():
            r.setFixedSize(max(need.width(), r.minimumWidth()), need.height())

    def showEvent(self, event):  # noqa: N802
        super().showEvent(event)
        self.scene.frame_contacts()  # the view's aspect is known now

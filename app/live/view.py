"""Live view: contacts on the patched object, force and equilibrium plots, controls.

The view only *shows* bundles from the worker (:class:`app.workers.DeviceWorker`): each
bundle moves the contact glyphs in place and appends one point per plot; Qt coalesces the
repaints to the display rate.
"""

from __future__ import annotations

import time

import numpy as np
from PySide6.QtCore import Qt, Signal
from PySide6.QtWidgets import (
    QCheckBox, QComboBox, QDoubleSpinBox, QFormLayout, QGroupBox, QHBoxLayout, QLabel, QPushButton, QSlider,
    QSplitter, QVBoxLayout, QWidget,
)

from ..scene import CubeScene
from ..widgets.plots import EquilibriumPlot, FaceForcePlot

__all__ = ["LiveView"]


class LiveView(QWidget):
    """The assembled object with its contacts, plus plots and acquisition controls.

    Signals are requests to the owner (the main window forwards them to the worker):
    ``tare_requested``, ``pause_toggled(bool)``, ``record_toggled(bool)``,
    ``replay_requested``, ``seek_requested(float)`` (s), ``calibration_requested``,
    ``assembly_requested(str)``.
    """

    tare_requested = Signal()
    pause_toggled = Signal(bool)
    record_toggled = Signal(bool)
    replay_requested = Signal()
    live_requested = Signal()
    seek_requested = Signal(float)
    calibration_requested = Signal()
    assembly_requested = Signal(str)

    def __init__(self, core=None, assemblies=(), parent=None):
        super().__init__(parent)
        self.paused = False
        self.scene = CubeScene(core)
        self.scene.setMinimumSize(640, 480)
        self.force_plot = FaceForcePlot()
        self.equilibrium = EquilibriumPlot()
        self.bundles_shown = 0
        self.latency = float("nan")
        self.scene.glyphs.force_scale = 0.004  # m/N: 15 N -> 6 cm

        # --- toolbar
        bar = QHBoxLayout()
        self.assembly = QComboBox()
        self.assembly.addItems(list(assemblies) or ["cube"])
        self.load_cal = QPushButton("Load calibration…")
        self.tare = QPushButton("Tare")
        self.pause = QPushButton("Pause")
        self.pause.setCheckable(True)
        self.record = QPushButton("● Record")
        self.record.setCheckable(True)
        self.record.setObjectName("record")
        self.replay = QPushButton("Replay…")
        self.back_live = QPushButton("Back to live")
        self.back_live.setVisible(False)
        for w in (QLabel("Object"), self.assembly, self.load_cal, self.tare, self.pause, self.record, self.replay, self.back_live):
            bar.addWidget(w)
        bar.addStretch(1)
        self.readout = QLabel("")
        self.readout.setObjectName("value")
        bar.addWidget(self.readout)

        # --- timeline (replay)
        tl = QHBoxLayout()
        self.timeline = QSlider(Qt.Orientation.Horizontal)
        self.timeline.setRange(0, 1000)
        self.timeline.setEnabled(False)
        self.time_label = QLabel("live")
        self.time_label.setMinimumWidth(150)
        tl.addWidget(QLabel("Timeline"))
        tl.addWidget(self.timeline, 1)
        tl.addWidget(self.time_label)

        # --- display options
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
        self.show_uncertainty = QCheckBox("uncertainty ellipsoids (2σ)")
        form.addRow("Hide contacts under", self.threshold)
        form.addRow("Force arrows", self.force_scale)
        form.addRow("Torsion ring radius", self.torque_scale)
        form.addRow(self.show_torsion)
        form.addRow(self.show_uncertainty)

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
        lay.addWidget(split, 1)
        lay.addLayout(tl)

        self.sync_options()
        self.threshold.valueChanged.connect(self._options_changed)
        self.force_scale.valueChanged.connect(self._options_changed)
        self.torque_scale.valueChanged.connect(self._options_changed)
        self.show_torsion.toggled.connect(self._options_changed)
        self.show_uncertainty.toggled.connect(self._options_changed)
        self.tare.clicked.connect(self.tare_requested)
        self.pause.toggled.connect(self._pause)
        self.record.toggled.connect(self._record)
        self.replay.clicked.connect(self.replay_requested)
        self.back_live.clicked.connect(self.live_requested)
        self.load_cal.clicked.connect(self.calibration_requested)
        self.assembly.currentTextChanged.connect(self.assembly_requested)
        self.timeline.sliderReleased.connect(self._seek)
        self._last_contacts = None
        self._last_plot = 0.0
        self.plot_rate = 10.0  # Hz: pyqtgraph repaints its axes on every refresh

    # ------------------------------------------------------------ options (glyphs are the model)
    def sync_options(self) -> None:
        """Glyph settings → widgets, signals blocked."""
        g = self.scene.glyphs
        widgets = (self.threshold, self.force_scale, self.torque_scale, self.show_torsion, self.show_uncertainty)
        for w in widgets:
            w.blockSignals(True)
        self.threshold.setValue(g.threshold)
        self.force_scale.setValue(g.force_scale * 1000)
        self.torque_scale.setValue(g.torque_scale * 1000)
        self.show_torsion.setChecked(g.show_torsion)
        self.show_uncertainty.setChecked(g.show_uncertainty)
        for w in widgets:
            w.blockSignals(False)

    def _options_changed(self, *_) -> None:
        g = self.scene.glyphs
        g.threshold = self.threshold.value()
        g.force_scale = self.force_scale.value() / 1000
        g.torque_scale = self.torque_scale.value() / 1000
        g.show_torsion = self.show_torsion.isChecked()
        g.show_uncertainty = self.show_uncertainty.isChecked()
        if self._last_contacts is not None:
            self._show_contacts(self._last_contacts)
        self.scene.redraw()

    def _pause(self, on: bool) -> None:
        self.paused = on
        self.pause.setText("Resume" if on else "Pause")
        self.pause_toggled.emit(on)

    def _record(self, on: bool) -> None:
        self.record.setText("■ Stop recording" if on else "● Record")
        self.record_toggled.emit(on)

    def _seek(self) -> None:
        dur = self.timeline.property("duration") or 0.0
        self.seek_requested.emit(self.timeline.value() / 1000 * float(dur))

    def set_replay_mode(self, on: bool, duration: float = 0.0) -> None:
        self.timeline.setEnabled(on)
        self.timeline.setProperty("duration", duration)
        self.back_live.setVisible(on)
        self.record.setEnabled(not on)
        self.time_label.setText("replay" if on else "live")
        self.force_plot.clear_data()
        self.equilibrium.clear_data()

    # ------------------------------------------------------------ data
    def _show_contacts(self, c) -> np.ndarray:
        return self.scene.glyphs.update(c["points"], c["normals"], c["forces"], c["torsions"], c["valid"],
                                        c.get("covariance"))

    def on_bundle(self, b) -> None:
        """Show one bundle: glyphs moved in place, one point per plot, a repaint request."""
        if b.replay_position is not None and b.replay_duration:
            if not self.timeline.isSliderDown():
                self.timeline.blockSignals(True)
                self.timeline.setValue(int(1000 * b.replay_position / b.replay_duration))
                self.timeline.blockSignals(False)
            self.time_label.setText(f"replay {b.replay_position:6.2f} / {b.replay_duration:.2f} s")
        if self.record.isChecked():
            self.record.setText(f"■ Stop recording ({b.recorded / 1000:.1f} k samples)")
        if self.paused or b.time.size == 0:
            return
        t = b.latest_time
        self.latency = time.monotonic() - t  # s from the newest sample's arrival to its display
        if b.contacts is not None:
            self._last_contacts = b.contacts
            shown = self._show_contacts(b.contacts)
            n_shown = int(shown.sum())
        else:
            n_shown = 0
        if b.wrenches is not None:
            fn = np.linalg.norm(b.wrenches[:, :3], axis=1)
            self.force_plot.append(t, fn)
            if b.sum_force is not None:
                self.equilibrium.append(t, float(np.linalg.norm(b.sum_force)), float(np.linalg.norm(b.sum_torque)))
            self.readout.setText(
                f"{n_shown} contact{'s' if n_shown != 1 else ''}   ‖ΣF‖ {np.linalg.norm(b.sum_force):5.2f} N   "
                f"‖ΣT‖ {np.linalg.norm(b.sum_torque) * 1000:5.1f} mN·m"
            )
        now = time.monotonic()
        if now - self._last_plot >= 1.0 / self.plot_rate:  # plots at most plot_rate Hz
            self._last_plot = now
            self.force_plot.refresh()
            self.equilibrium.refresh()
        self.scene.redraw()
        self.bundles_shown += 1

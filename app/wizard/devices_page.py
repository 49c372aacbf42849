"""Step 3: devices — the cube's port and the reference sensor, with live raw values and health."""

from __future__ import annotations

import time

import numpy as np
from PySide6.QtCore import Qt, Signal
from PySide6.QtWidgets import (
    QCheckBox, QComboBox, QFormLayout, QGridLayout, QGroupBox, QHBoxLayout, QHeaderView, QLabel, QLineEdit,
    QPushButton, QTableWidget, QTableWidgetItem, QVBoxLayout,
)

from pito_core.devices import list_serial_ports

from .page import WizardPage

__all__ = ["DevicesPage"]

AXES = ("fx (N)", "fy (N)", "fz (N)", "tx (N·m)", "ty (N·m)", "tz (N·m)")


class DevicesPage(WizardPage):
    """Wizard step 3: connect the cube (serial port) and the reference (Net F/T host), or the simulators.

    Shows the raw counts (36,) and the reference wrench ``[fx, fy, fz, tx, ty, tz]`` (N, N·m) live,
    with both sample rates (Hz). Emits ``connect_requested(port, host, simulated)``.

    Parameters
    ----------
    model : app.wizard.model.WizardModel
        The wizard's state (method, mount, captures); the page reads and sets it.
    parent : QWidget, optional
    """
    title = "3 · Devices"
    help = ("Connect the cube (serial port) and the reference sensor (ATI Net F/T address). Check that the raw "
            "values move when you touch the cube, that both sample rates are steady, and that nothing saturates "
            "or drops frames.")

    #: (port, host, simulated): the window opens the devices and gives them to the live feed
    connect_requested = Signal(str, str, bool)

    def __init__(self, model, parent=None):
        super().__init__(model, parent)
        self.body.addWidget(self._connection_box())
        self.body.addWidget(self._health_box())
        self.body.addLayout(self._raw_readings(), 1)
        self.connect_btn.clicked.connect(self._connect)
        self._last_table = 0.0
        self._seen = 0
        self.connected = False

    def _connection_box(self) -> QGroupBox:
        """Port, Net F/T address, simulators, Connect and its state."""
        box = QGroupBox("Connection")
        form = QFormLayout(box)
        self.port = QComboBox()
        self.port.setEditable(True)
        self.port.addItems([p["device"] for p in list_serial_ports()] or ["/dev/ttyACM0"])
        self.host = QLineEdit("192.168.1.1")
        self.simulated = QCheckBox("Use the simulators (virtual cube on a pty, virtual Net F/T on loopback UDP)")
        self.connect_btn = QPushButton("Connect")
        self.connect_btn.setObjectName("primary")
        self.status = QLabel("not connected")
        self.status.setObjectName("state")
        form.addRow("Cube serial port", self.port)
        form.addRow("Reference Net F/T address", self.host)
        form.addRow(self.simulated)
        row = QHBoxLayout()
        row.addWidget(self.connect_btn)
        row.addWidget(self.status, 1)
        form.addRow(row)
        return box

    def _health_box(self) -> QGroupBox:
        """Rates, saturated samples and dropped frames: ``self.health[key]`` is each value's label."""
        health = QGroupBox("Health")
        hg = QGridLayout(health)
        self.health = {}
        for c, (key, text) in enumerate((
            ("rate_cube", "Cube rate"), ("rate_reference", "Reference rate"),
            ("saturated", "Saturated samples"), ("dropped", "Dropped frames"),
        )):
            hg.addWidget(QLabel(text), 0, c)
            lab = QLabel("—")
            lab.setObjectName("bigValue")
            hg.addWidget(lab, 1, c)
            self.health[key] = lab
        return health

    def _raw_readings(self) -> QHBoxLayout:
        """The 36 gauge counts (a face per row) beside the reference's six readings."""
        raw = QHBoxLayout()
        gbox = QGroupBox("Gauge counts (raw) — face rows, channels 1–6")
        gl = QVBoxLayout(gbox)
        self.table = QTableWidget(6, 6)
        self.table.setHorizontalHeaderLabels([f"ch {k}" for k in range(1, 7)])
        self.table.setVerticalHeaderLabels([f"face {i}" for i in range(1, 7)])
        self.table.horizontalHeader().setSectionResizeMode(QHeaderView.ResizeMode.Stretch)
        self.table.verticalHeader().setSectionResizeMode(QHeaderView.ResizeMode.Stretch)
        self.table.setEditTriggers(QTableWidget.EditTrigger.NoEditTriggers)
        for r in range(6):
            for c in range(6):
                it = QTableWidgetItem("—")
                it.setTextAlignment(Qt.AlignmentFlag.AlignRight | Qt.AlignmentFlag.AlignVCenter)
                self.table.setItem(r, c, it)
        gl.addWidget(self.table)
        raw.addWidget(gbox, 3)
        rbox = QGroupBox("Reference (tared, its own frame)")
        rl = QFormLayout(rbox)
        self.ref_labels = []
        for a in AXES:
            lab = QLabel("—")
            lab.setObjectName("value")
            rl.addRow(a, lab)
            self.ref_labels.append(lab)
        raw.addWidget(rbox, 1)
        return raw

    def _connect(self) -> None:
        self.status.setText("connecting…")
        self._seen = 0
        self.connect_requested.emit(self.port.currentText(), self.host.text(), self.simulated.isChecked())

    def set_connected(self, text: str, ok: bool) -> None:
        """The state of the source the live feed reads (the window calls this whenever it changes it)."""
        self.connected = bool(ok)
        self.status.setText(text)
        self.status.setProperty("ok", ok)
        self.status.style().polish(self.status)
        if not ok:
            self.set_ready(False)

    def on_bundle(self, b) -> None:
        s = b.stats or {}
        for key, fmt in (("rate_cube", "{:.0f} Hz"), ("rate_reference", "{:.0f} Hz"), ("saturated", "{:d}"), ("dropped", "{:d}")):
            v = s.get(key)
            if v is not None:
                self.health[key].setText(fmt.format(int(v) if "d}" in fmt else float(v)))
        if b.time.size:
            if not self.connected:  # data flow, whoever opened the source: the state says so
                self.set_connected("✔ receiving data" + (" (SIMULATED)" if s.get("simulated") else ""), True)
            self._seen += b.time.size
            if self._seen > 100:
                self.set_ready(True)
        now = time.monotonic()
        if now - self._last_table < 0.1 or b.counts.shape[0] == 0:  # 10 Hz is enough to read numbers
            return
        self._last_table = now
        c = b.counts[-1].reshape(6, 6)
        for r in range(6):
            for k in range(6):
                self.table.item(r, k).setText(f"{int(c[r, k]):d}")
        ref = b.reference[-1]
        for k, lab in enumerate(self.ref_labels):
            lab.setText("—" if not np.isfinite(ref[k]) else (f"{ref[k]:+.3f}" if k < 3 else f"{ref[k]:+.4f}"))

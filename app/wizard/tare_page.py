"""Step 4: tare — an unloaded recording of both devices, with a stillness check."""

from __future__ import annotations

import numpy as np
from PySide6.QtWidgets import QGridLayout, QGroupBox, QLabel, QProgressBar, QPushButton, QDoubleSpinBox, QHBoxLayout

from pito_core.defaults import TARE_STILL_FORCE_STD_N, TARE_STILL_TORQUE_STD_NM
from pito_core.pipeline import check_tare

from .page import WizardPage

__all__ = ["TarePage", "STILL_FORCE_STD", "STILL_TORQUE_STD"]

#: Largest standard deviation of the reference during the tare: N and N·m (the one tare check's,
#: ``pito_core.pipeline.check_tare``, which the live view's Tare uses too).
STILL_FORCE_STD = TARE_STILL_FORCE_STD_N
STILL_TORQUE_STD = TARE_STILL_TORQUE_STD_NM


class TarePage(WizardPage):
    """Wizard step 4: record the unloaded offsets (counts (36,), reference (6,) N and N·m) over a duration in s.

    Parameters
    ----------
    model : app.wizard.model.WizardModel
        The wizard's state (method, mount, captures); the page reads and sets it.
    parent : QWidget, optional
    """
    title = "4 · Tare"
    help = ("Take your hands off: nothing may touch the cube or the flange. Record the unloaded offsets of "
            "both devices; the recording is kept only if the cube stayed still.")

    #: called with None when the page opens (the demo's simulated operator lets go)
    operator = None

    def __init__(self, model, parent=None):
        super().__init__(model, parent)
        row = QHBoxLayout()
        self.duration = QDoubleSpinBox()
        self.duration.setRange(0.5, 30.0)
        self.duration.setValue(2.0)
        self.duration.setSuffix(" s")
        self.record = QPushButton("Record tare")
        self.record.setObjectName("primary")
        row.addWidget(QLabel("Duration"))
        row.addWidget(self.duration)
        row.addWidget(self.record)
        row.addStretch(1)
        self.body.addLayout(row)
        self.progress = QProgressBar()
        self.progress.setFormat("%p % recorded")
        self.body.addWidget(self.progress)
        box = QGroupBox("Result")
        grid = QGridLayout(box)
        self.labels = {}
        for r, (key, text) in enumerate((
            ("samples", "Samples"),
            ("force_std", f"Reference force spread (limit {STILL_FORCE_STD} N)"),
            ("torque_std", f"Reference torque spread (limit {STILL_TORQUE_STD * 1000:g} mN·m)"),
            ("counts_std", "Gauge noise, median channel (counts)"),
            ("verdict", "Stillness check"),
        )):
            grid.addWidget(QLabel(text), r, 0)
            lab = QLabel("—")
            lab.setObjectName("value")
            grid.addWidget(lab, r, 1)
            self.labels[key] = lab
        self.body.addWidget(box)
        self.body.addStretch(1)
        self._chunks = None
        self.record.clicked.connect(self.start_recording)

    def enter(self) -> None:
        if self.operator is not None:
            self.operator(None)
        if not self.model.has_tare:  # a new mount (the second): its own tare
            for lab in self.labels.values():
                lab.setText("—")
            self.progress.setValue(0)
        self.set_ready(self.model.has_tare)

    def start_recording(self) -> None:
        self._chunks = []
        self.progress.setValue(0)
        self.labels["verdict"].setText("recording…")
        self.record.setEnabled(False)

    @property
    def recording(self) -> bool:
        return self._chunks is not None

    def on_bundle(self, b) -> None:
        if self._chunks is None or b.time.size == 0:
            return
        self._chunks.append((b.time, b.counts, b.reference))
        t0 = self._chunks[0][0][0]
        elapsed = float(b.time[-1] - t0)
        self.progress.setValue(int(min(100, 100 * elapsed / self.duration.value())))
        if elapsed >= self.duration.value():
            self._finish()

    def _finish(self) -> None:
        chunks, self._chunks = self._chunks, None
        counts = np.concatenate([c[1] for c in chunks])
        reference = np.concatenate([c[2] for c in chunks])
        check = check_tare(counts, reference)  # the live view's Tare checks the same way
        still, sf, st = check.ok, check.reference_force_std, check.reference_torque_std
        self.labels["samples"].setText(f"{counts.shape[0]}")
        self.labels["force_std"].setText(f"{sf:.3f} N")
        self.labels["torque_std"].setText(f"{st * 1000:.3f} mN·m")
        self.labels["counts_std"].setText(f"{np.median(counts.std(axis=0)):.0f}")
        self.labels["verdict"].setText("✔ still — offsets kept" if still else f"✘ {check.reason} — record again")
        self.labels["verdict"].setProperty("ok", still)
        self.labels["verdict"].style().polish(self.labels["verdict"])
        self.model.set_tare(counts, reference, still)
        self.record.setEnabled(True)
        self.set_ready(still)

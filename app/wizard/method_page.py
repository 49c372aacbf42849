"""Step 1: choose the calibration method (and its flange and connected face)."""

from __future__ import annotations

from PySide6.QtWidgets import (
    QButtonGroup, QComboBox, QFormLayout, QGroupBox, QLabel, QRadioButton, QSpinBox, QVBoxLayout,
)

from pito_core.calibration import METHODS

from .model import RECOMMENDED_METHOD, RECOMMENDED_WHY, faces_to_load
from .page import WizardPage

__all__ = ["MethodPage", "FLANGE_TEXT"]

#: Operator names of the flanges (docs/conventions.md, "Calibration mounts").
FLANGE_TEXT = {
    "frame": "type 1 — on the core frame (connected face not loadable)",
    "frame_hole": "type 2 — on the core frame, with an access hole",
    "face": "type 3 — on the connected face itself (it carries the reaction)",
}


class MethodPage(WizardPage):
    """Wizard step 1: choose the calibration method (sets the flange, the faces to load and the outputs).

    Parameters
    ----------
    model : app.wizard.model.WizardModel
        The wizard's state (method, mount, captures); the page reads and sets it.
    parent : QWidget, optional
    """
    title = "1 · Method"
    help = ("Choose how the cube will be calibrated. Each method fixes the flange that holds the cube on the "
            "reference sensor, the faces you load one at a time, and what the calibration outputs.")

    def __init__(self, model, parent=None):
        super().__init__(model, parent)
        box = QGroupBox("Calibration method")
        lay = QVBoxLayout(box)
        self.group = QButtonGroup(self)
        self.buttons = {}
        self.why = QLabel(RECOMMENDED_WHY)
        self.why.setObjectName("emphasis")
        self.why.setWordWrap(True)
        lay.addWidget(self.why)
        for name, spec in METHODS.items():
            label = f"{name}   ({spec.paper})" + ("   — recommended" if name == RECOMMENDED_METHOD else "")
            rb = QRadioButton(label)
            rb.setObjectName("methodRadio")
            text = QLabel(spec.summary)
            text.setWordWrap(True)
            text.setObjectName("methodText")
            text.setIndent(26)
            self.group.addButton(rb)
            self.buttons[name] = rb
            lay.addWidget(rb)
            lay.addWidget(text)
            rb.toggled.connect(lambda on, n=name: on and self._set_method(n))
        self.body.addWidget(box)

        form_box = QGroupBox("Mount and amount of data")
        form = QFormLayout(form_box)
        self.flange = QComboBox()
        self.face = QSpinBox()
        self.face.setRange(1, 6)
        self.face.setPrefix("face ")
        self.k = QSpinBox()
        self.k.setRange(100, 100000)
        self.k.setSingleStep(500)
        self.k.setSuffix(" samples / face")
        self.summary = QLabel()
        self.summary.setObjectName("emphasis")
        self.summary.setWordWrap(True)
        form.addRow("Flange", self.flange)
        form.addRow("Connected face (on the flange)", self.face)
        form.addRow("Samples per face (k)", self.k)
        form.addRow(self.summary)
        self.body.addWidget(form_box)
        self.body.addStretch(1)
        self.flange.currentIndexChanged.connect(self._ui_flange)
        self.face.valueChanged.connect(lambda v: self.model.set_mount(connected_face=v))
        self.k.valueChanged.connect(lambda v: self.model.set_k(v))
        model.mount_changed.connect(self.sync)
        self.sync()
        self.set_ready(True)

    def _set_method(self, name: str) -> None:
        if name != self.model.method:
            self.model.set_mount(method=name)

    def _ui_flange(self, index: int) -> None:
        flange = self.flange.itemData(index)
        if flange and flange != self.model.main_flange:
            self.model.set_mount(flange=flange)

    def sync(self) -> None:
        """Model → widgets, with signals blocked (no loops)."""
        m = self.model
        for w in (self.flange, self.face, self.k, *self.buttons.values()):
            w.blockSignals(True)
        self.buttons[m.method].setChecked(True)
        self.flange.clear()
        for f in m.spec.flanges:
            self.flange.addItem(f"{f}: {FLANGE_TEXT[f]}", f)
        self.flange.setCurrentIndex(list(m.spec.flanges).index(m.main_flange))
        self.face.setValue(m.main_connected_face)
        self.k.setValue(m.base_rules.k)
        for w in (self.flange, self.face, self.k, *self.buttons.values()):
            w.blockSignals(False)
        faces = faces_to_load(m.method, m.main_flange, m.main_connected_face)
        text = (f"You will load faces {', '.join(map(str, faces))} one at a time "
                f"(at least {m.base_rules.k} samples each; usually more, until the coverage bars are green), with the flange on face {m.main_connected_face}; "
                f"then a short validation pass of fresh loads.")
        extra = m.completing
        if extra is not None:
            text += (f"<br><b>Then a second mount</b> ('{extra.flange}' on face {extra.connected_face}, "
                     f"face{'s' if len(extra.faces) > 1 else ''} {', '.join(map(str, extra.faces))}): {extra.why}")
        self.summary.setText(text)

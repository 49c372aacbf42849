"""Step 2: mount the cube on the flange, shown in 3D, and confirm."""

from __future__ import annotations

from PySide6.QtWidgets import QCheckBox, QHBoxLayout, QLabel, QPushButton, QVBoxLayout

from ..scene import CubeScene
from .page import WizardPage

__all__ = ["MountPage", "mount_steps"]


def mount_steps(flange: str, connected_face: int, faces) -> list[str]:
    """The mounting steps in words for ``flange`` on ``connected_face``."""
    c = connected_face
    common_end = [
        "Route the cube's USB cable and the reference sensor's cable so that they hang free and touch nothing.",
        "Do not touch the cube again until the tare step.",
    ]
    if flange == "face":
        steps = [
            "Bolt the reference sensor (ATI) on the bench stand, tool side up.",
            f"Remove the patch of face {c} and screw the type-3 flange onto face {c}'s patch mount (4 × M2, 0.3 N·m).",
            "Screw the flange onto the reference sensor's tool plate: the cube now hangs on face "
            f"{c} only, which carries the reaction of every load.",
        ]
    else:
        hole = flange == "frame_hole"
        steps = [
            "Bolt the reference sensor (ATI) on the bench stand, tool side up.",
            f"Screw the type-{2 if hole else 1} flange{' (with the access hole)' if hole else ''} onto the reference "
            "sensor's tool plate.",
            f"Set the cube's core frame on the flange's four posts with face {c} towards the flange; tighten the four "
            "frame screws. The face's sensing plate must not touch the flange.",
        ]
        if hole:
            steps.append(f"Check that the probe reaches the centre of face {c} through the access hole.")
    steps.append("Faces to load, one at a time: " + ", ".join(map(str, faces)) + ".")
    return steps + common_end


class MountPage(WizardPage):
    """Wizard step 2: show how to mount the cube (flange, connected face 1..6) in a 3-D view; the operator confirms.

    Parameters
    ----------
    model : app.wizard.model.WizardModel
        The wizard's state (method, mount, captures); the page reads and sets it.
    parent : QWidget, optional
    """
    title = "2 · Mount"
    help = ("Mount the cube as shown: the flange's face is orange. Follow the steps, then confirm. "
            "Drag to rotate the view.")

    def __init__(self, model, parent=None):
        super().__init__(model, parent)
        row = QHBoxLayout()
        self.scene = CubeScene(model.core)
        self.scene.setMinimumSize(520, 420)
        row.addWidget(self.scene, 3)
        side = QVBoxLayout()
        self.flange_label = QLabel()
        self.flange_label.setObjectName("emphasis")
        self.flange_label.setWordWrap(True)
        self.steps = QLabel()
        self.steps.setWordWrap(True)
        self.steps.setObjectName("steps")
        self.confirm = QCheckBox("The cube is mounted as shown")
        self.confirm.setObjectName("confirm")
        # the second mount can be left out: the calibration then says what it does not measure
        self.skip = QPushButton("Skip the second mount (the calibration will be partial, and say so)")
        side.addWidget(self.flange_label)
        side.addWidget(self.steps)
        side.addStretch(1)
        side.addWidget(self.skip)
        side.addWidget(self.confirm)
        row.addLayout(side, 2)
        self.body.addLayout(row, 1)
        self.confirm.toggled.connect(self.set_ready)
        self.skip.clicked.connect(self._skip)
        #: set by the wizard: go on to the results after a skip
        self.skip_requested = None
        model.mount_changed.connect(self.sync)
        self.sync()

    def _skip(self) -> None:
        self.model.skip_completing()
        if self.skip_requested is not None:
            self.skip_requested()

    def sync(self) -> None:
        m = self.model
        self.confirm.blockSignals(True)
        self.confirm.setChecked(False)
        self.confirm.blockSignals(False)
        self.set_ready(False)
        text = f"Method {m.method}: flange '{m.flange}' on face {m.connected_face}"
        if m.current.kind == "completing":
            text = f"Second mount — {text}.<br>{m.current.why}"
        self.flange_label.setText(text)
        self.skip.setVisible(m.current.kind == "completing")
        self.steps.setText("<ol>" + "".join(f"<li style='margin-bottom:6px'>{s}</li>" for s in mount_steps(m.flange, m.connected_face, m.faces)) + "</ol>")
        self.scene.set_mount(m.flange, m.connected_face, flange_opacity=0.45)  # see the orange face through it
        self.scene.highlight(connected_face=m.connected_face)
        self.scene.look_at_mount(m.connected_face, elevation=0.3)
        kind = {"frame": "type-1 frame flange", "frame_hole": "type-2 frame flange (access hole)",
                "face": "type-3 face flange"}[m.flange]
        self.scene.set_caption(f"orange: face {m.connected_face}, towards the {kind}\n"
                               "dark cylinder: the reference sensor (ATI) on its stand")

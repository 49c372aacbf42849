"""The results page's model section: which calibration model was chosen, why, and a switch to linear."""

from __future__ import annotations

from PySide6.QtCore import Signal
from PySide6.QtWidgets import QCheckBox, QGroupBox, QLabel, QVBoxLayout

__all__ = ["ModelChoiceBox", "model_summary"]


def model_summary(choice, output_faces=()) -> str:
    """Words for a ``ModelChoice``: the model in use, why, and the cross-validated RMSE (N, N·m) of each
    candidate, the one in use marked — the name and the figures beside it always agree."""
    groups = choice.corrected(output_faces) if choice.name != "linear" else []
    rms = choice.cv_rms()
    if choice.name == "linear":
        head, used = "the papers' linear fit (C = W S⁺)", "linear"
    elif output_faces and not groups:
        head, used = "the linear fit (the correction won on no output group)", "chosen" if "chosen" in rms else "poly"
    elif output_faces:
        head = (f"linear fit + polynomial correction on {len(groups)} of {2 * len(output_faces)} output groups: "
                + ", ".join(f"face {f} {part}" for f, part in groups))
        used = "chosen" if "chosen" in rms else "poly"
    else:
        head, used = "linear fit + polynomial correction", "chosen" if "chosen" in rms else "poly"
    text = f"<b>In use: {head}</b> — {choice.reason}"
    words = {"linear": "the linear fit everywhere", "poly": "the correction on every output group",
             "chosen": "the correction only where it won"}
    for key, (force, torque) in rms.items():
        mark = " <b>(in use)</b>" if key == used else ""
        text += f"<br>cross-validated RMSE, {words[key]}{mark}: forces {force:.3f} N, torques {torque * 1000:.2f} mN·m"
    return text


class ModelChoiceBox(QGroupBox):
    """Shows the model a fit chose and offers the papers' linear fit instead.

    Signals
    -------
    requested_changed(str)
        ``"linear"`` when the user asks for the papers' linear fit, ``"auto"`` to let the data choose.
    """

    requested_changed = Signal(str)

    def __init__(self, parent=None):
        super().__init__("Calibration model", parent)
        lay = QVBoxLayout(self)
        self.text = QLabel("—")
        self.text.setWordWrap(True)
        self.linear = QCheckBox("Use the papers' linear fit (refit)")
        self.linear.setToolTip("By default the model is chosen by cross-validation over loading segments: the "
                               "polynomial correction is used only where it predicts held-out segments better.")
        lay.addWidget(self.text)
        lay.addWidget(self.linear)
        self.linear.toggled.connect(lambda on: self.requested_changed.emit("linear" if on else "auto"))

    @property
    def requested(self) -> str:
        return "linear" if self.linear.isChecked() else "auto"

    def show_choice(self, choice, output_faces=()) -> None:
        """Show a ``ModelChoice`` (or nothing for None), with the groups that use the correction."""
        self.text.setText("—" if choice is None else model_summary(choice, output_faces))

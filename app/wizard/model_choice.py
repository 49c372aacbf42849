"""The results page's model section: which calibration model was chosen, why, and a switch to linear."""

from __future__ import annotations

from PySide6.QtCore import Signal
from PySide6.QtWidgets import QCheckBox, QGroupBox, QLabel, QVBoxLayout

__all__ = ["ModelChoiceBox", "model_summary"]


def _rms(values) -> float:
    v = [float(x) for x in values]
    return (sum(x * x for x in v) / max(len(v), 1)) ** 0.5


def model_summary(choice) -> str:
    """Words for a ``ModelChoice``: the model, why, cross-validated RMSE of both candidates and the chosen mix (N, N·m)."""
    words = {"linear": "the papers' linear fit (C = W S⁺)", "poly": "linear fit + polynomial correction",
             "chosen": "the chosen mix (the correction only where it won)"}
    text = f"<b>{words.get(choice.name, choice.name)}</b> — {choice.reason}"
    for key in ("linear", "poly", "chosen"):
        r = (choice.cv_rmse or {}).get(key) or []
        if r:
            force = [v for i, v in enumerate(r) if i % 6 < 3]
            torque = [v for i, v in enumerate(r) if i % 6 >= 3]
            text += (f"<br>cross-validated RMSE, {words[key]}: forces {_rms(force):.3f} N, "
                     f"torques {_rms(torque) * 1000:.2f} mN·m")
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

    def show_choice(self, choice) -> None:
        """Show a ``ModelChoice`` (or nothing for None)."""
        self.text.setText("—" if choice is None else model_summary(choice))

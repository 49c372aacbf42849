"""The results page's model section: which calibration model was chosen, why, and a switch to linear."""

from __future__ import annotations

from PySide6.QtCore import Signal
from PySide6.QtWidgets import QCheckBox, QGroupBox, QLabel, QVBoxLayout

from pito_core.report import model_summary

__all__ = ["ModelChoiceBox"]


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

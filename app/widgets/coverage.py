"""Coverage bars: how far each wrench axis has been loaded, per sign, against full scale."""

from __future__ import annotations

import numpy as np
from PySide6.QtCore import QObject, QRectF, Qt, Signal
from PySide6.QtGui import QColor, QFont, QPainter, QPen
from PySide6.QtWidgets import QSizePolicy, QWidget

from pito_core.defaults import FULL_SCALE_FACE

__all__ = ["CoverageModel", "CoverageBars", "FULL_SCALE", "AXIS_LABELS"]

#: Full-scale loads of one face: ±15 N, ±0.1 N·m (fx, fy, fz, tx, ty, tz).
FULL_SCALE = np.array(FULL_SCALE_FACE)  # N, N·m per axis (pito_core.defaults)
AXIS_LABELS = ("fx", "fy", "fz", "tx", "ty", "tz")
AXIS_UNITS = ("N", "N", "N", "N·m", "N·m", "N·m")


class CoverageModel(QObject):
    """Coverage of the six wrench axes, each sign apart, as fractions of full scale.

    ``reached (6, 2)``: largest fraction of full scale kept so far, ``[:, 0]`` negative
    and ``[:, 1]`` positive side; ``current (6,)``: the live load as a signed fraction;
    ``required``: the fraction each of the 12 bars must reach.
    """

    changed = Signal()

    def __init__(self, required: float = 0.3, parent=None):
        super().__init__(parent)
        self.required = float(required)
        self.reached = np.zeros((6, 2))
        self.current = np.zeros(6)

    def set_state(self, reached, current) -> None:
        self.reached = np.clip(np.asarray(reached, dtype=float).reshape(6, 2), 0.0, 1.0)
        self.current = np.clip(np.asarray(current, dtype=float).reshape(6), -1.0, 1.0)
        self.changed.emit()

    def set_current(self, current) -> None:
        self.current = np.clip(np.nan_to_num(np.asarray(current, dtype=float).reshape(6)), -1.0, 1.0)
        self.changed.emit()

    @property
    def sufficient(self) -> bool:
        """Every axis reached ``required`` of full scale on both signs."""
        return bool(np.all(self.reached >= self.required))


class CoverageBars(QWidget):
    """Twelve half-bars (six axes × two signs) drawn about a centre line, with the live load.

    Parameters
    ----------
    model : CoverageModel
    """

    def __init__(self, model: CoverageModel, parent=None):
        super().__init__(parent)
        self.model = model
        model.changed.connect(self.update)
        self.setMinimumSize(360, 210)
        self.setSizePolicy(QSizePolicy.Policy.Expanding, QSizePolicy.Policy.Preferred)

    def paintEvent(self, event):  # noqa: N802 (Qt)
        p = QPainter(self)
        p.setRenderHint(QPainter.RenderHint.Antialiasing)
        w, h = self.width(), self.height()
        label_w, value_w, top = 56, 0, 22
        bar_area = QRectF(label_w, top, w - label_w - 12 - value_w, h - top - 6)
        row_h = bar_area.height() / 6
        cx = bar_area.center().x()
        half = bar_area.width() / 2
        p.fillRect(self.rect(), QColor("#252b32"))
        small = QFont(self.font())
        small.setPointSizeF(max(7.5, self.font().pointSizeF() * 0.85))
        p.setFont(small)
        p.setPen(QColor("#9aa5b1"))
        p.drawText(QRectF(bar_area.left(), 2, half, top - 4), Qt.AlignmentFlag.AlignLeft | Qt.AlignmentFlag.AlignVCenter, "− full scale")
        p.drawText(QRectF(cx, 2, half, top - 4), Qt.AlignmentFlag.AlignRight | Qt.AlignmentFlag.AlignVCenter, "+ full scale")
        p.drawText(QRectF(cx - 40, 2, 80, top - 4), Qt.AlignmentFlag.AlignCenter, "0")
        req = self.model.required
        for k in range(6):
            y = bar_area.top() + k * row_h
            bar = QRectF(bar_area.left(), y + row_h * 0.18, bar_area.width(), row_h * 0.64)
            p.fillRect(bar, QColor("#323a43"))
            for side, sgn in ((0, -1), (1, 1)):
                frac = float(self.model.reached[k, side])
                color = QColor("#2ecc71") if frac >= req else QColor("#f0a030")
                width = frac * half
                x0 = cx if sgn > 0 else cx - width
                p.fillRect(QRectF(x0, bar.top(), width, bar.height()), color)
            # required marks
            p.setPen(QPen(QColor("#e8edf2"), 1, Qt.PenStyle.DashLine))
            for sgn in (-1, 1):
                x = cx + sgn * req * half
                p.drawLine(int(x), int(bar.top()), int(x), int(bar.bottom()))
            # live load
            cur = float(self.model.current[k])
            x = cx + cur * half
            p.setPen(QPen(QColor("#ffffff"), 3))
            p.drawLine(int(x), int(bar.top() - 3), int(x), int(bar.bottom() + 3))
            p.setPen(QColor("#e8edf2"))
            p.drawText(QRectF(0, y, label_w - 6, row_h), Qt.AlignmentFlag.AlignRight | Qt.AlignmentFlag.AlignVCenter,
                       f"{AXIS_LABELS[k]} ({AXIS_UNITS[k]})")
            p.setPen(QColor("#9aa5b1"))
            fs = FULL_SCALE[k]
            txt = f"±{fs:g} {AXIS_UNITS[k]}"
            p.drawText(QRectF(cx + 6, y, half - 10, row_h), Qt.AlignmentFlag.AlignRight | Qt.AlignmentFlag.AlignVCenter, txt)
        p.setPen(QPen(QColor("#e8edf2"), 1))
        p.drawLine(int(cx), int(bar_area.top()), int(cx), int(bar_area.bottom()))
        p.end()

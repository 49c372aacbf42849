"""Coverage bars: how far each wrench axis has been loaded, per sign, against full scale."""

from __future__ import annotations

import numpy as np
from PySide6.QtCore import QObject, QRectF, Qt, Signal
from PySide6.QtGui import QColor, QFont, QPainter, QPen
from PySide6.QtWidgets import QSizePolicy, QWidget

from pito_core.defaults import FULL_SCALE_FACE
from pito_core.frames import WRENCH_COMPONENTS, WRENCH_UNITS

__all__ = ["CoverageModel", "CoverageBars", "FULL_SCALE", "AXIS_LABELS", "LEGEND_TEXT", "UNDER_COLOR", "REACHED_COLOR"]

#: Full-scale loads of one face: ±15 N, ±0.1 N·m (fx, fy, fz, tx, ty, tz).
FULL_SCALE = np.array(FULL_SCALE_FACE)  # N, N·m per axis (pito_core.defaults)
AXIS_LABELS = WRENCH_COMPONENTS
AXIS_UNITS = WRENCH_UNITS


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


#: bar colours: under the required fraction of full scale, reached it
UNDER_COLOR, REACHED_COLOR = "#f0a030", "#2ecc71"
#: what the colours and marks mean (the widget's tooltip; the legend row says it short)
LEGEND_TEXT = ("Each bar: the largest load kept so far on that axis and sign, as a fraction of the face's full scale.\n"
               "Orange: under the required fraction (dashed marks); green: reached it.\n"
               "White tick: the load on the face right now. The face is done when all twelve bars are green.")


class CoverageBars(QWidget):
    """Twelve half-bars (six axes × two signs) drawn about a centre line, with the live load.

    A legend row on top says what orange, green, the dashed marks and the white tick mean;
    the full-scale values (±15 N, ±0.1 N·m) are written in a column right of the bars, so a
    full bar never covers them.

    Parameters
    ----------
    model : CoverageModel
    """

    def __init__(self, model: CoverageModel, parent=None):
        super().__init__(parent)
        self.model = model
        model.changed.connect(self.update)
        self.setMinimumSize(400, 230)
        self.setSizePolicy(QSizePolicy.Policy.Expanding, QSizePolicy.Policy.Preferred)
        self.setToolTip(LEGEND_TEXT)

    def bar_rect(self) -> QRectF:
        """Where the bars are drawn (widget pixels): right of the axis names, left of the full-scale column."""
        label_w, value_w, top = 64, 78, 40
        return QRectF(label_w, top, self.width() - label_w - value_w, self.height() - top - 6)

    def value_rect(self, k: int) -> QRectF:
        """Where axis ``k``'s full-scale value is written: the column right of the bars."""
        bars = self.bar_rect()
        row_h = bars.height() / 6
        return QRectF(bars.right() + 6, bars.top() + k * row_h, self.width() - bars.right() - 8, row_h)

    def paintEvent(self, event):  # noqa: N802 (Qt)
        p = QPainter(self)
        p.setRenderHint(QPainter.RenderHint.Antialiasing)
        bar_area = self.bar_rect()
        label_w, top = bar_area.left(), bar_area.top()
        row_h = bar_area.height() / 6
        cx = bar_area.center().x()
        half = bar_area.width() / 2
        p.fillRect(self.rect(), QColor("#252b32"))
        small = QFont(self.font())
        small.setPointSizeF(max(7.5, self.font().pointSizeF() * 0.85))
        p.setFont(small)
        req = self.model.required
        self._paint_legend(p, req)
        p.setPen(QColor("#9aa5b1"))
        head = QRectF(bar_area.left(), 20, bar_area.width(), top - 20)
        p.drawText(head, Qt.AlignmentFlag.AlignLeft | Qt.AlignmentFlag.AlignVCenter, "− full scale")
        p.drawText(head, Qt.AlignmentFlag.AlignRight | Qt.AlignmentFlag.AlignVCenter, "+ full scale")
        p.drawText(head, Qt.AlignmentFlag.AlignCenter, "0")
        p.drawText(QRectF(bar_area.right() + 6, 20, self.width() - bar_area.right() - 8, top - 20),
                   Qt.AlignmentFlag.AlignLeft | Qt.AlignmentFlag.AlignVCenter, "full scale")
        for k in range(6):
            y = bar_area.top() + k * row_h
            bar = QRectF(bar_area.left(), y + row_h * 0.18, bar_area.width(), row_h * 0.64)
            p.fillRect(bar, QColor("#323a43"))
            for side, sgn in ((0, -1), (1, 1)):
                frac = float(self.model.reached[k, side])
                color = QColor(REACHED_COLOR) if frac >= req else QColor(UNDER_COLOR)
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
            txt = f"±{FULL_SCALE[k]:g} {AXIS_UNITS[k]}"
            p.drawText(self.value_rect(k), Qt.AlignmentFlag.AlignLeft | Qt.AlignmentFlag.AlignVCenter, txt)
        p.setPen(QPen(QColor("#e8edf2"), 1))
        p.drawLine(int(cx), int(bar_area.top()), int(cx), int(bar_area.bottom()))
        p.end()

    def _paint_legend(self, p: QPainter, required: float) -> None:
        """The legend row: orange, green, the dashed required mark and the white live tick."""
        x, y, h = 4.0, 3.0, 14.0
        fm = p.fontMetrics()
        for kind, text in (("under", f"under {required:.0%} of full scale"), ("reached", "reached"),
                           ("required", "required"), ("live", "live load")):
            if kind in ("under", "reached"):
                p.fillRect(QRectF(x, y + 2, 14, h - 4), QColor(UNDER_COLOR if kind == "under" else REACHED_COLOR))
            elif kind == "required":
                p.setPen(QPen(QColor("#e8edf2"), 1, Qt.PenStyle.DashLine))
                p.drawLine(int(x + 7), int(y), int(x + 7), int(y + h))
            else:
                p.setPen(QPen(QColor("#ffffff"), 3))
                p.drawLine(int(x + 7), int(y), int(x + 7), int(y + h))
            p.setPen(QColor("#c9d1d9"))
            p.drawText(QRectF(x + 18, y, fm.horizontalAdvance(text) + 4, h), Qt.AlignmentFlag.AlignVCenter, text)
            x += 18 + fm.horizontalAdvance(text) + 14

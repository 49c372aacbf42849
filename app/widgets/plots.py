"""Time plots over ring buffers (pyqtgraph): force norm per face, equilibrium."""

from __future__ import annotations

import numpy as np
import pyqtgraph as pg
from PySide6.QtWidgets import QVBoxLayout, QWidget

from ..scene import FACE_COLORS

__all__ = ["RingBuffer", "FaceForcePlot", "EquilibriumPlot"]

pg.setConfigOptions(antialias=False, background="#1e2329", foreground="#c9d1d9")


class RingBuffer:
    """A fixed-size ring of rows: ``append`` is O(rows), ``data()`` returns them oldest first.

    Parameters
    ----------
    capacity : int
        Rows kept.
    width : int
        Columns per row.
    """

    def __init__(self, capacity: int, width: int):
        self.capacity = int(capacity)
        self._buf = np.full((self.capacity, width), np.nan)
        self._n = 0  # rows written in all

    def append(self, rows) -> None:
        rows = np.atleast_2d(np.asarray(rows, dtype=float))
        if rows.shape[0] >= self.capacity:
            rows = rows[-self.capacity :]
        m = rows.shape[0]
        start = self._n % self.capacity
        first = min(m, self.capacity - start)
        self._buf[start : start + first] = rows[:first]
        self._buf[: m - first] = rows[first:]
        self._n += m

    def __len__(self) -> int:
        return min(self._n, self.capacity)

    def clear(self) -> None:
        self._n = 0
        self._buf[:] = np.nan

    def data(self) -> np.ndarray:
        """``(len, width)`` rows, oldest first (a copy)."""
        n = len(self)
        if self._n <= self.capacity:
            return self._buf[:n].copy()
        start = self._n % self.capacity
        return np.concatenate([self._buf[start:], self._buf[:start]])


def _style_plot(plot: pg.PlotItem, left: str, bottom: str = "time (s)") -> None:
    plot.showGrid(x=True, y=True, alpha=0.25)
    for name in ("left", "bottom"):
        plot.getAxis(name).enableAutoSIPrefix(False)
    plot.setLabel("left", left)
    plot.setLabel("bottom", bottom)
    plot.setMouseEnabled(x=False, y=False)
    plot.hideButtons()


class FaceForcePlot(pg.PlotWidget):
    """‖F‖ (N) on each face over the last ``window`` seconds, one curve per face colour."""

    def __init__(self, window: float = 10.0, rate: float = 60.0, parent=None):
        super().__init__(parent)
        self.window = float(window)
        self.buffer = RingBuffer(int(window * rate * 1.5), 7)  # t, |F1|..|F6|
        _style_plot(self.getPlotItem(), "force norm ‖F‖ (N)")
        self.addLegend(offset=(6, 4), colCount=6, labelTextSize="8pt")
        self.curves = [
            self.plot([], [], pen=pg.mkPen(FACE_COLORS[i], width=1), name=f"face {i}") for i in range(1, 7)
        ]
        self.setYRange(0, 15)

    def append(self, t: float, norms) -> None:
        self.buffer.append(np.concatenate([[t], np.asarray(norms, dtype=float)]))

    def refresh(self) -> None:
        d = self.buffer.data()
        if d.shape[0] == 0:
            return
        t = d[:, 0] - d[-1, 0]
        for k, c in enumerate(self.curves):
            c.setData(t, np.nan_to_num(d[:, k + 1]), connect="finite")
        self.setXRange(-self.window, 0, padding=0)
        top = np.nanmax(d[:, 1:]) if np.isfinite(d[:, 1:]).any() else 1.0
        self.setYRange(0, max(2.0, 1.15 * top), padding=0)

    def clear_data(self) -> None:
        self.buffer.clear()


class EquilibriumPlot(QWidget):
    """‖ΣF‖ (N) against the object's weight m·g, and ‖ΣT‖ (N·m), over time.

    For an object held still, the face loads balance its weight: ‖ΣF‖ ≈ m·g and
    ‖ΣT‖ ≈ 0 about its centre of mass.
    """

    def __init__(self, weight: float = 0.0, window: float = 10.0, rate: float = 60.0, parent=None):
        super().__init__(parent)
        self.window = float(window)
        self.buffer = RingBuffer(int(window * rate * 1.5), 3)  # t, |ΣF|, |ΣT|
        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        layout.setSpacing(2)
        self.force_plot = pg.PlotWidget()
        self.torque_plot = pg.PlotWidget()
        _style_plot(self.force_plot.getPlotItem(), "‖ΣF‖ (N)", bottom="")
        _style_plot(self.torque_plot.getPlotItem(), "‖ΣT‖ (mN·m)")
        self.torque_plot.addLegend(offset=(6, 4), labelTextSize="8pt")
        self.force_plot.addLegend(offset=(6, 4), labelTextSize="8pt")
        self.force_curve = self.force_plot.plot([], [], pen=pg.mkPen("#e8edf2", width=1), name="‖ΣF‖ of the six faces")
        self.weight_line = pg.InfiniteLine(angle=0, pen=pg.mkPen("#f0a030", width=1, style=pg.QtCore.Qt.PenStyle.DashLine),
                                           label="weight m·g = {value:.2f} N", labelOpts={"color": "#f0a030", "position": 0.15})
        self.force_plot.addItem(self.weight_line)
        self.torque_curve = self.torque_plot.plot([], [], pen=pg.mkPen("#56B4E9", width=1),
                                                  name="‖ΣT‖ about the centre of gravity (0 when still)")
        self.set_weight(weight)
        layout.addWidget(self.force_plot)
        layout.addWidget(self.torque_plot)

    def set_weight(self, weight: float) -> None:
        """The object's weight m·g, N."""
        self.weight = float(weight)
        self.weight_line.setValue(self.weight)

    def append(self, t: float, sum_force: float, sum_torque: float) -> None:
        self.buffer.append([t, sum_force, sum_torque])

    def refresh(self) -> None:
        d = self.buffer.data()
        if d.shape[0] == 0:
            return
        t = d[:, 0] - d[-1, 0]
        self.force_curve.setData(t, np.nan_to_num(d[:, 1]))
        self.torque_curve.setData(t, np.nan_to_num(d[:, 2]) * 1000)
        for p in (self.force_plot, self.torque_plot):
            p.setXRange(-self.window, 0, padding=0)
        fmax = max(self.weight * 1.5, np.nanmax(d[:, 1]) * 1.15 if np.isfinite(d[:, 1]).any() else 1.0, 1.0)
        self.force_plot.setYRange(0, fmax, padding=0)
        tmax = 1000 * max(0.02, np.nanmax(d[:, 2]) * 1.15 if np.isfinite(d[:, 2]).any() else 0.02)
        self.torque_plot.setYRange(0, tmax, padding=0)

    def clear_data(self) -> None:
        self.buffer.clear()

"""Time plots over ring buffers (pyqtgraph): force norm per face, equilibrium.

Data and drawing are decoupled: ``append`` writes new samples into a ring buffer (O(new
samples), called once per live bundle); ``refresh`` (one routine for both plots) — called by
the live view's display pacer, at most at the display rate — hands each curve the last
``window`` seconds as a view of the ring (no copy), decimated to the plot's pixel width by
min–max per pixel column, so a 1 kHz stream costs the same to draw as a 60 Hz one and no peak
is lost. The axes move only when the range must change (hysteresis), so a refresh repaints
curves, not tick labels.

A ring holds one timeline: samples whose time goes back (a replay that loops or seeks, another
source) start a new one (:meth:`TimeRing.append`), and a stretch without samples longer than
``GAP`` is drawn as a break in the curves, never as a straight line across it.
"""

from __future__ import annotations

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import Qt
from PySide6.QtWidgets import QVBoxLayout, QWidget

from pito_core.devices import Ring

from ..palette import FACE_COLORS

__all__ = ["TimeRing", "FaceForcePlot", "EquilibriumPlot", "minmax_decimate", "break_gaps", "GAP", "legend_html"]

#: s: a stretch without samples longer than this is a break in the curves (not a line across it)
GAP = 0.5

#: the plots' background and foreground (axes, tick labels, axis titles): set on each plot, never
#: through ``pg.setConfigOptions`` (a global setting; importing the app changes none)
BACKGROUND = "#1e2329"
FOREGROUND = "#c9d1d9"


def _plot_widget(parent=None) -> pg.PlotWidget:
    w = pg.PlotWidget(parent, background=BACKGROUND)
    w.setAntialiasing(False)
    _opaque(w)
    return w


def _opaque(view: pg.GraphicsView) -> None:
    """Tell Qt that ``view`` paints every pixel of its viewport (its background brush covers it).

    Otherwise, under the app's style sheet (``QWidget { background: … }``), every repaint of
    a curve first paints the styled background beneath it: ~5 of the ~6 ms of CPU a frame of
    the live view's plots took (docs/performance.md); the pixels are the same.
    """
    view.viewport().setAttribute(Qt.WidgetAttribute.WA_OpaquePaintEvent, True)


class TimeRing:
    """The last ``capacity`` rows ``[t, y1, …]`` (column 0: time, s), kept in time order, on a :class:`Ring`.

    Rows older than the newest kept one start a new timeline: the ring is cleared first (a
    replay looped or seeked, or the source changed), so its times always increase. The rows
    live in one contiguous :class:`~pito_core.devices.Ring` (field ``rows``), so
    :meth:`view` hands them out without copying.

    Parameters
    ----------
    capacity : int
        Rows kept (>= 1).
    width : int
        Columns per row (the time and ``width - 1`` values).

    Attributes
    ----------
    written : int
        Rows appended plus clears since the ring was made: changes with every append and
        every clear (a refresh draws only when it changed).
    """

    def __init__(self, capacity: int, width: int):
        self.ring = Ring(int(capacity), {"rows": (np.float64, (int(width),))}, contiguous=True)
        self.written = 0

    def __len__(self) -> int:
        return len(self.ring)

    @property
    def capacity(self) -> int:
        return self.ring.capacity

    def append(self, rows) -> None:
        """Append rows ``(n, width)`` (or one row ``(width,)``), times in column 0, s."""
        rows = np.atleast_2d(np.asarray(rows, dtype=float))
        if rows.shape[0] == 0:
            return
        back = np.flatnonzero(np.diff(rows[:, 0]) < 0)
        if back.size:  # back in time within the rows: the last run is the new timeline
            rows = rows[int(back[-1]) + 1:]
            self.clear()
        elif len(self.ring) and rows[0, 0] < self.ring.last(1, copy=False)["rows"][0, 0]:
            self.clear()
        self.ring.append(rows=rows)
        self.written += rows.shape[0]

    def clear(self) -> None:
        self.ring.clear()
        self.written += 1

    def view(self) -> np.ndarray:
        """``(len, width)`` rows, oldest first: a view into the ring (valid until the next append)."""
        return self.ring.last(copy=False)["rows"]


def break_gaps(t, y, gap: float = GAP):
    """``(t, y)`` with a NaN row after every sample followed by none for more than ``gap`` s.

    A curve drawn with ``connect="finite"`` then stops at the gap instead of joining its two
    sides with a straight line. ``t`` (n,) sorted, ``y`` (n, k).
    """
    t = np.asarray(t, dtype=float)
    idx = np.flatnonzero(np.diff(t) > gap)
    if idx.size == 0:
        return t, y
    return np.insert(t, idx + 1, t[idx]), np.insert(np.asarray(y, dtype=float), idx + 1, np.nan, axis=0)


def minmax_decimate(t, y, t0: float, t1: float, n_bins: int):
    """Min–max decimation of ``y (n, k)`` over sorted times ``t (n,)`` to ``n_bins`` columns of ``[t0, t1]``.

    Returns ``(t (m,), y (m, k))`` with, per non-empty column, its first time and the column's
    minimum, then its last time and its maximum (``m ≤ 2 n_bins``); NaN samples are ignored
    (a column of NaN only stays NaN). Inputs with no more than ``2 n_bins`` samples are
    returned as they are.
    """
    t = np.asarray(t, dtype=float)
    y = np.asarray(y, dtype=float)
    if t.size <= 2 * n_bins:
        return t, y
    col = np.clip(np.floor((t - t0) / max(t1 - t0, 1e-12) * n_bins), 0, n_bins - 1).astype(np.int64)
    starts = np.flatnonzero(np.r_[True, col[1:] != col[:-1]])
    ends = np.r_[starts[1:], t.size] - 1
    # without NaN, minimum/maximum give what fmin/fmax give, in ~40 % of their time (a sum is
    # NaN if any value is, or on inf - inf: then the NaN-aware pair, as always)
    with np.errstate(invalid="ignore", over="ignore"):
        lo_of, hi_of = (np.fmin, np.fmax) if not np.isfinite(y.sum()) else (np.minimum, np.maximum)
        lo = lo_of.reduceat(y, starts, axis=0)
        hi = hi_of.reduceat(y, starts, axis=0)
    m = starts.size
    t_out = np.empty(2 * m)
    t_out[0::2], t_out[1::2] = t[starts], t[ends]
    y_out = np.empty((2 * m, y.shape[1]))
    y_out[0::2], y_out[1::2] = lo, hi
    return t_out, y_out


def _style_plot(plot: pg.PlotItem, left: str, bottom: str = "time (s)") -> None:
    for name in ("left", "bottom", "top", "right"):
        plot.getAxis(name).setPen(FOREGROUND)
        plot.getAxis(name).setTextPen(FOREGROUND)
    # no grid: pyqtgraph draws it as part of each axis, so every curve update repainted the
    # axes and their grid (~2.4 ms a paint, 7 paints a frame); tick labels remain
    plot.showGrid(x=False, y=False)
    for name in ("left", "bottom"):
        axis = plot.getAxis(name)
        axis.enableAutoSIPrefix(False)
        # the ticks point into the plot area, so every curve update repainted both axes (their
        # tick labels replayed, ~0.2 ms an axis); cached as pixels, an axis is redrawn only when
        # it changes (a new range, a resize) and is otherwise copied
        axis.setCacheMode(pg.QtWidgets.QGraphicsItem.CacheMode.DeviceCoordinateCache)
    plot.setLabel("left", left)
    plot.setLabel("bottom", bottom)
    plot.setMouseEnabled(x=False, y=False)
    plot.hideButtons()
    plot.getViewBox().disableAutoRange()


class _Curve(pg.PlotCurveItem):
    """A ``PlotCurveItem`` told its data bounds with its data (:meth:`set_curve`).

    pyqtgraph finds a curve's bounds with ``nanmin``/``nanmax`` over its data each time the
    data change, per curve and axis; here the decimation has them for all curves in one pass.
    """

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._bounds = None  # ((x0, x1), (y0, y1)) of the current data, or None: pyqtgraph's own

    def set_curve(self, x, y, y_lo: float, y_hi: float) -> None:
        """New data ``x`` (sorted), ``y`` whose finite values lie in ``[y_lo, y_hi]`` (NaN: none)."""
        xb = (float(x[0]), float(x[-1])) if x.size else (None, None)
        yb = (float(y_lo), float(y_hi)) if x.size and np.isfinite(y_lo) and np.isfinite(y_hi) else (None, None)
        self._bounds = (xb, yb)
        self.setData(x, y, connect="finite")

    def dataBounds(self, ax, frac=1.0, orthoRange=None):  # noqa: N802 - pyqtgraph's name
        if self._bounds is None or frac < 1.0 or orthoRange is not None or ax not in (0, 1):
            return super().dataBounds(ax, frac, orthoRange)
        return self._bounds[ax]


def _curve(plot: pg.PlotItem, color: str, name: str) -> _Curve:
    """A bare curve in ``plot``: the data are decimated here already, so ``PlotDataItem``'s own
    dataset, bounds and downsampling pass would only repeat work on every refresh."""
    c = _Curve(pen=pg.mkPen(color, width=1), name=name, antialias=False)
    plot.addItem(c)
    return c


def legend_html(entries) -> str:
    """A one-line legend (``(colour, text, dashed)`` entries) as HTML for a plot's title row.

    The legend sits above the plot area, not in it: curves never run over it.
    """
    parts = [f'<span style="color:{color}">{"┄┄" if dashed else "━━"}</span>&nbsp;{text}'
             for color, text, dashed in entries]
    return "&nbsp;&nbsp;&nbsp;".join(parts)


def _set_legend(plot: pg.PlotItem, entries) -> None:
    plot.setTitle(legend_html(entries), size="9pt", color=FOREGROUND)


def _column_bounds(y):
    """Per column of ``y (m, k)``: the smallest and largest finite value (NaN for a column without)."""
    with np.errstate(invalid="ignore"):
        return np.fmin.reduce(y, axis=0), np.fmax.reduce(y, axis=0)


class _YRange:
    """A y range ``[0, top]`` that grows at once and shrinks only when the data fall well under it."""

    def __init__(self, floor: float):
        self.floor = float(floor)
        self.top = float(floor)

    def fit(self, peak: float) -> bool:
        """New range for data peaking at ``peak``; True if it changed."""
        if not np.isfinite(peak):
            return False
        want = max(self.floor, 1.15 * peak)
        if want > self.top or want < 0.5 * self.top:
            self.top = want
            return True
        return False


class _TimelinePlot:
    """The refresh both plots share: the last ``window`` seconds of ``buffer`` handed to the curves.

    A subclass sets ``window`` (s) and ``buffer`` (a :class:`TimeRing` of rows ``[t, y1, …,
    yk]``) and draws in :meth:`_draw`. ``last_time`` is the time (s, host clock) of the newest
    sample drawn by the last refresh, ``refreshes`` counts the refreshes that drew. Times are
    drawn relative to the newest sample (0 at the right edge); the rows are decimated to the
    plot's pixel width (:func:`minmax_decimate`) and gaps longer than :data:`GAP` are breaks.
    """

    last_time = float("nan")
    refreshes = 0
    _drawn_n = -1  # the ring's ``written`` when last drawn

    def _curves(self) -> list:
        """Every curve of the plot (cleared when the ring is empty)."""
        raise NotImplementedError

    def _pixel_width(self) -> int:
        """Width of the plot area, px: the decimation's number of columns."""
        raise NotImplementedError

    def _draw(self, t, y, lo, hi) -> None:
        """Hand the curves times ``t (m,)`` s (≤ 0), values ``y (m, k)`` and per-column bounds ``lo``, ``hi`` (k,)."""
        raise NotImplementedError

    def refresh(self) -> bool:
        """Redraw the curves from the ring (decimated to the pixel width); False if nothing new."""
        if self.buffer.written == self._drawn_n:
            return False
        self._drawn_n = self.buffer.written
        d = self.buffer.view()
        if d.shape[0] == 0:
            for c in self._curves():
                c.set_curve(np.zeros(0), np.zeros(0), np.nan, np.nan)
            return False
        t_end = d[-1, 0]
        d = d[int(np.searchsorted(d[:, 0], t_end - self.window)):]
        px = max(50, self._pixel_width())
        t, y = minmax_decimate(d[:, 0], d[:, 1:], t_end - self.window, t_end, px)
        t, y = break_gaps(t, y)
        lo, hi = _column_bounds(y)
        self._draw(t - t_end, y, lo, hi)
        self.last_time = float(t_end)
        self.refreshes += 1
        return True

    def clear_data(self) -> None:
        self.buffer.clear()
        self.refresh()  # the curves show the empty ring (not the old timeline)


class FaceForcePlot(_TimelinePlot, pg.PlotWidget):
    """‖F‖ (N) on each face over the last ``window`` seconds, one curve per face colour."""

    def __init__(self, window: float = 10.0, rate: float = 1000.0, parent=None):
        super().__init__(parent, background=BACKGROUND)
        self.setAntialiasing(False)
        _opaque(self)
        self.window = float(window)
        self.buffer = TimeRing(int(window * rate * 1.25), 7)  # t, |F1|..|F6|
        _style_plot(self.getPlotItem(), "force norm ‖F‖ (N)")
        self.curves = [
            _curve(self.getPlotItem(), FACE_COLORS[i], f"face {i}") for i in range(1, 7)
        ]
        _set_legend(self.getPlotItem(), [(FACE_COLORS[i], f"face {i}", False) for i in range(1, 7)])
        self._y = _YRange(2.0)
        self.setXRange(-self.window, 0, padding=0)
        self.setYRange(0, self._y.top, padding=0)

    def append(self, t, norms) -> None:
        """New samples: times ``t`` (n,) s and force norms ``(n, 6)`` N (or one time and a (6,) row)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        norms = np.asarray(norms, dtype=float).reshape(t.size, 6)
        self.buffer.append(np.column_stack([t, norms]))

    def _curves(self) -> list:
        return self.curves

    def _pixel_width(self) -> int:
        return int(self.getPlotItem().getViewBox().width())

    def _draw(self, t, y, lo, hi) -> None:
        for k, c in enumerate(self.curves):
            c.set_curve(t, y[:, k], lo[k], hi[k])
        peak = np.fmax.reduce(hi)  # NaN only if no finite value
        if self._y.fit(float(peak)):
            self.setYRange(0, self._y.top, padding=0)


class EquilibriumPlot(_TimelinePlot, QWidget):
    """‖ΣF‖ (N) against the object's weight m·g, and ‖ΣT‖ (N·m), over time.

    For an object held still, the face loads balance its weight: ‖ΣF‖ ≈ m·g and
    ‖ΣT‖ ≈ 0 about its centre of mass — up to the calibration's error, which leaves a residual
    of a few mN·m at rest; the legend says so.
    """

    def __init__(self, weight: float = 0.0, window: float = 10.0, rate: float = 120.0, parent=None):
        super().__init__(parent)
        self.window = float(window)
        self.buffer = TimeRing(int(window * rate * 1.25), 3)  # t, |ΣF|, |ΣT| (every sample, as the face plot)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        layout.setSpacing(2)
        self.force_plot = _plot_widget()
        self.torque_plot = _plot_widget()
        _style_plot(self.force_plot.getPlotItem(), "‖ΣF‖ (N)", bottom="")
        _style_plot(self.torque_plot.getPlotItem(), "‖ΣT‖ (mN·m)")
        self.force_curve = _curve(self.force_plot.getPlotItem(), "#e8edf2", "‖ΣF‖ of the six faces")
        self.weight_line = pg.InfiniteLine(angle=0, pen=pg.mkPen("#f0a030", width=1, style=pg.QtCore.Qt.PenStyle.DashLine),
                                           label="m·g = {value:.2f} N", labelOpts={"color": "#f0a030", "position": 0.92})
        self.force_plot.addItem(self.weight_line)
        self.torque_curve = _curve(self.torque_plot.getPlotItem(), "#56B4E9", "‖ΣT‖ about the centre of gravity")
        _set_legend(self.force_plot.getPlotItem(), [("#e8edf2", "‖ΣF‖ of the six faces", False),
                                                    ("#f0a030", "the object's weight m·g (at rest)", True)])
        _set_legend(self.torque_plot.getPlotItem(), [
            ("#56B4E9", "‖ΣT‖ about the centre of gravity: 0 at rest, up to the calibration's error", False)])
        self._fy = _YRange(1.0)
        self._ty = _YRange(20.0)  # mN·m
        for p in (self.force_plot, self.torque_plot):
            p.setXRange(-self.window, 0, padding=0)
        self.force_plot.setYRange(0, self._fy.top, padding=0)
        self.torque_plot.setYRange(0, self._ty.top, padding=0)
        self.set_weight(weight)
        layout.addWidget(self.force_plot)
        layout.addWidget(self.torque_plot)

    def set_weight(self, weight: float) -> None:
        """The object's weight m·g, N."""
        self.weight = float(weight)
        self.weight_line.setValue(self.weight)
        self._fy.floor = max(1.0, 1.5 * self.weight)
        self._fy.top = max(self._fy.top, self._fy.floor)
        self.force_plot.setYRange(0, self._fy.top, padding=0)

    def append(self, t, sum_force, sum_torque) -> None:
        """New samples: times ``t`` s, ‖ΣF‖ N and ‖ΣT‖ N·m, each ``(n,)`` (or one of each)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        self.buffer.append(np.column_stack([t, np.broadcast_to(sum_force, t.shape), np.broadcast_to(sum_torque, t.shape)]))

    def _curves(self) -> list:
        return [self.force_curve, self.torque_curve]

    def _pixel_width(self) -> int:
        return int(self.force_plot.getPlotItem().getViewBox().width())

    def _draw(self, t, y, lo, hi) -> None:
        self.force_curve.set_curve(t, y[:, 0], lo[0], hi[0])
        self.torque_curve.set_curve(t, y[:, 1] * 1000, lo[1] * 1000, hi[1] * 1000)
        if self._fy.fit(float(hi[0])):
            self.force_plot.setYRange(0, self._fy.top, padding=0)
        if self._ty.fit(1000 * float(hi[1])):
            self.torque_plot.setYRange(0, self._ty.top, padding=0)

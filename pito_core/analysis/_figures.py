"""Figures of an analysis (matplotlib, Agg canvas; no pyplot state, safe in worker threads).

:func:`overview_figure`: one figure per recording (``overview.png``, drawn by default): the
grip and load force over the whole recording with every trial's phases shaded and the
phases that are not single contacts hatched red, and every trial's grip and load force
overlaid, aligned on its lift-off. It costs one figure (~0.1 s) whatever the number of
trials; curves are decimated to the pixels they fill (min and max of each pixel column).

Per-trial figures (``trial_NN.png``, on request: ``pito analyze --figures trials``):

One figure is built per recording and redrawn for each trial (:class:`_TrialCanvas`): the
axes, ticks and legends are made once, each trial only moves the lines' data, the phase
spans and the limits, so a figure costs its drawing only.
"""

from __future__ import annotations

import threading
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from ..frames import FACE_COLORS
from ._grasp import norm3
from ._series import FIGURE_PAD_S, FIGURE_POINTS

__all__ = ["trial_figure", "save_trial_figures", "overview_figure", "save_overview_figure"]

_MAX_POINTS = FIGURE_POINTS
_PHASE_COLOURS = {"load": "#dbe9f6", "lift": "#fde3c8", "hold": "#e2f0d9", "replace": "#fde3c8", "release": "#ececec"}
_PAD_S = FIGURE_PAD_S
_FORCES = (("grip force (Σ finger normal)", "-"), ("load force (Σ finger tangential)", "-"),
           ("internal force Σ‖(I−G⁺G)f‖", "--"), ("manipulation force Σ‖G⁺Gf‖", ":"))
_N_SPANS = 5  # at most one span per phase name


class _TrialCanvas:
    """One figure of three panels (forces, normal force per patch, contact displacement) for a recording's trials."""

    def __init__(self, analysis):
        self.analysis = analysis
        self.base = analysis.settings.base_face
        self.fingers = np.array([i + 1 != self.base for i in range(6)])
        fig = Figure(figsize=(8, 7.5))  # fixed margins: a layout engine would cost a third of the drawing
        fig.subplots_adjust(left=0.08, right=0.98, bottom=0.065, top=0.91, hspace=0.1)
        FigureCanvasAgg(fig)
        self.fig = fig
        self.axes = axes = fig.subplots(3, 1, sharex=True)
        self.force_lines = [axes[0].plot([], [], ls, label=label)[0] for label, ls in _FORCES]
        self.normal_lines = [axes[1].plot([], [], color=FACE_COLORS[i + 1],
                                          label=f"face {i + 1}" + (" (base)" if i + 1 == self.base else ""))[0]
                             for i in range(6)]
        self.path_lines = [axes[2].plot([], [], color=FACE_COLORS[i + 1], label=f"face {i + 1}")[0] for i in range(6)]
        axes[0].set_ylabel("force (N)")
        axes[1].set_ylabel("normal force (N)")
        axes[2].set_ylabel("contact displacement (mm)")
        axes[2].set_xlabel("time (s)")
        self.spans, self.hatches = [], []
        for ax in axes:
            self.spans.append([ax.axvspan(0, 1, lw=0, zorder=0, visible=False) for _ in range(_N_SPANS)])
            self.hatches.append([ax.axvspan(0, 1, facecolor="none", edgecolor="#c0392b", hatch="///", lw=0, zorder=1,
                                            visible=False) for _ in range(_N_SPANS)])
            ax.grid(alpha=0.3)
        self.labels = [axes[0].text(0, 1.0, "", transform=axes[0].get_xaxis_transform(), ha="center", va="bottom",
                                    fontsize=8) for _ in range(_N_SPANS)]
        self.title = fig.suptitle("", fontsize=10)
        axes[0].legend(fontsize=7, loc="upper right")
        self._legends = {}

    def _legend(self, ax, lines, shown) -> None:
        key = (id(ax), tuple(shown))
        if key not in self._legends:
            ax.legend(handles=[lines[i] for i in shown], fontsize=7, loc="upper right")
            self._legends[key] = ax.legend_
        ax.legend_ = self._legends[key]

    def draw(self, trial) -> Figure:
        """The figure of ``trial``; phases whose contacts are not single contacts hatched red and named in the title."""
        a, g = self.analysis, self.analysis.series
        lo, hi = np.searchsorted(g.time, (trial.start - _PAD_S, trial.stop + _PAD_S), side="left")
        hi = int(hi) + int(hi < g.time.size and g.time[hi] <= trial.stop + _PAD_S)
        m = np.arange(lo, hi)
        if not g.decimated:
            m = m[:: max(1, m.size // _MAX_POINTS)]  # a screen's worth of points per curve
        t = g.time[m]
        on = g.on[m]
        f_n = g.f_n[m]
        ys = ((f_n * self.fingers).sum(axis=1), (g.f_t[m] * self.fingers).sum(axis=1),
              norm3(g.f_int[m]).sum(axis=1), norm3(g.f_manip[m]).sum(axis=1))
        for line, y in zip(self.force_lines, ys):
            line.set_data(t, y)
        shown = [i for i in range(6) if on[:, i].any()]
        for i, line in enumerate(self.normal_lines):
            line.set_data((t, np.where(on[:, i], f_n[:, i], np.nan)) if i in shown else ([], []))
            line.set_visible(i in shown)
        for i, line in enumerate(self.path_lines):
            p = g.path[m, i]
            ok = np.isfinite(p).all(axis=1)
            if ok.any():
                line.set_data(t, 1e3 * norm3(p - p[ok][0]))
            else:
                line.set_data([], [])
            line.set_visible(bool(ok.any()))
        self._legend(self.axes[1], self.normal_lines, shown)
        bad = _implausible(a, trial)
        phases = list(trial.phases.items())[:_N_SPANS]
        for k in range(_N_SPANS):
            for j in range(3):
                span, hatch = self.spans[j][k], self.hatches[j][k]
                if k < len(phases):
                    name, (x0, x1) = phases[k]
                    _move_span(span, x0, x1)
                    span.set_color(_PHASE_COLOURS.get(name, "#eeeeee"))
                    span.set_visible(True)
                    _move_span(hatch, x0, x1)
                    hatch.set_visible(name in bad)
                else:
                    span.set_visible(False)
                    hatch.set_visible(False)
            label = self.labels[k]
            if k < len(phases):
                name, (x0, x1) = phases[k]
                label.set_text(name)
                label.set_x((x0 + x1) / 2)
            label.set_visible(k < len(phases))
        for ax in self.axes:
            ax.relim(visible_only=True)
            ax.autoscale_view()
        if t.size:
            self.axes[0].set_xlim(*_padded(t[0], t[-1]))
        sim = "SIMULATED — " if a.simulated else ""
        title = f"{sim}trial {trial.index}: {trial.start:.2f}–{trial.stop:.2f} s"
        if bad:
            title += f"\nnot single contacts (hatched): {', '.join(bad)}"
        self.title.set_text(title)
        self.title.set_color("#c0392b" if bad else "black")
        return self.fig


def _move_span(span, x0, x1) -> None:
    """Move an ``axvspan`` rectangle (data x, axes y) to ``[x0, x1]``."""
    if hasattr(span, "set_x") and hasattr(span, "set_width"):  # matplotlib ≥ 3.9: a Rectangle
        span.set_x(x0)
        span.set_width(x1 - x0)
    else:  # a Polygon
        span.set_xy([[x0, 0], [x0, 1], [x1, 1], [x1, 0], [x0, 0]])


def _padded(t0, t1):
    """The x limits autoscaling would give the curves (5 % margins)."""
    d = (t1 - t0) * 0.05 or 0.5
    return t0 - d, t1 + d


def trial_figure(analysis, trial) -> Figure:
    """Forces, normal force per patch and contact displacement of one trial, phases shaded.

    A phase whose contacts are not single contacts is hatched red and named in the title.
    (Many trials: :func:`save_trial_figures` redraws one figure instead of building one each.)
    """
    return _TrialCanvas(analysis).draw(trial)


def _implausible(analysis, trial) -> list[str]:
    ph = analysis.phases
    rows = ph[(ph["trial"] == trial.index) & ph["plausible"].eq(False).fillna(False)]
    return [str(p) for p in rows["phase"]]


def save_trial_figures(analysis, directory, dpi: int = 90) -> list:
    """Write ``trial_NN.png`` for every trial into ``directory``; the paths written."""
    out = []
    canvas = _TrialCanvas(analysis) if analysis.trials else None
    for tr in analysis.trials:
        path = Path(directory) / f"trial_{tr.index:02d}.png"
        canvas.draw(tr).savefig(path, dpi=dpi, pil_kwargs={"compress_level": 1})  # fast zlib
        out.append(path)
    return out


def _envelope(t, y, columns: int):
    """``(t, y)`` reduced to the min and max of ``y`` in each of ``columns`` index buckets (what a line of that
    many pixels shows), in time order; unchanged when it has fewer than ``2 * columns`` points."""
    n = t.size
    if n <= 2 * columns:
        return t, y
    edges = np.linspace(0, n, columns + 1).astype(np.intp)
    yy = np.where(np.isfinite(y), y, np.nan)
    lo = np.fmin.reduceat(yy, edges[:-1])
    hi = np.fmax.reduceat(yy, edges[:-1])
    tt = np.repeat(t[edges[:-1]], 2)
    tt[1::2] = t[edges[1:] - 1]
    yy = np.empty(2 * columns)
    yy[0::2], yy[1::2] = lo, hi
    return tt, yy


def _implausible_phases(analysis) -> dict:
    """``{trial: [phase, ...]}`` of the phases whose contacts are not single contacts."""
    ph = analysis.phases
    rows = ph[ph["plausible"].eq(False).fillna(False)]
    out = {}
    for tr, name in zip(rows["trial"], rows["phase"]):
        out.setdefault(int(tr), []).append(str(name))
    return out


class _OverviewCanvas:
    """The overview figure (:func:`overview_figure`), built once and redrawn for each recording (a thread's own)."""

    def __init__(self):
        from matplotlib.collections import LineCollection

        fig = Figure(figsize=(8, 6))
        fig.subplots_adjust(left=0.08, right=0.98, bottom=0.08, top=0.83, hspace=0.3)
        FigureCanvasAgg(fig)
        self.fig = fig
        self.ax0, self.ax1 = ax0, ax1 = fig.subplots(2, 1)
        self.grip = ax0.plot([], [], lw=0.8, color="#1f77b4", label="grip force (Σ finger normal)")[0]
        self.load = ax0.plot([], [], lw=0.8, color="#ff7f0e", label="load force (Σ finger tangential)")[0]
        ax0.set_xlabel("time (s)", labelpad=1)
        ax0.set_ylabel("force (N)")
        self.overlay = LineCollection([], linewidths=0.6, alpha=0.6)
        ax1.add_collection(self.overlay)
        ax1.set_ylabel("force (N)")
        ax1.grid(alpha=0.3)
        ax1.set_xlabel("time from lift-off (s; from the first contact without one)")
        ax1.set_title("every trial overlaid: grip (blue), load (orange); red: a trial with a phase not single contacts",
                      fontsize=8, pad=2)
        self.title = fig.suptitle("", fontsize=10, y=0.995, va="top")
        self.spans = []
        self._legends = {}

    def draw(self, analysis, columns: int = 700) -> Figure:
        a, g = analysis, analysis.series
        ax0, ax1 = self.ax0, self.ax1
        base = a.settings.base_face
        fingers = np.array([i + 1 != base for i in range(6)])
        t = np.asarray(g.time, float)
        grip = (np.asarray(g.f_n, float) * fingers).sum(axis=1)
        load = (np.asarray(g.f_t, float) * fingers).sum(axis=1)
        bad = _implausible_phases(a)
        self.grip.set_data(*_envelope(t, grip, columns))
        self.load.set_data(*_envelope(t, load, columns))
        for c in self.spans:
            c.remove()
        self.spans = []
        spans, hatched = {}, []
        for tr in a.trials:
            for name, (x0, x1) in tr.phases.items():
                spans.setdefault(name, []).append((x0, x1 - x0))
                if name in bad.get(tr.index, ()):
                    hatched.append((x0, x1 - x0))
        for name in sorted(spans, key=lambda n: list(_PHASE_COLOURS).index(n) if n in _PHASE_COLOURS else 9):
            self.spans.append(ax0.broken_barh(spans[name], (0, 1), transform=ax0.get_xaxis_transform(),
                                              facecolor=_PHASE_COLOURS.get(name, "#eee"), lw=0, zorder=0, label=name))
        if hatched:
            self.spans.append(ax0.broken_barh(hatched, (0, 1), transform=ax0.get_xaxis_transform(), facecolor="none",
                                              edgecolor="#c0392b", hatch="///", lw=0, zorder=1,
                                              label="not single contacts"))
        handles = [self.grip, self.load, *self.spans]
        key = tuple(h.get_label() for h in handles)
        if key not in self._legends:
            ax0.legend(handles=handles, fontsize=7, loc="lower center", bbox_to_anchor=(0.5, 1.0), ncol=4,
                       frameon=False)
            self._legends[key] = ax0.legend_
        ax0.legend_ = self._legends[key]
        ax0.relim(visible_only=True)
        ax0.autoscale_view()
        segs, colours = [], []
        per = max(150, 4 * columns // max(1, len(a.trials)))  # points per trial curve (a 6 s trial: 40 ms apart)
        for tr in a.trials:
            zero = tr.lift_off if np.isfinite(tr.lift_off) else tr.start
            i0, i1 = np.searchsorted(t, (tr.start - _PAD_S, tr.stop + _PAD_S))
            if i1 - i0 < 2:
                continue
            m = np.arange(i0, i1)[:: max(1, (i1 - i0) // per)]
            red = tr.index in bad
            for y, c in ((grip, "#1f77b4"), (load, "#ff7f0e")):
                segs.append(np.column_stack([t[m] - zero, y[m]]))
                colours.append("#c0392b" if red else c)
        self.overlay.set_segments(segs)
        self.overlay.set_color(colours or "#1f77b4")
        if segs:  # the limits autoscaling gives (5 % margins), of every curve's finite points
            xy = np.concatenate(segs)
            xy = xy[np.isfinite(xy).all(axis=1)]
            if xy.size:
                ax1.set_xlim(*_padded(xy[:, 0].min(), xy[:, 0].max()))
                ax1.set_ylim(*_padded(xy[:, 1].min(), xy[:, 1].max()))
        sim = "SIMULATED — " if a.simulated else ""
        title = f"{sim}{len(a.trials)} trial{'s' * (len(a.trials) != 1)}, {t[-1] - t[0] if t.size else 0:.0f} s"
        src = a.meta.get("source")
        if src:
            title = f"{Path(str(src)).name}: {title}"
        if bad:
            names = [f"{k} ({', '.join(v)})" for k, v in list(bad.items())[:6]]
            more = f" and {len(bad) - 6} more" if len(bad) > 6 else ""
            title += f"\nnot single contacts (hatched) in trial {', '.join(names)}{more}"
        self.title.set_text(title)
        self.title.set_color("#c0392b" if bad else "black")
        return self.fig


def overview_figure(analysis, columns: int = 700) -> Figure:
    """One figure of a whole recording: its trials on one time axis and overlaid (module docstring).

    ``columns``: points per curve (about the pixel width of a panel); longer curves are reduced to
    each column's min and max, so no peak is lost. (:func:`save_overview_figure` redraws one
    figure per thread instead of building one each time.)
    """
    return _OverviewCanvas().draw(analysis, columns)


_local = threading.local()


def save_overview_figure(analysis, directory, dpi: int = 90) -> Path:
    """Write ``overview.png`` (:func:`overview_figure`) into ``directory``; its path."""
    path = Path(directory) / "overview.png"
    if getattr(_local, "overview", None) is None:
        _local.overview = _OverviewCanvas()
    _local.overview.draw(analysis).savefig(path, dpi=dpi, pil_kwargs={"compress_level": 1})
    return path

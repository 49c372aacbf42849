"""Per-trial figures (matplotlib, Agg canvas; no pyplot state, safe in worker threads)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from ..frames import FACE_COLORS

__all__ = ["trial_figure", "save_trial_figures"]

#: Most points drawn per curve (the series is decimated to this for the figure only).
_MAX_POINTS = 1500
_PHASE_COLOURS = {"load": "#dbe9f6", "lift": "#fde3c8", "hold": "#e2f0d9", "replace": "#fde3c8", "release": "#ececec"}


def _shade(ax, analysis, trial) -> None:
    """Phase spans of ``trial``; implausible phases (not single contacts) hatched red."""
    bad = set(_implausible(analysis, trial))
    for name, (a, b) in trial.phases.items():
        ax.axvspan(a, b, color=_PHASE_COLOURS.get(name, "#eeeeee"), lw=0, zorder=0)
        if name in bad:
            ax.axvspan(a, b, facecolor="none", edgecolor="#c0392b", hatch="///", lw=0, zorder=1)


def trial_figure(analysis, trial) -> Figure:
    """Forces, normal force per patch and contact displacement of one trial, phases shaded.

    A phase whose contacts are not single contacts is hatched red and named in the title.
    """
    g = analysis.series
    pad = 0.3
    m = np.flatnonzero((g.time >= trial.start - pad) & (g.time <= trial.stop + pad))
    m = m[:: max(1, m.size // _MAX_POINTS)]  # a screen's worth of points per curve
    t = g.time[m]
    fingers = np.array([i + 1 != analysis.settings.base_face for i in range(6)])
    fig = Figure(figsize=(8, 7.5))  # fixed margins: a layout engine would cost a third of the drawing
    fig.subplots_adjust(left=0.08, right=0.98, bottom=0.065, top=0.91, hspace=0.1)
    FigureCanvasAgg(fig)
    axes = fig.subplots(3, 1, sharex=True)
    ax = axes[0]
    ax.plot(t, (g.f_n[m] * fingers).sum(axis=1), label="grip force (Σ finger normal)")
    ax.plot(t, (g.f_t[m] * fingers).sum(axis=1), label="load force (Σ finger tangential)")
    ax.plot(t, np.linalg.norm(g.f_int[m], axis=2).sum(axis=1), "--", label="internal force Σ‖(I−G⁺G)f‖")
    ax.plot(t, np.linalg.norm(g.f_manip[m], axis=2).sum(axis=1), ":", label="manipulation force Σ‖G⁺Gf‖")
    ax.set_ylabel("force (N)")
    ax.legend(fontsize=7, loc="upper right")
    ax = axes[1]
    for i in range(6):
        if g.on[m, i].any():
            role = " (base)" if i + 1 == analysis.settings.base_face else ""
            ax.plot(t, np.where(g.on[m, i], g.f_n[m, i], np.nan), label=f"face {i + 1}{role}", color=FACE_COLORS[i + 1])
    ax.set_ylabel("normal force (N)")
    ax.legend(fontsize=7, loc="upper right")
    ax = axes[2]
    for i in range(6):
        p = g.path[m, i]
        if np.isfinite(p).any():
            first = p[np.isfinite(p).all(axis=1)][0]
            ax.plot(t, 1e3 * np.linalg.norm(p - first, axis=1), label=f"face {i + 1}", color=FACE_COLORS[i + 1])
    ax.set_ylabel("contact displacement (mm)")
    ax.set_xlabel("time (s)")
    for ax in axes:
        _shade(ax, analysis, trial)
        ax.grid(alpha=0.3)
    for name, (a, b) in trial.phases.items():
        axes[0].text((a + b) / 2, 1.0, name, transform=axes[0].get_xaxis_transform(), ha="center", va="bottom",
                     fontsize=8)
    bad = _implausible(analysis, trial)
    sim = "SIMULATED — " if analysis.simulated else ""
    title = f"{sim}trial {trial.index}: {trial.start:.2f}–{trial.stop:.2f} s"
    if bad:
        title += f"\nnot single contacts (hatched): {', '.join(bad)}"
    fig.suptitle(title, fontsize=10, color="#c0392b" if bad else "black")
    return fig


def _implausible(analysis, trial) -> list[str]:
    ph = analysis.phases
    rows = ph[(ph["trial"] == trial.index) & ph["plausible"].eq(False).fillna(False)]
    return [str(p) for p in rows["phase"]]


def save_trial_figures(analysis, directory, dpi: int = 90) -> list:
    """Write ``trial_NN.png`` for every trial into ``directory``; the paths written."""
    out = []
    for tr in analysis.trials:
        path = Path(directory) / f"trial_{tr.index:02d}.png"
        trial_figure(analysis, tr).savefig(path, dpi=dpi, pil_kwargs={"compress_level": 1})  # fast zlib
        out.append(path)
    return out

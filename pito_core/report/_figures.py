"""Figures and their data files: nothing here touches pyplot or matplotlib's global state."""

from __future__ import annotations

import csv
import math
import os

__all__ = ["new_figure", "save_png", "write_csv"]


def new_figure(*grid, figsize, **subplot_kw):
    """A new ``matplotlib.figure.Figure`` and ``fig.subplots(*grid, **subplot_kw)``: ``(fig, axes)``.

    No pyplot and no backend switch, so importing or calling this changes no global setting;
    ``figsize`` in inches.
    """
    # deferred: matplotlib takes ~0.4 s to import and the modules that use this load with `pito --help`
    from matplotlib.figure import Figure

    fig = Figure(figsize=figsize)
    return fig, fig.subplots(*grid, **subplot_kw)


def save_png(fig, path, *, dpi: int = 120, note: str | None = None, tight: bool = True) -> str:
    """Write ``fig`` to ``path`` as PNG at ``dpi``; ``note`` (e.g. "SIMULATED data …") in small grey print
    at the bottom right. Returns ``path`` as ``str``."""
    if note:
        fig.text(0.995, 0.005, note, ha="right", va="bottom", fontsize=7, color="0.4")
    if tight:
        fig.tight_layout()
    fig.savefig(path, dpi=dpi)
    return os.fspath(path)


def write_csv(path, header, rows) -> str:
    """A CSV file: ``header`` then ``rows``; floats with 9 significant digits, non-finite ones empty."""

    def cell(v):
        if isinstance(v, float):
            return f"{v:.9g}" if math.isfinite(v) else ""
        return v

    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(header)
        w.writerows([cell(v) for v in r] for r in rows)
    return os.fspath(path)

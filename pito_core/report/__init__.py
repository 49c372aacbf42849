"""Output for people: plain-text tables with units and figures that change no global setting.

One place for what the command line, ``pito bench`` and ``pito reproduce`` print and draw:

- :func:`fmt` a number with its significant digits (``—`` for NaN or None),
- :func:`table` right-aligned plain-text columns under a header,
- :func:`new_figure` a matplotlib ``Figure`` and its axes grid (no pyplot, no backend switch),
- :func:`save_png` and :func:`write_csv` the files behind a figure,
- the calibration report: :func:`rmse_figure`, :func:`identification_figure`,
  :func:`comparison_figure` (the wizard's results page draws the same), :func:`model_summary`
  and :func:`export_report` (a folder of figures, ``report.md`` and ``numbers.json``),
- why face identification scores what it does: :func:`identification_breakdown`,
  :func:`identification_why` (a paragraph) and :func:`identification_note` (one line).
"""

from ._calibration import (
    SCREEN_DPI,
    SMALL,
    comparison_figure,
    export_report,
    face_rmse,
    identification_figure,
    model_summary,
    rmse_figure,
    style_figure,
)
from ._figures import new_figure, save_png, write_csv
from ._identification import identification_breakdown, identification_note, identification_text, identification_why
from ._text import fmt, table

__all__ = ["fmt", "table", "new_figure", "save_png", "write_csv", "rmse_figure", "identification_figure",
           "comparison_figure", "style_figure", "model_summary", "export_report", "SMALL", "SCREEN_DPI",
           "identification_breakdown", "identification_why", "identification_note", "identification_text",
           "face_rmse"]

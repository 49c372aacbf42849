"""Plain-text tables with units for the command line."""

from __future__ import annotations

import numpy as np

__all__ = ["table", "fmt"]


def fmt(x, digits: int = 4) -> str:
    """A number with ``digits`` significant digits; ``—`` for NaN/None."""
    if x is None:
        return "—"
    x = float(x)
    if not np.isfinite(x):
        return "—"
    return f"{x:.{digits}g}"


def table(header, rows, title: str | None = None) -> str:
    """Right-aligned columns under ``header``; ``rows`` are sequences of str."""
    cols = [list(map(str, header))] + [list(map(str, r)) for r in rows]
    widths = [max(len(r[k]) for r in cols) for k in range(len(header))]
    line = lambda r: "  ".join(c.rjust(w) if k else c.ljust(w) for k, (c, w) in enumerate(zip(r, widths)))  # noqa: E731
    out = []
    if title:
        out.append(title)
    out.append(line(cols[0]))
    out.append("  ".join("-" * w for w in widths))
    out += [line(r) for r in cols[1:]]
    return "\n".join(out)

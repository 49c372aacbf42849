"""Plain-text tables: numbers with their significant digits, columns under a header."""

from __future__ import annotations

import math

__all__ = ["fmt", "table"]


def fmt(x, digits: int = 4) -> str:
    """``x`` with ``digits`` significant digits (``—`` for None and non-finite numbers; text as is).

    Scientific notation where ``format(x, "g")`` chooses it (below 10⁻⁴ or from 10^digits up).
    """
    if x is None:
        return "—"
    try:
        x = float(x)
    except (TypeError, ValueError):
        return str(x)
    if not math.isfinite(x):
        return "—"
    return f"{x:.{digits}g}"


def table(header, rows, title: str | None = None) -> str:
    """Columns under ``header``: the first left-aligned, the rest right-aligned; ``rows`` of any values (``str()``-ed).

    Units belong in the header (``"RMSE fx (N)"``). ``title``, if given, is the first line.
    """
    cols = [[str(c) for c in header]] + [[str(c) for c in r] for r in rows]
    for k, r in enumerate(cols[1:], 1):
        if len(r) != len(cols[0]):
            raise ValueError(f"rows[{k - 1}]: expected {len(cols[0])} values (one per header column), got {len(r)}")
    widths = [max(len(r[k]) for r in cols) for k in range(len(cols[0]))]
    line = lambda r: "  ".join(c.ljust(w) if k == 0 else c.rjust(w) for k, (c, w) in enumerate(zip(r, widths)))  # noqa: E731
    out = [title] if title else []
    out += [line(cols[0]), "  ".join("-" * w for w in widths)]
    out += [line(r) for r in cols[1:]]
    return "\n".join(out)

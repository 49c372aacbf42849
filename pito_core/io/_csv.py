"""CSV import/export of sessions for labs that log to text.

Columns (header row required, any order, extra columns ignored):
``time`` (s, optional), ``counts_1`` … ``counts_36``, ``fx fy fz`` (N), ``tx ty tz`` (N·m),
``loaded_1`` … ``loaded_6`` (0/1 or true/false).
"""

from __future__ import annotations

import csv

import numpy as np

from ..frames import N_GAUGES, WRENCH_COMPONENTS

__all__ = ["read_session_csv_fields", "write_session_csv", "CSV_COUNTS", "CSV_REFERENCE", "CSV_LOADED"]

CSV_COUNTS = [f"counts_{j}" for j in range(1, N_GAUGES + 1)]
CSV_REFERENCE = list(WRENCH_COMPONENTS)
CSV_LOADED = [f"loaded_{i}" for i in range(1, 7)]


def _parse_bool(col: np.ndarray, name: str, rows_offset: int = 2) -> np.ndarray:
    low = np.char.lower(np.char.strip(col.astype(str)))
    true = np.isin(low, ["1", "true", "t", "yes", "1.0"])
    false = np.isin(low, ["0", "false", "f", "no", "0.0", ""])
    bad = np.flatnonzero(~(true | false))
    if bad.size:
        raise ValueError(f"{name}: expected 0/1 or true/false, got {col[bad[0]]!r} on line {bad[0] + rows_offset}")
    return true


def read_session_csv_fields(path) -> dict:
    """Read the sample columns of a session CSV (see module docstring for the columns).

    Returns ``counts`` (N, 36), ``reference`` (N, 6) N and N·m, ``loaded`` (N, 6) bool and
    ``time`` (N,) s or None; ``CalibrationSession.from_csv`` builds the session.
    """

    with open(path, newline="") as fh:
        reader = csv.reader(fh)
        try:
            header = [h.strip() for h in next(reader)]
        except StopIteration:
            raise ValueError(f"{path}: empty CSV file, expected a header row") from None
        rows = [r for r in reader if r and any(c.strip() for c in r)]
    missing = [c for c in CSV_COUNTS + CSV_REFERENCE + CSV_LOADED if c not in header]
    if missing:
        raise ValueError(f"{path}: missing columns {missing[:6]}{' …' if len(missing) > 6 else ''}")
    width = len(header)
    for k, r in enumerate(rows):
        if len(r) != width:
            raise ValueError(f"{path}: line {k + 2} has {len(r)} fields, expected {width}")
    table = np.array(rows, dtype=object).reshape(len(rows), width) if rows else np.empty((0, width), dtype=object)
    col = {name: table[:, j] for j, name in enumerate(header)}

    def numeric(names, what):
        try:
            return np.array([col[c].astype(float) for c in names]).T.reshape(len(rows), len(names))
        except ValueError as exc:
            raise ValueError(f"{path}: {what}: non-numeric value ({exc})") from None

    counts = numeric(CSV_COUNTS, "counts")
    if np.all(np.isfinite(counts)) and np.all(counts == np.round(counts)) and np.all(np.abs(counts) < 2**62):
        counts = counts.astype(np.int64)
    reference = numeric(CSV_REFERENCE, "reference")
    loaded = np.array([_parse_bool(col[c], c) for c in CSV_LOADED]).T.reshape(len(rows), 6)
    time = numeric(["time"], "time")[:, 0] if "time" in col else None
    return {"counts": counts, "reference": reference, "loaded": loaded, "time": time}


def write_session_csv(path, session) -> None:
    """Write a session's samples as CSV with the columns :func:`read_session_csv` reads."""
    header = (["time"] if session.time is not None else []) + CSV_COUNTS + CSV_REFERENCE + CSV_LOADED
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        for block in session.iter_blocks():
            n = block.counts.shape[0]
            counts = np.asarray(session.counts[block.start : block.start + n])
            parts = []
            if session.time is not None:
                parts.append(np.asarray(session.time[block.start : block.start + n], dtype=object)[:, None])
            parts += [counts.astype(object), block.reference.astype(object), block.loaded.astype(int).astype(object)]
            for row in np.hstack(parts):
                w.writerow([repr(float(v)) if isinstance(v, float) else v for v in row])

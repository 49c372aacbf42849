"""Grasp trials into NWB: an intervals table ``intervals/grasp_phases`` (docs/analysis.md, "NWB").

One row per trial × phase of :mod:`pito_core.analysis` (its ``phases`` table): ``start_time``
and ``stop_time`` (s, the file's timestamps), ``trial``, ``phase`` and every metric column
(the unit in the column name and its description). Separate from :func:`write_nwb`: it is
added to a file that function wrote.
"""

from __future__ import annotations

import numpy as np

__all__ = ["append_grasp_phases", "GRASP_PHASES_TABLE"]

#: Name of the intervals table.
GRASP_PHASES_TABLE = "grasp_phases"


def append_grasp_phases(path, phases, descriptions: dict | None = None) -> int:
    """Add ``phases`` (a DataFrame with ``start_s``, ``stop_s``, ``trial``, ``phase``, metrics) to the NWB file ``path``.

    Parameters
    ----------
    path : str or Path
        An NWB file (e.g. written by :func:`write_nwb`), opened in append mode.
    phases : pandas.DataFrame
        :attr:`GraspAnalysis.phases`.
    descriptions : dict, optional
        Column → description (default: the column name).

    Returns
    -------
    int
        Rows written.
    """
    from pynwb import NWBHDF5IO  # optional dependency (extra "interop")
    from pynwb.epoch import TimeIntervals

    descriptions = descriptions or {}
    table = TimeIntervals(name=GRASP_PHASES_TABLE, description="grasp trials and phases with their metrics "
                          "(pito analyze; units in the column names; docs/analysis.md)")
    cols = [c for c in phases.columns if c not in ("start_s", "stop_s")]
    for c in cols:
        table.add_column(name=c, description=descriptions.get(c, c))
    for row in phases.itertuples(index=False):
        r = row._asdict()
        values = {c: _nwb_value(r[c]) for c in cols}
        table.add_interval(start_time=float(r["start_s"]), stop_time=float(r["stop_s"]), **values)
    with NWBHDF5IO(str(path), "a") as io:
        nwb = io.read()
        nwb.add_time_intervals(table)
        io.write(nwb)
    return len(phases)


def _nwb_value(v):
    """A table cell NWB can store: str for categories and flags (``"unknown"`` for a missing flag)."""
    if isinstance(v, (bool, np.bool_)):
        return "true" if v else "false"
    if v is None or (not isinstance(v, (str, int, float, np.integer, np.floating))):
        return "unknown" if v is None or str(v) == "<NA>" else str(v)
    if isinstance(v, (np.integer, int)):
        return int(v)
    if isinstance(v, (np.floating, float)):
        return float(v)
    return v

"""Export recordings to CSV (one file per stream) and MATLAB ``.mat``.

CSV columns (header row, SI units, floats written with 17 significant digits so they read
back exactly):

- cube: ``time`` (s, the one time base: the cube's device clock, unwrapped, from the first
  sample of either stream; strictly increasing), ``host_time`` (s, arrival at the host),
  ``seq``, ``time_us`` (µs, device clock as sent), ``counts_1`` … ``counts_36``;
- Net F/T: ``time`` (s, its ``rdt_seq`` clock on the same base), ``host_time`` (s),
  ``rdt_seq``, ``ft_seq``, ``status``, ``fx fy fz`` (N), ``tx ty tz`` (N·m).

``time`` is :func:`pito_core.pipeline.recording_times` of the recording, passed in as ``times``
(io does not pair clocks); without it the column is left out (the layout of older exports).

MATLAB variables: ``pito_time``, ``pito_seq``, ``pito_time_us``, ``pito_host_time``, ``pito_counts``
(N×36), ``ati_time``, ``ati_rdt_seq``, ``ati_ft_seq``, ``ati_status``, ``ati_host_time``, ``ati_wrench``
(M×6, N and N·m), ``meta_json`` (the header metadata as JSON text), ``format``, ``version``.
"""

from __future__ import annotations

import json
import os

import numpy as np

from ..frames import N_GAUGES
from ._csv import CSV_COUNTS, CSV_REFERENCE
from ._recording import RECORDING_FORMAT, RECORDING_VERSION

__all__ = ["export_recording_files", "export_recording_csv", "export_recording_mat", "read_recording_csv", "RECORDING_CSV_COLUMNS"]

#: Column names of the exported CSV files, per stream.
RECORDING_CSV_COLUMNS = {
    "pito": ["time", "host_time", "seq", "time_us"] + CSV_COUNTS,
    "netft": ["time", "host_time", "rdt_seq", "ft_seq", "status"] + CSV_REFERENCE,
}


def _table(recording, stream: str, time=None) -> tuple[list, list[str], set]:
    """Columns, names and the indices of the float columns of one stream (``time``: its times, s, or None)."""
    if stream == "pito":
        r = recording.pito
        cols = [r["host_time"], r["seq"], r["time_us"]] + [r["counts"][:, j] for j in range(N_GAUGES)]
        floats = {0}
    elif stream == "netft":
        r = recording.netft
        cols = [r["host_time"], r["rdt_seq"], r["ft_seq"], r["status"]] + [r["wrench"][:, j] for j in range(6)]
        floats = {0, 4, 5, 6, 7, 8, 9}
    else:
        raise ValueError(f"stream: expected 'pito' or 'netft', got {stream!r}")
    names = RECORDING_CSV_COLUMNS[stream]
    if time is None:
        return cols, names[1:], floats
    time = np.asarray(time, float)
    if time.shape != (r.size,):
        raise ValueError(f"time: expected shape ({r.size},) for the {stream} stream, got {time.shape}")
    return [time] + cols, names, {0} | {j + 1 for j in floats}


def export_recording_csv(recording, path, stream: str = "pito", time=None) -> None:
    """Write one stream of ``recording`` (a :class:`Recording`) to exactly ``path`` as CSV.

    ``time``: the stream's sample times ``(n,)`` s (:func:`pito_core.pipeline.recording_times`), the first column.
    """
    cols, names, float_cols = _table(recording, stream, time)
    n = len(cols[0])
    with open(os.fspath(path), "w", newline="") as fh:
        fh.write(",".join(names) + "\n")
        if n:
            fmt = ",".join("%.17g" if j in float_cols else "%d" for j in range(len(cols)))
            table = np.empty((n, len(cols)), dtype=object)
            for j, c in enumerate(cols):
                table[:, j] = c.astype(float) if j in float_cols else c.astype(np.int64)
            np.savetxt(fh, table, fmt=fmt)


def read_recording_csv(path, stream: str = "pito") -> dict:
    """Read a CSV written by :func:`export_recording_csv` (with or without ``time``) into ``{column: array}``."""
    names = RECORDING_CSV_COLUMNS.get(stream)
    if names is None:
        raise ValueError(f"stream: expected 'pito' or 'netft', got {stream!r}")
    with open(os.fspath(path)) as fh:
        header = fh.readline().strip().split(",")
    if header == names[1:]:
        names = names[1:]
    if header != names:
        raise ValueError(f"{path}: expected the columns of a '{stream}' recording export, got {header[:5]}…")
    data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2, dtype=float)
    if data.size == 0:
        data = np.zeros((0, len(names)))
    return {name: data[:, j] for j, name in enumerate(names)}


def export_recording_mat(recording, path, times=None) -> None:
    """Write ``recording`` to exactly ``path`` as a MATLAB ``.mat`` file (v5, scipy.io.savemat).

    ``times``: ``(cube times (n,), reference times (m,))`` s (:func:`pito_core.pipeline.recording_times`):
    the variables ``pito_time`` and ``ati_time``.
    """
    # deferred: scipy.io loads its MATLAB, NetCDF and Harwell-Boeing readers (~0.1 s) and this
    # module loads with every `pito` command
    from scipy.io import savemat

    p, a = recording.pito, recording.netft
    extra = {}
    if times is not None:
        tc, tr = (np.asarray(t, float) for t in times)
        if tc.shape != (p.size,) or tr.shape != (a.size,):
            raise ValueError(f"times: expected shapes ({p.size},) and ({a.size},), got {tc.shape} and {tr.shape}")
        extra = {"pito_time": tc.reshape(-1, 1), "ati_time": tr.reshape(-1, 1)}
    with open(os.fspath(path), "wb") as fh:  # exactly the name given: savemat adds ".mat" to str paths
        savemat(
            fh,
            {
                **extra,
                "format": RECORDING_FORMAT,
                "version": RECORDING_VERSION,
                "meta_json": json.dumps(recording.meta),
                "pito_seq": p["seq"].reshape(-1, 1),
                "pito_time_us": p["time_us"].reshape(-1, 1),
                "pito_host_time": p["host_time"].reshape(-1, 1),
                "pito_counts": p["counts"].reshape(-1, N_GAUGES),
                "ati_rdt_seq": a["rdt_seq"].reshape(-1, 1),
                "ati_ft_seq": a["ft_seq"].reshape(-1, 1),
                "ati_status": a["status"].reshape(-1, 1),
                "ati_host_time": a["host_time"].reshape(-1, 1),
                "ati_wrench": a["wrench"].reshape(-1, 6),
            },
            do_compression=True,
        )


def export_recording_files(recording, csv_prefix=None, mat=None, times=None) -> list[str]:
    """Write ``recording`` as ``{csv_prefix}_pito.csv`` + ``{csv_prefix}_ati.csv`` and/or ``mat``.

    The one export path of ``pito replay --csv/--mat`` and ``pito export``; returns the paths written.
    ``times``: ``(cube times, reference times)`` s (:func:`pito_core.pipeline.recording_times`).
    """
    written = []
    tc, tr = (None, None) if times is None else times
    if csv_prefix:
        export_recording_csv(recording, f"{csv_prefix}_pito.csv", "pito", tc)
        export_recording_csv(recording, f"{csv_prefix}_ati.csv", "netft", tr)
        written += [f"{csv_prefix}_pito.csv", f"{csv_prefix}_ati.csv"]
    if mat:
        export_recording_mat(recording, mat, times)
        written.append(str(mat))
    return written

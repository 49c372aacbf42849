"""Export recordings to CSV (one file per stream) and MATLAB ``.mat``.

CSV columns (header row, SI units, floats written with 17 significant digits so they read
back exactly):

- cube: ``host_time`` (s), ``seq``, ``time_us`` (µs, device clock), ``counts_1`` … ``counts_36``;
- Net F/T: ``host_time`` (s), ``rdt_seq``, ``ft_seq``, ``status``, ``fx fy fz`` (N),
  ``tx ty tz`` (N·m).

MATLAB variables: ``pito_seq``, ``pito_time_us``, ``pito_host_time``, ``pito_counts``
(N×36), ``ati_rdt_seq``, ``ati_ft_seq``, ``ati_status``, ``ati_host_time``, ``ati_wrench``
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
    "pito": ["host_time", "seq", "time_us"] + CSV_COUNTS,
    "netft": ["host_time", "rdt_seq", "ft_seq", "status"] + CSV_REFERENCE,
}


def _table(recording, stream: str) -> tuple[np.ndarray, list[str]]:
    if stream == "pito":
        r = recording.pito
        cols = [r["host_time"], r["seq"], r["time_us"]] + [r["counts"][:, j] for j in range(N_GAUGES)]
    elif stream == "netft":
        r = recording.netft
        cols = [r["host_time"], r["rdt_seq"], r["ft_seq"], r["status"]] + [r["wrench"][:, j] for j in range(6)]
    else:
        raise ValueError(f"stream: expected 'pito' or 'netft', got {stream!r}")
    return cols, RECORDING_CSV_COLUMNS[stream]


def export_recording_csv(recording, path, stream: str = "pito") -> None:
    """Write one stream of ``recording`` (a :class:`Recording`) to exactly ``path`` as CSV."""
    cols, names = _table(recording, stream)
    n = len(cols[0])
    with open(os.fspath(path), "w", newline="") as fh:
        fh.write(",".join(names) + "\n")
        if n:
            float_cols = {0} if stream == "pito" else {0, 4, 5, 6, 7, 8, 9}
            fmt = ",".join("%.17g" if j in float_cols else "%d" for j in range(len(cols)))
            table = np.empty((n, len(cols)), dtype=object)
            for j, c in enumerate(cols):
                table[:, j] = c.astype(float) if j in float_cols else c.astype(np.int64)
            np.savetxt(fh, table, fmt=fmt)


def read_recording_csv(path, stream: str = "pito") -> dict:
    """Read a CSV written by :func:`export_recording_csv` into ``{column: array}``."""
    names = RECORDING_CSV_COLUMNS.get(stream)
    if names is None:
        raise ValueError(f"stream: expected 'pito' or 'netft', got {stream!r}")
    with open(os.fspath(path)) as fh:
        header = fh.readline().strip().split(",")
    if header != names:
        raise ValueError(f"{path}: expected the columns of a '{stream}' recording export, got {header[:5]}…")
    data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2, dtype=float)
    if data.size == 0:
        data = np.zeros((0, len(names)))
    return {name: data[:, j] for j, name in enumerate(names)}


def export_recording_mat(recording, path) -> None:
    """Write ``recording`` to exactly ``path`` as a MATLAB ``.mat`` file (v5, scipy.io.savemat)."""
    # deferred: scipy.io loads its MATLAB, NetCDF and Harwell-Boeing readers (~0.1 s) and this
    # module loads with every `pito` command
    from scipy.io import savemat

    p, a = recording.pito, recording.netft
    with open(os.fspath(path), "wb") as fh:  # exactly the name given: savemat adds ".mat" to str paths
        savemat(
            fh,
            {
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


def export_recording_files(recording, csv_prefix=None, mat=None) -> list[str]:
    """Write ``recording`` as ``{csv_prefix}_pito.csv`` + ``{csv_prefix}_ati.csv`` and/or ``mat``.

    The one export path of ``pito replay --csv/--mat`` and ``pito export``; returns the paths written.
    """
    written = []
    if csv_prefix:
        export_recording_csv(recording, f"{csv_prefix}_pito.csv", "pito")
        export_recording_csv(recording, f"{csv_prefix}_ati.csv", "netft")
        written += [f"{csv_prefix}_pito.csv", f"{csv_prefix}_ati.csv"]
    if mat:
        export_recording_mat(recording, mat)
        written.append(str(mat))
    return written

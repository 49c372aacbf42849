"""Export recordings to CSV (one file per stream) and MATLAB ``.mat``, block by block (bounded memory).

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
from ._mat import Mat5Writer
from ._recording import NETFT_ROW, PITO_ROW, RECORDING_FORMAT, RECORDING_VERSION

__all__ = ["export_recording_files", "export_recording_csv", "export_recording_mat", "read_recording_csv", "RECORDING_CSV_COLUMNS"]

#: Column names of the exported CSV files, per stream.
RECORDING_CSV_COLUMNS = {
    "pito": ["time", "host_time", "seq", "time_us"] + CSV_COUNTS,
    "netft": ["time", "host_time", "rdt_seq", "ft_seq", "status"] + CSV_REFERENCE,
}


#: Rows per block: the exports read and write a recording this many rows at a time.
BLOCK = 65536


def _rows(recording, stream: str, start: int, stop: int) -> np.ndarray:
    """Rows ``start:stop`` of a :class:`Recording` (in memory) or a :class:`RecordingChunks` (read from the file)."""
    if hasattr(recording, "rows"):
        return recording.rows(stream, start, stop)
    return (recording.pito if stream == "pito" else recording.netft)[start:stop]


def _n_rows(recording, stream: str) -> int:
    if hasattr(recording, "rows"):
        return recording.n_pito if stream == "pito" else recording.n_netft
    return int((recording.pito if stream == "pito" else recording.netft).size)


def _columns(rows: np.ndarray, stream: str) -> list:
    if stream == "pito":
        return [rows["host_time"], rows["seq"], rows["time_us"]] + [rows["counts"][:, j] for j in range(N_GAUGES)]
    return [rows["host_time"], rows["rdt_seq"], rows["ft_seq"], rows["status"]] + [rows["wrench"][:, j] for j in range(6)]


def export_recording_csv(recording, path, stream: str = "pito", time=None, progress=None) -> None:
    """Write one stream of ``recording`` to exactly ``path`` as CSV, :data:`BLOCK` rows at a time.

    ``recording``: a :class:`Recording` or a :class:`RecordingChunks` (bounded memory: an hour's
    recording is never held whole). ``time``: the stream's sample times ``(n,)`` s
    (:func:`pito_core.pipeline.recording_times`), the first column. ``progress(fraction, text)``,
    optional, after each block.
    """
    if stream not in RECORDING_CSV_COLUMNS:
        raise ValueError(f"stream: expected 'pito' or 'netft', got {stream!r}")
    n = _n_rows(recording, stream)
    names = RECORDING_CSV_COLUMNS[stream]
    floats = {0} if stream == "pito" else {0, 4, 5, 6, 7, 8, 9}
    if time is None:
        names = names[1:]
    else:
        time = np.asarray(time, float)
        if time.shape != (n,):
            raise ValueError(f"time: expected shape ({n},) for the {stream} stream, got {time.shape}")
        floats = {0} | {j + 1 for j in floats}
    fmt = ",".join("%.17g" if j in floats else "%d" for j in range(len(names)))
    with open(os.fspath(path), "w", newline="") as fh:
        fh.write(",".join(names) + "\n")
        for a in range(0, n, BLOCK):
            rows = _rows(recording, stream, a, a + BLOCK)
            cols = _columns(rows, stream) if time is None else [time[a:a + len(rows)]] + _columns(rows, stream)
            table = np.empty((len(rows), len(cols)), dtype=object)
            for j, c in enumerate(cols):
                table[:, j] = c.astype(float) if j in floats else c.astype(np.int64)
            np.savetxt(fh, table, fmt=fmt)
            if progress is not None:
                progress(min(1.0, (a + len(rows)) / n), f"{path}: {a + len(rows)} of {n} rows")


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


#: The .mat variables of each stream: (name, field of the row, columns).
_MAT_VARS = {
    "pito": (("pito_seq", "seq", 1), ("pito_time_us", "time_us", 1), ("pito_host_time", "host_time", 1),
             ("pito_counts", "counts", N_GAUGES)),
    "netft": (("ati_rdt_seq", "rdt_seq", 1), ("ati_ft_seq", "ft_seq", 1), ("ati_status", "status", 1),
              ("ati_host_time", "host_time", 1), ("ati_wrench", "wrench", 6)),
}


def export_recording_mat(recording, path, times=None, progress=None) -> None:
    """Write ``recording`` to exactly ``path`` as a MATLAB v5 ``.mat`` file, :data:`BLOCK` rows at a time.

    ``recording``: a :class:`Recording` or a :class:`RecordingChunks` (bounded memory). The file is
    uncompressed (:class:`Mat5Writer` says why); ``scipy.io.loadmat`` and MATLAB read it.
    ``times``: ``(cube times (n,), reference times (m,))`` s (:func:`pito_core.pipeline.recording_times`):
    the variables ``pito_time`` and ``ati_time``. ``progress(fraction, text)``, optional, after each block.
    """
    n = {s: _n_rows(recording, s) for s in ("pito", "netft")}
    total, done = max(1, n["pito"] + n["netft"]), 0
    if times is not None:
        times = tuple(np.asarray(t, float) for t in times)
        if times[0].shape != (n["pito"],) or times[1].shape != (n["netft"],):
            raise ValueError(f"times: expected shapes ({n['pito']},) and ({n['netft']},), "
                             f"got {times[0].shape} and {times[1].shape}")
    with open(os.fspath(path), "w+b") as fh:  # exactly the name given
        w = Mat5Writer(fh, f"MATLAB 5.0 MAT-file, {RECORDING_FORMAT} version {RECORDING_VERSION}, written by pito")
        w.value("format", RECORDING_FORMAT)
        w.value("version", np.int64(RECORDING_VERSION))
        w.value("meta_json", json.dumps(recording.meta))
        if times is not None:
            w.value("pito_time", times[0].reshape(-1, 1))
            w.value("ati_time", times[1].reshape(-1, 1))
        for stream, variables in _MAT_VARS.items():
            dtype = (PITO_ROW if stream == "pito" else NETFT_ROW)
            mats = [(w.matrix(name, (n[stream], k), dtype[field].base), field) for name, field, k in variables]
            for a in range(0, n[stream], BLOCK):
                rows = _rows(recording, stream, a, a + BLOCK)
                for m, field in mats:
                    w.fill(m, a, rows[field])
                done += len(rows)
                if progress is not None:
                    progress(done / total, f"{path}: {done} of {total} rows")
        w.close()


def export_recording_files(recording, csv_prefix=None, mat=None, times=None, progress=None) -> list[str]:
    """Write ``recording`` as ``{csv_prefix}_pito.csv`` + ``{csv_prefix}_ati.csv`` and/or ``mat``.

    The one export path of ``pito replay --csv/--mat`` and ``pito export``; returns the paths written.
    ``times``: ``(cube times, reference times)`` s (:func:`pito_core.pipeline.recording_times`).
    ``progress(fraction, text)``, optional: each file's blocks.
    """
    written = []
    tc, tr = (None, None) if times is None else times
    if csv_prefix:
        export_recording_csv(recording, f"{csv_prefix}_pito.csv", "pito", tc, progress)
        export_recording_csv(recording, f"{csv_prefix}_ati.csv", "netft", tr, progress)
        written += [f"{csv_prefix}_pito.csv", f"{csv_prefix}_ati.csv"]
    if mat:
        export_recording_mat(recording, mat, times, progress)
        written.append(str(mat))
    return written

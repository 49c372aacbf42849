"""The session file: HDF5, format ``pito-session``, version 1.

Layout (documented in docs/file-formats.md)::

    /            attrs: format="pito-session", version=1, writer, flange, connected_face,
                        core_edge (m), counts_range [lo, hi], meta (JSON text)
    /counts      (N, 36) as given (int32/int64/float64), chunked, gzip
    /reference   (N, 6) float64, N and N·m, reference frame
    /loaded      (N, 6) bool
    /T_core_ati  (4, 4) float64
    /time        (N,) float64 s, optional
"""

from __future__ import annotations

import os

import h5py
import numpy as np

from ..frames import N_GAUGES
from ._hdf5 import (
    CheckedDataset,
    FileFormatError,
    checked_read,
    json_attr,
    open_checked,
    read_json_attr,
    require,
    seal,
    verify,
    write_header,
)

__all__ = ["write_session", "read_session_fields", "SESSION_FORMAT", "SESSION_VERSION"]

SESSION_FORMAT = "pito-session"
SESSION_VERSION = 1
_CHUNK_ROWS = 8192


def write_session(path, session, block_size: int = 262144) -> None:
    """Write ``session`` to exactly ``path`` (overwriting), block by block."""
    n = len(session)
    counts_dtype = np.asarray(session.counts[:0]).dtype
    if counts_dtype.kind not in "iuf":
        counts_dtype = np.dtype(float)
    tmp = f"{os.fspath(path)}.partial"
    with h5py.File(tmp, "w") as f:
        write_header(f, SESSION_FORMAT, SESSION_VERSION)
        f.attrs["flange"] = session.flange
        f.attrs["connected_face"] = session.connected_face
        f.attrs["core_edge"] = session.core.edge
        f.attrs["counts_range"] = np.asarray(session.counts_range, dtype=np.int64)
        f.attrs["meta"] = json_attr(session.meta)
        chunk = (min(max(n, 1), _CHUNK_ROWS),)
        dc = f.create_dataset("counts", (n, N_GAUGES), dtype=counts_dtype, chunks=chunk + (N_GAUGES,), compression="gzip", compression_opts=1, shuffle=True, fletcher32=True)
        dr = f.create_dataset("reference", (n, 6), dtype=float, chunks=chunk + (6,), compression="gzip", compression_opts=1, shuffle=True, fletcher32=True)
        dl = f.create_dataset("loaded", (n, 6), dtype=bool, chunks=chunk + (6,), compression="gzip", compression_opts=1, fletcher32=True)
        for start in range(0, n, block_size):
            stop = min(n, start + block_size)
            dc[start:stop] = np.asarray(session.counts[start:stop])
            dr[start:stop] = np.asarray(session.reference[start:stop])
            dl[start:stop] = np.asarray(session.loaded[start:stop])
        f.create_dataset("T_core_ati", data=np.asarray(session.T_core_ati, dtype=float), chunks=True, fletcher32=True)
        if session.time is not None:
            f.create_dataset("time", data=np.asarray(session.time, dtype=float), chunks=chunk, compression="gzip", compression_opts=1, fletcher32=True)
        seal(f)  # SHA-256 manifest of every dataset and attribute
    os.replace(tmp, path)  # a crash mid-write never leaves a half file under the real name


def read_session_fields(path, lazy: bool = False):
    """Read a session file into plain fields; ``lazy=True`` keeps the big arrays on disk.

    Returns ``(fields, f)``: the keyword arguments of :class:`pito_core.io.CalibrationSession`
    (``counts`` (N, 36), ``reference`` (N, 6) N and N·m, ``loaded`` (N, 6) bool, ``T_core_ati`` (4, 4),
    ``flange``, ``connected_face``, ``core_edge`` m, ``time`` (N,) s or None, ``meta``, ``counts_range``)
    and the open ``h5py.File`` that must stay open while the lazy datasets are used (``None`` when
    not lazy). ``CalibrationSession.load`` builds the object (io never imports calibration).
    """
    f = open_checked(path, SESSION_FORMAT, {SESSION_VERSION})
    try:
        # Lazy: the big datasets are not hashed at open (that would read them twice); every chunk
        # read is checked by its fletcher32 checksum instead, and `pito_core.io.verify_file` (io/_verify.py) checks
        # them in full. Eager: everything is hashed against the SHA-256 manifest.
        big = ("/counts", "/reference", "/loaded")
        verify(f, path, skip=big if lazy else ())
        counts = CheckedDataset(require(f, "counts", path), path)
        reference = CheckedDataset(require(f, "reference", path), path)
        loaded = CheckedDataset(require(f, "loaded", path), path)
        T = checked_read(require(f, "T_core_ati", path), path)
        time = checked_read(f["time"], path) if "time" in f else None
        meta = read_json_attr(f, "meta", path)
        attrs = {k: f.attrs[k] for k in ("flange", "connected_face", "core_edge", "counts_range") if k in f.attrs}
        missing = {"flange", "connected_face", "core_edge", "counts_range"} - set(attrs)
        if missing:
            raise FileFormatError(f"{path}: missing attributes {sorted(missing)}")
        flange = attrs["flange"].decode() if isinstance(attrs["flange"], bytes) else str(attrs["flange"])
        if not lazy:
            try:
                counts, reference, loaded = counts[()], reference[()], loaded[()]
            except OSError as exc:
                raise FileFormatError(f"{path}: data could not be read (truncated or corrupt?): {exc}") from None
        fields = {
            "counts": counts, "reference": reference, "loaded": loaded, "T_core_ati": T, "flange": flange,
            "connected_face": int(attrs["connected_face"]), "core_edge": float(attrs["core_edge"]),
            "time": time, "meta": meta, "counts_range": tuple(int(v) for v in attrs["counts_range"]),
        }
    except BaseException:  # close the file on any failure, then re-raise it unchanged
        f.close()
        raise
    if lazy:
        return fields, f  # the caller keeps f open while the session lives
    f.close()
    return fields, None

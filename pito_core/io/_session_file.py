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

from ._hdf5 import FileFormatError, json_attr, open_checked, read_json_attr, require, write_header

__all__ = ["write_session", "read_session", "SESSION_FORMAT", "SESSION_VERSION"]

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
        dc = f.create_dataset("counts", (n, 36), dtype=counts_dtype, chunks=chunk + (36,), compression="gzip", compression_opts=1, shuffle=True)
        dr = f.create_dataset("reference", (n, 6), dtype=float, chunks=chunk + (6,), compression="gzip", compression_opts=1, shuffle=True)
        dl = f.create_dataset("loaded", (n, 6), dtype=bool, chunks=chunk + (6,), compression="gzip", compression_opts=1)
        for start in range(0, n, block_size):
            stop = min(n, start + block_size)
            dc[start:stop] = np.asarray(session.counts[start:stop])
            dr[start:stop] = np.asarray(session.reference[start:stop])
            dl[start:stop] = np.asarray(session.loaded[start:stop])
        f.create_dataset("T_core_ati", data=np.asarray(session.T_core_ati, dtype=float))
        if session.time is not None:
            f.create_dataset("time", data=np.asarray(session.time, dtype=float), chunks=chunk, compression="gzip", compression_opts=1)
    os.replace(tmp, path)  # a crash mid-write never leaves a half file under the real name


def read_session(path, lazy: bool = False):
    """Read a session file; ``lazy=True`` keeps the big arrays on disk."""
    from ..calibration._session import CalibrationSession
    from ..frames import CubeCore

    f = open_checked(path, SESSION_FORMAT, {SESSION_VERSION})
    try:
        counts = require(f, "counts", path)
        reference = require(f, "reference", path)
        loaded = require(f, "loaded", path)
        T = np.asarray(require(f, "T_core_ati", path)[()])
        time = np.asarray(f["time"][()]) if "time" in f else None
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
        session = CalibrationSession(
            counts,
            reference,
            loaded,
            T,
            flange,
            int(attrs["connected_face"]),
            core=CubeCore(float(attrs["core_edge"])),
            time=time,
            meta=meta,
            counts_range=tuple(int(v) for v in attrs["counts_range"]),
            _lazy=lazy,
        )
    except Exception:
        f.close()
        raise
    if lazy:
        session._file = f  # keeps the datasets readable while the session lives
    else:
        f.close()
    return session

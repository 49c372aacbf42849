"""The calibration file: HDF5, format ``pito-calibration``, version 1.

Layout (docs/file-formats.md)::

    /             attrs: format="pito-calibration", version=1, writer, method, output_frame,
                         output_faces [..], core_edge (m), meta (JSON text)
    /matrix       (6·F, 36) float64: counts → N, N·m
    /offset       (36,) float64 counts
    /T_core_ati   (4, 4) float64
"""

from __future__ import annotations

import os

import h5py
import numpy as np

from ._hdf5 import FileFormatError, json_attr, open_checked, read_json_attr, require, write_header

__all__ = ["write_calibration", "read_calibration", "CALIBRATION_FORMAT", "CALIBRATION_VERSION"]

CALIBRATION_FORMAT = "pito-calibration"
CALIBRATION_VERSION = 1


def write_calibration(path, cal) -> None:
    """Write ``cal`` to exactly ``path`` (atomically: a temporary file, then rename)."""
    tmp = f"{os.fspath(path)}.partial"
    with h5py.File(tmp, "w") as f:
        write_header(f, CALIBRATION_FORMAT, CALIBRATION_VERSION)
        f.attrs["method"] = cal.method
        f.attrs["output_frame"] = cal.output_frame
        f.attrs["output_faces"] = np.asarray(cal.output_faces, dtype=np.int64)
        f.attrs["core_edge"] = cal.core.edge
        f.attrs["meta"] = json_attr(cal.meta)
        f.create_dataset("matrix", data=cal.matrix)
        f.create_dataset("offset", data=cal.offset)
        f.create_dataset("T_core_ati", data=cal.T_core_ati)
    os.replace(tmp, path)


def read_calibration(path):
    """Read a calibration file; a wrong, truncated or corrupt file raises ``FileFormatError``."""
    from ..calibration._calibration import Calibration
    from ..frames import CubeCore

    with open_checked(path, CALIBRATION_FORMAT, {CALIBRATION_VERSION}) as f:
        try:
            attrs = {k: f.attrs[k] for k in ("method", "output_frame", "output_faces", "core_edge")}
        except KeyError as exc:
            raise FileFormatError(f"{path}: missing attribute {exc}") from None
        try:
            matrix = np.asarray(require(f, "matrix", path)[()])
            offset = np.asarray(require(f, "offset", path)[()])
            T = np.asarray(require(f, "T_core_ati", path)[()])
        except OSError as exc:
            raise FileFormatError(f"{path}: data could not be read (truncated or corrupt?): {exc}") from None
        meta = read_json_attr(f, "meta", path)
    dec = lambda v: v.decode() if isinstance(v, bytes) else str(v)  # noqa: E731
    try:
        return Calibration(
            dec(attrs["method"]), matrix, [int(v) for v in attrs["output_faces"]], dec(attrs["output_frame"]),
            offset, CubeCore(float(attrs["core_edge"])), T, meta,
        )
    except ValueError as exc:
        raise FileFormatError(f"{path}: inconsistent calibration: {exc}") from None

"""``verify_file``: check any pito file in full (HDF5 SHA-256 manifest, or a recording's CRCs)."""

from __future__ import annotations

import os
from pathlib import Path

import h5py

from ._hdf5 import FileFormatError, verify
from ._recording import Recording

__all__ = ["verify_file"]


def verify_file(path) -> bool:
    """Verify a whole pito file; True if verified.

    HDF5 files (sessions, calibrations) are checked against their SHA-256 manifest in full
    (every dataset read once, in blocks); recordings are read with every CRC checked.
    Raises :class:`ChecksumError` (naming the file and dataset or chunk) on a mismatch;
    returns False with an :class:`UnverifiedFileWarning` for a file written before
    checksums existed.
    """
    path = Path(os.fspath(path))
    with open(path, "rb") as fh:
        magic = fh.read(8)
    if magic == b"PITOREC\0":
        Recording(path)
        return True
    try:
        f = h5py.File(path, "r")
    except OSError as exc:
        raise FileFormatError(f"{path}: not a readable HDF5 file (truncated or corrupt?): {exc}") from None
    with f:
        return verify(f, path)

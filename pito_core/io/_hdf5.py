"""Shared HDF5 helpers: format tags, versions, JSON attributes and clear errors."""

from __future__ import annotations

import json
import os
from pathlib import Path

import h5py
import numpy as np

__all__ = ["FileFormatError", "open_checked", "write_header", "json_attr", "read_json_attr"]


class FileFormatError(ValueError):
    """A file is not of the expected pito format, version, or is truncated/corrupt."""


def write_header(f: h5py.File, fmt: str, version: int) -> None:
    """Tag an HDF5 file with its pito format name and version."""
    f.attrs["format"] = fmt
    f.attrs["version"] = int(version)
    from .. import __version__

    f.attrs["writer"] = f"pito {__version__}"


def open_checked(path, fmt: str, versions, mode: str = "r") -> h5py.File:
    """Open ``path`` and check it is a pito ``fmt`` file of a supported version."""
    path = Path(os.fspath(path))
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such file")
    try:
        f = h5py.File(path, mode)
    except OSError as exc:
        raise FileFormatError(f"{path}: not a readable HDF5 file (truncated or corrupt?): {exc}") from None
    try:
        got = f.attrs.get("format")
        if isinstance(got, bytes):
            got = got.decode()
        if got != fmt:
            raise FileFormatError(f"{path}: expected a '{fmt}' file, got format {got!r}")
        version = int(f.attrs.get("version", -1))
        if version not in versions:
            raise FileFormatError(
                f"{path}: '{fmt}' version {version} is not supported (this pito reads {sorted(versions)})"
            )
    except Exception:
        f.close()
        raise
    return f


def json_attr(obj) -> str:
    """JSON text for an attribute (numpy scalars and arrays become plain values)."""

    def default(o):
        if isinstance(o, np.generic):
            return o.item()
        if isinstance(o, np.ndarray):
            return o.tolist()
        raise TypeError(f"meta: value of type {type(o).__name__} is not JSON-serialisable")

    return json.dumps(obj, default=default, allow_nan=True)


def read_json_attr(f: h5py.File, name: str, path) -> object:
    """Parse a JSON attribute, naming the file and attribute on error."""
    try:
        raw = f.attrs[name]
    except KeyError:
        raise FileFormatError(f"{path}: missing attribute '{name}'") from None
    if isinstance(raw, bytes):
        raw = raw.decode()
    try:
        return json.loads(raw)
    except json.JSONDecodeError as exc:
        raise FileFormatError(f"{path}: attribute '{name}' is not valid JSON: {exc}") from None


def require(f: h5py.File, name: str, path):
    """Dataset ``name`` or a :class:`FileFormatError` naming it."""
    if name not in f:
        raise FileFormatError(f"{path}: missing dataset '{name}'")
    return f[name]

"""Shared HDF5 helpers: format tags, versions, JSON attributes and clear errors."""

from __future__ import annotations

import hashlib
import json
import os
import warnings
from pathlib import Path

import h5py
import numpy as np

from .._version import __version__

__all__ = [
    "FileFormatError",
    "ChecksumError",
    "UnverifiedFileWarning",
    "open_checked",
    "write_header",
    "json_attr",
    "read_json_attr",
    "seal",
    "verify",
    "checked_read",
    "CHECKSUM_ATTR",
]

#: Root attribute holding the SHA-256 manifest (JSON ``{"algorithm", "objects": {path: hex}}``).
CHECKSUM_ATTR = "pito_checksums"
_BLOCK_BYTES = 64 << 20  # datasets are hashed in blocks of about this many bytes


class FileFormatError(ValueError):
    """A file is not of the expected pito format, version, or is truncated/corrupt."""


class ChecksumError(FileFormatError):
    """A stored checksum does not match the content: the file was altered or damaged.

    Attributes
    ----------
    path : str
        The file.
    dataset : str
        The HDF5 object (dataset, or group/attributes) whose content does not match.
    """

    def __init__(self, path, dataset: str, detail: str = ""):
        self.path, self.dataset, self.detail = str(path), str(dataset), str(detail)
        super().__init__(
            f"{path}: checksum mismatch in '{dataset}'{': ' + detail if detail else ''} "
            "(the file was altered or is damaged; it is refused)"
        )

    def __reduce__(self):  # pickles as itself (it crosses the pipeline process's boundary)
        return (ChecksumError, (self.path, self.dataset, self.detail))


class UnverifiedFileWarning(UserWarning):
    """A file written before pito stored checksums: its content cannot be verified."""


# ---------------------------------------------------------------------------- checksums
def _attrs_bytes(obj) -> bytes:
    """Canonical bytes of an object's attributes (the manifest attribute itself excluded)."""
    h = hashlib.sha256()
    for name in sorted(obj.attrs.keys()):
        if name == CHECKSUM_ATTR:
            continue
        v = obj.attrs[name]
        h.update(name.encode() + b"\0")
        if isinstance(v, (bytes, str)):
            h.update(b"s" + (v.encode() if isinstance(v, str) else v))
        else:
            a = np.asarray(v)
            h.update(f"{a.dtype.str}{a.shape}".encode() + np.ascontiguousarray(a).tobytes())
        h.update(b"\0")
    return h.digest()


def _dataset_digest(ds, path=None) -> str:
    """SHA-256 of a dataset's dtype, shape, values (read in blocks) and attributes."""
    h = hashlib.sha256()
    h.update(f"{ds.dtype.str}{ds.shape}".encode())
    if ds.shape is None or ds.size == 0:
        pass
    elif ds.ndim == 0:
        h.update(np.ascontiguousarray(ds[()]).tobytes())
    else:
        row = max(1, int(np.prod(ds.shape[1:])) * ds.dtype.itemsize)
        step = max(1, _BLOCK_BYTES // row)
        if ds.chunks:
            step = max(ds.chunks[0], step - step % ds.chunks[0])
        for start in range(0, ds.shape[0], step):
            h.update(np.ascontiguousarray(_read(ds, slice(start, start + step), path)).tobytes())
    h.update(_attrs_bytes(ds))
    return h.hexdigest()


def _read(ds, key, path=None):
    """``ds[key]``, an HDF5 read error (fletcher32 or filter failure) becoming :class:`ChecksumError`."""
    try:
        return ds[key]
    except OSError as exc:
        raise ChecksumError(path if path is not None else ds.file.filename, ds.name, f"chunk not readable ({exc})") from None


def _manifest(f: h5py.File, skip=()) -> dict:
    objects = {"/": hashlib.sha256(_attrs_bytes(f)).hexdigest()}

    def visit(name, obj):
        key = "/" + name
        if isinstance(obj, h5py.Dataset):
            if key not in skip:
                objects[key] = _dataset_digest(obj)
        else:
            objects[key] = hashlib.sha256(_attrs_bytes(obj)).hexdigest()

    f.visititems(visit)
    return objects


def seal(f: h5py.File) -> None:
    """Store the SHA-256 manifest of every dataset (values + attributes), group and the root attributes.

    Call last, just before closing a file opened for writing: anything written after is not covered.
    Generic: every dataset and group present is covered, whatever its name.
    """
    f.flush()
    f.attrs[CHECKSUM_ATTR] = json.dumps({"algorithm": "sha256", "objects": _manifest(f)}, sort_keys=True)


def checked_dataset(group, name: str, data=None, **kw):
    """``group.create_dataset`` with the fletcher32 chunk checksum on (chunked; scalars stay contiguous)."""
    arr = None if data is None else np.asarray(data)
    shape = kw.get("shape", None if arr is None else arr.shape)
    if shape is not None and len(shape) > 0 and int(np.prod(shape)) > 0:
        kw.setdefault("fletcher32", True)
        kw.setdefault("chunks", True)
    return group.create_dataset(name, data=arr, **kw)


def verify(f: h5py.File, path, *, skip=()) -> bool:
    """Check ``f`` against its manifest; return False (and warn) for a file without one.

    ``skip``: dataset paths not hashed here (lazily read big datasets, protected by fletcher32 on
    every chunk read; :func:`verify_file` checks them in full). Raises :class:`ChecksumError` naming
    the first object that does not match, or a dataset/group the manifest does not know.
    """
    raw = f.attrs.get(CHECKSUM_ATTR)
    if raw is None:
        warnings.warn(
            f"{path}: written without checksums (older pito): its content cannot be verified",
            UnverifiedFileWarning,
            stacklevel=3,
        )
        return False
    try:
        stored = json.loads(raw.decode() if isinstance(raw, bytes) else raw)["objects"]
    except (ValueError, KeyError, TypeError) as exc:
        raise ChecksumError(path, CHECKSUM_ATTR, f"manifest unreadable ({exc})") from None
    present = set()

    def collect(name, obj):
        present.add("/" + name)

    f.visititems(collect)
    for key in sorted(present | {"/"}):
        if key not in stored:
            raise ChecksumError(path, key, "not in the checksum manifest (added after writing)")
    for key in sorted(stored):
        if key not in present and key != "/":
            raise ChecksumError(path, key, "listed in the checksum manifest but missing")
    for key, want in sorted(stored.items()):
        if key in skip:
            continue
        obj = f if key == "/" else f[key]
        if isinstance(obj, h5py.Dataset):
            got = _dataset_digest(obj, path)
            what = "values or attributes"
        else:
            got = hashlib.sha256(_attrs_bytes(obj)).hexdigest()
            what = "attributes"
        if got != want:
            raise ChecksumError(path, key, f"{what} differ from the SHA-256 stored at writing")
    return True


def write_header(f: h5py.File, fmt: str, version: int) -> None:
    """Tag an HDF5 file with its pito format name and version."""
    f.attrs["format"] = fmt
    f.attrs["version"] = int(version)
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


class CheckedDataset:
    """A lazily read HDF5 dataset whose read errors (fletcher32 mismatch) name the file and dataset.

    Behaves like the h5py dataset for ``shape``, ``dtype``, ``ndim``, ``size``, ``len`` and
    slicing; a chunk whose fletcher32 checksum fails raises :class:`ChecksumError`.
    """

    def __init__(self, ds, path):
        self._ds, self._path = ds, path
        self.shape, self.dtype, self.ndim, self.size = ds.shape, ds.dtype, ds.ndim, ds.size
        self.name = ds.name

    def __len__(self) -> int:
        return len(self._ds)

    def __getitem__(self, key):
        return _read(self._ds, key, self._path)

    def __array__(self, dtype=None, copy=None):
        a = self[()]
        return a if dtype is None else a.astype(dtype)

    def __getattr__(self, name):
        return getattr(self._ds, name)


def checked_read(ds, path) -> np.ndarray:
    """All of ``ds`` as an array; a chunk checksum failure raises :class:`ChecksumError`."""
    return np.asarray(_read(ds, (), path))

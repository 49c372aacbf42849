"""Provenance: the calibration and patch assembly a file's wrenches were computed with.

Every recording (header ``meta["calibration"]``, ``meta["assembly"]``) and every export
(NWB, MCAP, LSL ``desc``) embeds the same JSON record, so a file always says how its
wrenches were computed:

- :func:`calibration_record` — the calibration file itself (``file``: its exact bytes,
  base64, with their SHA-256: the whole model, correction and covariance included, in whatever
  layout the calibration file has), and for a reader without pito: method, date, content hash,
  the matrix ``(6·F, 36)`` (counts → ``[fx, fy, fz, tx, ty, tz]`` N, N·m per output face, the
  linear part), the offset ``(36,)`` counts, output faces/frame, ``T_core_ati``, the core's
  edge (m) and the fit's metadata.
- :func:`calibration_hash` — ``"sha256:" +`` :func:`pito_core.io.calibration_hash` (the one
  calibration identity of pito: matrix, offset, ``T_core_ati``, method, output frame/faces, core
  edge, correction, metadata). Two files with the same hash compute the same wrenches from the
  same counts (the offset may be replaced by a tare).
- :func:`calibration_from_record` rebuilds the :class:`~pito_core.calibration.Calibration` from
  the embedded file with the calibration file's own reader (so a new file layout is carried
  without a change here), and checks it against the record's hash.
"""

from __future__ import annotations

import base64
import hashlib
import os
import tempfile
from pathlib import Path

import numpy as np

from ..calibration import Calibration, load_calibration
from ..contact import load_assembly
from ..frames import CubeCore
from ..io import FileFormatError, calibration_hash as content_hash

__all__ = [
    "PROVENANCE_VERSION",
    "calibration_hash",
    "calibration_record",
    "calibration_from_record",
    "calibration_file_bytes",
    "calibration_from_bytes",
    "assembly_record",
    "recording_calibration",
    "provenance_meta",
]

#: 2: the record carries the calibration file (``file``); 1: the linear part only (no correction, no covariance).
PROVENANCE_VERSION = 2


def calibration_hash(calibration) -> str:
    """Content hash ``"sha256:<64 hex>"`` of a :class:`~pito_core.calibration.Calibration`.

    The one calibration identity of pito (:func:`pito_core.io.calibration_hash`: matrix, offset
    (counts), ``T_core_ati``, method, output frame and faces, the core's edge (m) and ``meta``),
    prefixed with its algorithm; CLI lines and the app show its first 12 hex digits.
    """
    return "sha256:" + content_hash(calibration)


def calibration_file_bytes(calibration, source=None) -> bytes:
    """The exact bytes of ``calibration``'s file.

    ``source``'s bytes when it names a file holding this very calibration (same content hash),
    else the bytes :meth:`Calibration.save` writes for it now (a calibration fitted in memory).
    """
    if source is not None and os.path.isfile(os.fspath(source)):
        data = Path(os.fspath(source)).read_bytes()
        try:
            if calibration_hash(calibration_from_bytes(data)) == calibration_hash(calibration):
                return data
        except (ValueError, OSError):  # not a calibration file (or not this one): write it afresh
            pass
    with tempfile.TemporaryDirectory(prefix="pito-cal-") as d:
        p = Path(d) / "calibration.pitocal"
        calibration.save(p)
        return p.read_bytes()


def calibration_from_bytes(data: bytes, what: str = "calibration file"):
    """The :class:`~pito_core.calibration.Calibration` in the bytes of a calibration file (its own reader).

    Raises ``ValueError`` (``FileFormatError``) naming ``what`` when the bytes are not a readable calibration file.
    """
    with tempfile.TemporaryDirectory(prefix="pito-cal-") as d:
        p = Path(d) / "calibration.pitocal"
        p.write_bytes(bytes(data))
        try:
            return load_calibration(p)
        except FileFormatError as exc:
            raise FileFormatError(f"{what}: {str(exc).replace(str(p), 'embedded file')}") from None


def calibration_record(calibration, source: str | None = None, *, file_bytes: bytes | None = None) -> dict:
    """JSON-serialisable record of ``calibration`` (see the module docstring); ``source`` e.g. its file name.

    ``file_bytes``: the calibration file's bytes when already read (default: :func:`calibration_file_bytes`).
    """
    data = calibration_file_bytes(calibration, source) if file_bytes is None else bytes(file_bytes)
    return {
        "provenance_version": PROVENANCE_VERSION,
        "method": calibration.method,
        "date": calibration.meta.get("date"),
        "hash": calibration_hash(calibration),
        "source": None if source is None else str(source),
        "model": "poly" if getattr(calibration, "correction", None) is not None else "linear",
        "matrix": np.asarray(calibration.matrix, float).tolist(),
        "matrix_layout": "rows 6k..6k+5 = [fx, fy, fz, tx, ty, tz] (N, N·m) of output_faces[k] from counts − offset"
                         + (" (the linear part: the file holds the polynomial correction too)"
                            if getattr(calibration, "correction", None) is not None else ""),
        "offset": np.asarray(calibration.offset, float).tolist(),
        "output_faces": list(calibration.output_faces),
        "output_frame": calibration.output_frame,
        "T_core_ati": np.asarray(calibration.T_core_ati, float).tolist(),
        "core_edge_m": float(calibration.core.edge),
        "meta": calibration.meta,
        "file": {"encoding": "base64", "sha256": hashlib.sha256(data).hexdigest(), "size_bytes": len(data),
                 "content": base64.b64encode(data).decode("ascii")},
    }


#: Record keys left out where a record is shown in a line or a table (the file, the big arrays).
BULKY_RECORD_KEYS = ("matrix", "offset", "file")


def record_file_bytes(record: dict) -> bytes:
    """The calibration file's bytes embedded in ``record`` (checked against their SHA-256)."""
    f = record.get("file")
    if not isinstance(f, dict) or "content" not in f:
        raise ValueError("calibration record: file: missing (a record written before pito embedded the file)")
    try:
        data = base64.b64decode(f["content"], validate=True)
    except (ValueError, TypeError) as exc:
        raise ValueError(f"calibration record: file: content is not base64 ({exc})") from None
    got = hashlib.sha256(data).hexdigest()
    if f.get("sha256") != got:
        raise ValueError(f"calibration record: file: stored sha256 {f.get('sha256')} does not match its bytes' {got}")
    return data


def calibration_from_record(record: dict):
    """The :class:`~pito_core.calibration.Calibration` of a :func:`calibration_record`.

    From the embedded calibration file (the whole model: correction and covariance too), read
    by the calibration file's own reader; a record of provenance version 1 (no file) gives the
    linear part. Raises ``ValueError`` naming the field when the record is incomplete, its file
    damaged, or its hash or summary does not match the file's content.
    """
    if not isinstance(record, dict):
        raise ValueError(f"calibration record: expected an object, got {type(record).__name__}")
    if "file" in record:
        cal = calibration_from_bytes(record_file_bytes(record), "calibration record: file")
        if record.get("hash") and calibration_hash(cal) != record["hash"]:
            raise ValueError(f"calibration record: hash: stored {record['hash']} does not match its file's content "
                             f"{calibration_hash(cal)}")
        for key, value in (("matrix", cal.matrix), ("offset", cal.offset), ("T_core_ati", cal.T_core_ati)):
            if key in record and not np.array_equal(np.asarray(record[key], float), np.asarray(value, float)):
                raise ValueError(f"calibration record: {key}: differs from the embedded file's (altered record)")
        if "method" in record and record["method"] != cal.method:
            raise ValueError(f"calibration record: method: {record['method']!r}, the embedded file's is {cal.method!r}")
        return cal
    missing = [k for k in ("method", "matrix", "offset", "output_faces", "output_frame", "T_core_ati", "core_edge_m")
               if k not in record]
    if missing:
        raise ValueError(f"calibration record: missing field(s) {missing}")
    cal = Calibration(record["method"], record["matrix"], record["output_faces"], record["output_frame"],
                      record["offset"], CubeCore(record["core_edge_m"]), record["T_core_ati"], meta=record.get("meta"))
    if record.get("hash") and calibration_hash(cal) != record["hash"]:
        raise ValueError(f"calibration record: hash: stored {record['hash']} does not match its content "
                         f"{calibration_hash(cal)} (a record without the calibration file holds the linear part "
                         "only: re-export with --calibration FILE)")
    return cal


def assembly_record(assembly) -> dict | None:
    """JSON record of a patch assembly (name, core edge m, patch name per face 1..6), or None."""
    if assembly is None:
        return None
    if isinstance(assembly, str):
        assembly = load_assembly(assembly)
    return {
        "name": assembly.name,
        "core_edge_m": float(assembly.core.edge),
        "faces": {str(i): getattr(p, "name", str(p)) for i, p in assembly.patches.items()},
        "mass_kg": assembly.mass,
        "center_of_gravity_m": None if assembly.center_of_gravity is None else assembly.center_of_gravity.tolist(),
    }


def recording_calibration(meta: dict, override=None, override_source: str | None = None):
    """The calibration to compute a recording's wrenches with, and a sentence saying which.

    Parameters
    ----------
    meta : dict
        The recording's header metadata (``meta["calibration"]`` if it was recorded with one).
    override : Calibration, optional
        A calibration given by the user (``--calibration F``): used instead of the embedded one.
    override_source : str, optional
        Its file name, for the sentence.

    Returns
    -------
    calibration : Calibration or None
        None: no calibration anywhere (export counts and reference only).
    note : str
    """
    embedded = meta.get("calibration") if isinstance(meta, dict) else None
    if override is not None:
        h = calibration_hash(override)
        if embedded:
            same = embedded.get("hash") == h
            note = (f"recomputed with {override_source or 'the given calibration'} ({override.method}, {h[:19]}…)"
                    + (" — same content as the recording's own" if same else
                       f" instead of the recording's own ({embedded.get('method')}, {str(embedded.get('hash'))[:19]}…)"))
        else:
            note = f"computed with {override_source or 'the given calibration'} ({override.method}, {h[:19]}…); the recording has none"
        return override, note
    if embedded:
        cal = calibration_from_record(embedded)
        return cal, f"computed with the recording's own calibration ({cal.method}, {embedded.get('hash', '')[:19]}…)"
    return None, "no calibration: the recording has none and none was given (counts and reference only)"


def provenance_meta(pipeline, calibration_source: str | None = None) -> dict:
    """Recording header keys ``calibration``/``assembly`` for what ``pipeline`` computes with (empty when neither)."""
    meta = {}
    if getattr(pipeline, "calibration", None) is not None:
        meta["calibration"] = calibration_record(pipeline.calibration, calibration_source)
    if getattr(pipeline, "assembly", None) is not None:
        meta["assembly"] = assembly_record(pipeline.assembly)
    return meta

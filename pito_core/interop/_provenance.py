"""Provenance: the calibration and patch assembly a file's wrenches were computed with.

Every recording (header ``meta["calibration"]``, ``meta["assembly"]``) and every export
(NWB, MCAP, LSL ``desc``) embeds the same JSON record, so a file always says how its
wrenches were computed:

- :func:`calibration_record` — method, date, content hash, the matrix ``(6·F, 36)``
  (counts → ``[fx, fy, fz, tx, ty, tz]`` N, N·m per output face), the offset ``(36,)``
  counts, output faces/frame, ``T_core_ati`` and the core's edge (m), plus the fit's
  metadata. The fit's covariance is not embedded (it stays in the calibration file).
- :func:`calibration_hash` — ``"sha256:" +`` :func:`pito_core.io.calibration_hash` (the one
  calibration identity of pito: matrix, offset, ``T_core_ati``, method, output frame/faces, core
  edge, metadata). Two files with the same hash compute the same wrenches from the same counts
  (the offset may be replaced by a tare).
- :func:`calibration_from_record` rebuilds a :class:`~pito_core.calibration.Calibration`.
"""

from __future__ import annotations

import numpy as np

from ..calibration import Calibration
from ..contact import load_assembly
from ..frames import CubeCore
from ..io import calibration_hash as content_hash

__all__ = [
    "PROVENANCE_VERSION",
    "calibration_hash",
    "calibration_record",
    "calibration_from_record",
    "assembly_record",
    "recording_calibration",
    "provenance_meta",
]

PROVENANCE_VERSION = 1


def calibration_hash(calibration) -> str:
    """Content hash ``"sha256:<64 hex>"`` of a :class:`~pito_core.calibration.Calibration`.

    The one calibration identity of pito (:func:`pito_core.io.calibration_hash`: matrix, offset
    (counts), ``T_core_ati``, method, output frame and faces, the core's edge (m) and ``meta``),
    prefixed with its algorithm; CLI lines and the app show its first 12 hex digits.
    """
    return "sha256:" + content_hash(calibration)


def calibration_record(calibration, source: str | None = None) -> dict:
    """JSON-serialisable record of ``calibration`` (see the module docstring); ``source`` e.g. its file name."""
    return {
        "provenance_version": PROVENANCE_VERSION,
        "method": calibration.method,
        "date": calibration.meta.get("date"),
        "hash": calibration_hash(calibration),
        "source": source,
        "matrix": np.asarray(calibration.matrix, float).tolist(),
        "matrix_layout": "rows 6k..6k+5 = [fx, fy, fz, tx, ty, tz] (N, N·m) of output_faces[k] from counts − offset",
        "offset": np.asarray(calibration.offset, float).tolist(),
        "output_faces": list(calibration.output_faces),
        "output_frame": calibration.output_frame,
        "T_core_ati": np.asarray(calibration.T_core_ati, float).tolist(),
        "core_edge_m": float(calibration.core.edge),
        "meta": calibration.meta,
    }


def calibration_from_record(record: dict):
    """The :class:`~pito_core.calibration.Calibration` of a :func:`calibration_record` (no covariance).

    Raises ``ValueError`` naming the field when the record is incomplete or its hash does not match.
    """
    if not isinstance(record, dict):
        raise ValueError(f"calibration record: expected an object, got {type(record).__name__}")
    missing = [k for k in ("method", "matrix", "offset", "output_faces", "output_frame", "T_core_ati", "core_edge_m")
               if k not in record]
    if missing:
        raise ValueError(f"calibration record: missing field(s) {missing}")
    cal = Calibration(record["method"], record["matrix"], record["output_faces"], record["output_frame"],
                      record["offset"], CubeCore(record["core_edge_m"]), record["T_core_ati"], meta=record.get("meta"))
    if record.get("hash") and calibration_hash(cal) != record["hash"]:
        raise ValueError(f"calibration record: hash: stored {record['hash']} does not match its content "
                         f"{calibration_hash(cal)}")
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

"""NWB export (pynwb): one recording → one ``.nwb`` file (docs/interop.md, "NWB").

Layout (the cube's series share its timestamps: its device clock, s from ``session_start_time``,
strictly increasing, ``ExportData.time``; the reference has its own, on the same clock):

- ``acquisition/pito_raw_counts`` — ``TimeSeries`` (n, 36), unit ``counts``, the 36 gauges.
- ``acquisition/reference_force`` / ``reference_torque`` — ``TimeSeries`` (m, 3), N / N·m,
  every record of the reference sensor at its own time, tared, frame S_A (only with a reference).
- ``acquisition/pito_host_time`` — ``TimeSeries`` (n,), s: when each cube sample reached the
  host (``time.monotonic``; samples arrive in batches), on the cube's timestamps.
- ``processing/behavior/face_{i}_force`` / ``face_{i}_torque`` — ``TimeSeries`` (n, 3),
  N / N·m, ``[x, y, z]`` in face i's own frame (one unit per series).
- ``processing/behavior/contact_face_{i}`` — ``Position`` holding ``SpatialSeries``
  ``point`` (m, ``reference_frame`` = the core frame), plus ``TimeSeries``
  ``contact_face_{i}_normal`` (unit vector), ``_force`` (N), ``_torsion`` (N·m), ``_valid`` (0/1),
  ``_single_contact`` (1: one fingertip can produce the wrench, 0: flagged or no force),
  ``_single_contact_p`` (its p-value, 0..1) and ``_single_contact_reason`` (code, names in the
  description).
- ``processing/misc/calibration_matrix`` — ``DynamicTable``, one row per matrix
  row: ``face``, ``component``, ``unit``, ``coefficients`` (36, N or N·m per count),
  ``offset_counts`` as its own table; ``calibration_file`` (column ``content_base64``, parts in row order; the
  description gives ``content_hash``, ``sha256``, ``size_bytes``): the calibration file's exact bytes, the whole
  model (correction, covariance); the provenance record (method, date, hash, assembly) as JSON
  in the table's description and in ``nwbfile.notes``.

Module names are the NWB schema's own (``behavior``: what the hand did to the object;
``misc``: the calibration), as nwbinspector's ``check_processing_module_name`` asks.
:func:`missing_metadata` names the best-practice metadata (subject, experimenter,
institution) a call leaves out, so ``pito export`` can warn before writing.
"""

from __future__ import annotations

import datetime as _dt
import json

import numpy as np

from ..contact import SingleContactReason
from ..frames import WRENCH_COMPONENTS
from ._conventions import CORE_FRAME, FACE_FRAME
from ._provenance import BULKY_RECORD_KEYS

__all__ = ["write_nwb", "missing_metadata", "KEYWORDS", "BEHAVIOR_MODULE", "MISC_MODULE"]

#: processing modules (NWB schema names): face wrenches and contacts; the calibration
BEHAVIOR_MODULE, MISC_MODULE = "behavior", "misc"
#: ``/general/keywords`` of every export
KEYWORDS = ("PITO", "tactile sensing", "force/torque", "grasp", "contact")

#: Base64 characters per row of the ``calibration_file`` table.
_FILE_CHUNK = 1 << 16


def write_nwb(data, path, *, subject_id: str | None = None, species: str | None = None, sex: str | None = None,
              age: str | None = None,
              experimenter: list[str] | None = None, session_description: str | None = None,
              institution: str | None = None, lab: str | None = None, identifier: str | None = None,
              progress=None) -> None:
    """Write :class:`~pito_core.interop.ExportData` ``data`` to the NWB file ``path``.

    With ``subject_id``, ``species``, ``sex``, ``age``, ``experimenter`` and ``institution``
    given, nwbinspector finds nothing to report (tests/interop/test_nwb.py); see
    :func:`missing_metadata` for what is left out otherwise.
    """
    from pynwb import NWBHDF5IO  # deferred: optional dependency (extra "interop"), over 1 s to load

    def report(f, text):
        if progress is not None:
            progress(float(f), text)

    nwb = _nwb_file(data, experimenter=experimenter, session_description=session_description,
                    institution=institution, lab=lab, identifier=identifier)
    _add_subject(nwb, subject_id=subject_id, species=species, sex=sex, age=age)
    counts = _add_acquisition(nwb, data)
    report(0.75, "nwb: wrenches")
    _add_behavior(nwb, data, _timing(data.time, counts))
    if data.calibration is not None:
        _add_calibration(nwb, data.calibration)
    report(0.85, "nwb: writing")
    with NWBHDF5IO(str(path), "w") as io:
        io.write(nwb)
    report(1.0, "nwb: done")


def _nwb_file(data, *, experimenter, session_description, institution, lab, identifier):
    """The ``NWBFile`` with the session metadata and the provenance record (JSON) as its notes."""
    from pynwb import NWBFile  # deferred: optional dependency (extra "interop"), over 1 s to load

    start = _dt.datetime.fromtimestamp(data.start_unix or 0.0, tz=_dt.timezone.utc)
    prov = {"calibration": None if data.calibration is None else
            {k: v for k, v in data.calibration.items() if k not in BULKY_RECORD_KEYS},
            "assembly": data.assembly, "note": data.note, "simulated": data.simulated,
            "recording_meta": {k: v for k, v in data.meta.items() if k not in ("calibration", "assembly")}}
    desc = session_description or ("PITO grasp recording" + (" (SIMULATED devices)" if data.simulated else ""))
    return NWBFile(
        session_description=desc,
        identifier=identifier or f"pito-{data.calibration['hash'][7:23] if data.calibration else 'raw'}-{int(data.start_unix)}",
        session_start_time=start,
        experimenter=list(experimenter) if experimenter else None,
        institution=institution, lab=lab,
        keywords=list(KEYWORDS),
        experiment_description="Loads on the six faces of the PITO (Patched Intrinsic Tactile Object), a cube of six "
        "6-axis force/torque sensors under surface patches, computed from its gauge counts with a calibration, with "
        "the contact point on each face" + (" (SIMULATED devices)" if data.simulated else ""),
        notes=json.dumps(prov, default=str),
        source_script="pito export (pito_core.interop)",
        source_script_file_name="pito_core/interop/_nwb.py",
    )


def _add_subject(nwb, *, subject_id, species, sex, age) -> None:
    """Check ``sex`` (M, F, U, O) and ``age`` (ISO 8601 duration); a ``Subject`` when any is given."""
    from pynwb.file import Subject  # deferred: optional dependency (extra "interop"), over 1 s to load

    if sex is not None and sex not in ("M", "F", "U", "O"):
        raise ValueError(f"sex: expected one of M, F, U, O (NWB), got {sex!r}")
    if age is not None and not str(age).startswith("P"):
        raise ValueError(f"age: expected an ISO 8601 duration such as 'P30Y', got {age!r}")
    if subject_id or species or sex or age:
        nwb.subject = Subject(subject_id=subject_id, species=species, sex=sex, age=age,
                              description=f"participant {subject_id} handling the PITO object" if subject_id
                              else "participant handling the PITO object")


def _timing(t, link=None) -> dict:
    """TimeSeries timing of sample times ``t`` (s): ``starting_time`` and ``rate`` (Hz) when they are evenly
    spaced (to 1 ns: no dropped sample), else ``timestamps`` (``link``: a series whose timestamps to share)."""
    t = np.asarray(t, float)
    d = np.diff(t)
    if d.size and float(d.max() - d.min()) <= 1e-9:
        return {"starting_time": float(t[0]), "rate": float(np.round(1.0 / d.mean(), 6))}
    return {"timestamps": t if link is None else link}


def _add_acquisition(nwb, data):
    """The raw counts (and the reference's force and torque) as acquisition; returns the counts series."""
    from pynwb import TimeSeries  # deferred: optional dependency (extra "interop"), over 1 s to load

    t = np.asarray(data.time, float)
    counts = TimeSeries(name="pito_raw_counts", data=np.asarray(data.counts, np.int32), unit="counts",
                        **_timing(t), description="PITO cube raw gauge counts, 36 channels (6 per face, face-major)",
                        comments="channel 6(i-1)+g = face i gauge g (1..6)")
    nwb.add_acquisition(counts)
    if data.host_time is not None:
        nwb.add_acquisition(TimeSeries(name="pito_host_time", data=np.asarray(data.host_time, float), unit="s",
                                       **_timing(t, counts), description="host clock (time.monotonic) when each cube "
                                       "sample reached the computer; samples arrive in batches"))
    if np.size(data.reference_time):
        rt = np.asarray(data.reference_time, float)
        first = None
        for name, cols, unit in (("reference_force", slice(0, 3), "N"), ("reference_torque", slice(3, 6), "N*m")):
            ts = TimeSeries(name=name, data=np.asarray(data.reference_wrench[:, cols]), unit=unit,
                            **_timing(rt, first),
                            description=f"reference sensor (ATI Net F/T) {name.split('_')[1]} [x, y, z] in the "
                                        "reference frame S_A, every record at its own time (the cube's clock), tared")
            nwb.add_acquisition(ts)
            first = first or ts
    return counts


def _add_behavior(nwb, data, timing: dict) -> None:
    """The ``behavior`` module: face wrenches and contacts, with the cube's ``timing`` (:func:`_timing`)."""
    from pynwb import TimeSeries  # deferred: optional dependency (extra "interop"), over 1 s to load

    if data.face_wrenches is None and data.contacts is None:
        return
    what = ["face wrenches"] * (data.face_wrenches is not None) + [
        f"one point contact per face on the patch assembly {(data.assembly or {}).get('name')} (NaN where no "
        "contact)"] * (data.contacts is not None)
    mod = nwb.create_processing_module(BEHAVIOR_MODULE, f"PITO {' and '.join(what)}, computed from the "
                                       f"counts: {data.note}")
    if data.face_wrenches is not None:
        for i in range(1, 7):
            w = data.face_wrenches[:, i - 1]
            mod.add(TimeSeries(name=f"face_{i}_force", data=w[:, :3], unit="N", **timing,
                               description=f"force on face {i}, [fx, fy, fz] in {FACE_FRAME.format(i=i)}"))
            mod.add(TimeSeries(name=f"face_{i}_torque", data=w[:, 3:], unit="N*m", **timing,
                               description=f"torque on face {i} about its frame origin, [tx, ty, tz] in {FACE_FRAME.format(i=i)}"))
    if data.contacts is not None:
        for i in range(1, 7):
            _add_contact(mod, data.contacts, i, timing)


def _add_contact(mod, c, i, timing) -> None:
    """Face ``i``'s contact (``ContactEstimate``): point, normal, force, torsion, valid, single-contact test."""
    from pynwb import TimeSeries  # deferred: optional dependency (extra "interop"), over 1 s to load
    from pynwb.behavior import Position, SpatialSeries

    k = i - 1
    pos = Position(name=f"contact_face_{i}")
    pos.add_spatial_series(SpatialSeries(name="point", data=c.point[:, k], **timing, unit="meters",
                                         reference_frame=CORE_FRAME,
                                         description=f"contact point on face {i}'s patch, m, core frame"))
    mod.add(pos)
    mod.add(TimeSeries(name=f"contact_face_{i}_normal", data=c.normal[:, k], unit="1", **timing,
                       description="outward unit normal at the contact point, core frame"))
    mod.add(TimeSeries(name=f"contact_face_{i}_force", data=c.force[:, k], unit="N", **timing,
                       description="finger force [x, y, z] at the contact point, core frame"))
    mod.add(TimeSeries(name=f"contact_face_{i}_torsion", data=c.torsion[:, k], unit="N*m", **timing,
                       description="torsion about the normal"))
    mod.add(TimeSeries(name=f"contact_face_{i}_valid", data=c.valid[:, k].astype(np.uint8), unit="1",
                       **timing, description="1 where the face carries a contact, else 0"))
    if getattr(c, "single_contact", None) is not None:
        _add_single_contact(mod, c, i, timing)


def _add_calibration(nwb, cal: dict) -> None:
    """The ``misc`` module: the calibration matrix (one row per output component) and offset as tables."""
    from hdmf.common import DynamicTable, VectorData  # deferred: optional dependency (extra "interop", with pynwb)

    M = np.asarray(cal["matrix"], float)
    faces = [f for f in cal["output_faces"] for _ in range(6)]
    comps = list(WRENCH_COMPONENTS) * len(cal["output_faces"])
    units = ["N/count" if c[0] == "f" else "N*m/count" for c in comps]
    frame = "own face frame" if cal["output_frame"] == "face" else "reference frame S_A"
    mod = nwb.create_processing_module(MISC_MODULE, f"PITO calibration used ({cal['method']}, {cal['hash']})")
    mod.add(DynamicTable(name="calibration_matrix", description=json.dumps(
        {k: v for k, v in cal.items() if k not in BULKY_RECORD_KEYS}, default=str), columns=[
        VectorData(name="face", description="output face 1..6", data=faces),
        VectorData(name="component", description=f"wrench component, in the face's {frame}", data=comps),
        VectorData(name="unit", description="unit of the coefficients", data=units),
        VectorData(name="coefficients", description="matrix row: wrench component per count of gauges 1..36 "
                   "(applied to counts − offset)", data=M)]))
    mod.add(DynamicTable(name="calibration_offset", description="unloaded counts subtracted before the matrix", columns=[
        VectorData(name="channel", description="gauge channel 1..36", data=list(range(1, 37))),
        VectorData(name="offset_counts", description="counts", data=np.asarray(cal["offset"], float))]))
    f = cal.get("file")
    if f:  # the whole model (correction, covariance): the calibration file's bytes, as embedded in the recording
        text = f["content"]
        size = max(1, min(_FILE_CHUNK, -(-len(text) // 2)))  # at least two rows (a one-row table is a finding)
        parts = [text[k:k + size] for k in range(0, len(text), size)]
        mod.add(DynamicTable(name="calibration_file", description=json.dumps(
            {"what": "the calibration file (pito-calibration, HDF5) the wrenches were computed with: the rows' "
                     "content_base64 joined in order, base64-decoded", "content_hash": cal["hash"],
             "sha256": f["sha256"], "size_bytes": int(f["size_bytes"])}), columns=[
            VectorData(name="content_base64", description="base64 text of the file, in parts (row order)", data=parts)]))


def missing_metadata(*, subject_id=None, species=None, sex=None, age=None, experimenter=None, institution=None) -> list[str]:
    """The NWB best-practice metadata left out of a :func:`write_nwb` call, as ``pito export`` options.

    Returns e.g. ``["--subject-id", "--experimenter"]``; empty when nwbinspector has nothing
    to say about the file's metadata. Without a subject the file has none, which nwbinspector
    reports as CRITICAL ("Subject is missing") for DANDI.
    """
    given = {"--subject-id": subject_id, "--species": species, "--sex": sex, "--age": age,
             "--experimenter": experimenter, "--institution": institution}
    return [name for name, value in given.items() if not value]


def _add_single_contact(mod, c, i, timing) -> None:
    """The single-contact test of face ``i`` (``ContactEstimate.single_contact*``) as three series."""
    from pynwb import TimeSeries  # deferred: optional dependency (extra "interop"), over 1 s to load

    k = i - 1
    names = ", ".join(f"{r.value} {r.name.lower()}" for r in SingleContactReason)
    mod.add(TimeSeries(name=f"contact_face_{i}_single_contact", data=c.single_contact[:, k].astype(np.uint8),
                       unit="1", **timing,
                       description="1 where one fingertip on the patch can produce the face's wrench within its "
                                   "noise, 0 where not (a valid contact with 0 is flagged) or no force"))
    mod.add(TimeSeries(name=f"contact_face_{i}_single_contact_p", data=c.single_contact_p[:, k], unit="1",
                       **timing, description="p-value of the single-contact test (0..1; NaN: no force)"))
    mod.add(TimeSeries(name=f"contact_face_{i}_single_contact_reason", data=c.single_contact_reason[:, k],
                       unit="1", **timing, description=f"why the test fails: {names}"))

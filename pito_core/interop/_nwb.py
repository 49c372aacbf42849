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

__all__ = ["write_nwb", "NwbWriter", "missing_metadata", "KEYWORDS", "BEHAVIOR_MODULE", "MISC_MODULE"]

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
    """Write :class:`~pito_core.interop.ExportData` (or an :class:`~pito_core.interop.ExportStream`) ``data`` to the NWB file ``path``.

    With ``subject_id``, ``species``, ``sex``, ``age``, ``experimenter`` and ``institution``
    given, nwbinspector finds nothing to report (tests/interop/test_nwb.py); see
    :func:`missing_metadata` for what is left out otherwise. A stream is written block by
    block (:class:`NwbWriter`).
    """
    w = NwbWriter(data, path, subject_id=subject_id, species=species, sex=sex, age=age, experimenter=experimenter,
                  session_description=session_description, institution=institution, lab=lab, identifier=identifier)
    for block in data.blocks():
        w.append(block)
    if progress is not None:
        progress(0.85, "nwb: writing")
    w.close()
    if progress is not None:
        progress(1.0, "nwb: done")


class NwbWriter:
    """An NWB file written block by block: its layout first (datasets of the full length), then the rows.

    Parameters
    ----------
    head : ExportData or ExportStream
        Whose ``time`` and ``reference_time`` are the whole recording's (the datasets' lengths
        and timing), and its metadata (calibration, assembly, note).
    path : str or Path
    **metadata
        As :func:`write_nwb`.

    :meth:`append` takes the :class:`~pito_core.interop.ExportData` blocks in order;
    :meth:`close` checks that every row was written.
    """

    def __init__(self, head, path, **metadata):
        self.head, self.path, self.metadata = head, str(path), metadata
        self._file = None
        self._series: list = []
        self._at = {"cube": 0, "reference": 0}
        self._scratch = np.empty(0, np.uint8)

    def append(self, block) -> None:
        if self._file is None:
            self._start(block)
        n, m = self._at["cube"], self._at["reference"]
        k, r = int(np.size(block.time)), int(np.size(block.reference_time))
        for s in self._series:
            lo, count = (n, k) if s.rows == "cube" else (m, r)
            if count:
                self._write(s.dataset, lo, s.values(block))
        self._at["cube"], self._at["reference"] = n + k, m + r

    def _write(self, dataset, lo: int, values) -> None:
        """``values`` into rows ``lo:`` of ``dataset``: through one scratch buffer in the dataset's dtype (a
        block's column of a wider array, bool flags, counts held as float64 integers: one copy, no HDF5
        type conversion), by HDF5's own write (h5py's slicing checks cost more than the copy)."""
        import h5py

        v = np.asarray(values)
        dt = dataset.dtype
        if v.dtype != dt or not v.flags.c_contiguous:
            size = v.size * dt.itemsize
            if self._scratch.size < size:
                self._scratch = np.empty(size, np.uint8)
            buf = self._scratch[:size].view(dt).reshape(v.shape)
            np.copyto(buf, v, casting="unsafe")  # the counts: integers (float64) into int32, exactly
            v = buf
        space = dataset.id.get_space()
        space.select_hyperslab((lo,) + (0,) * (v.ndim - 1), v.shape)
        dataset.id.write(h5py.h5s.create_simple(v.shape), space, v)

    def close(self) -> None:
        if self._file is None:
            raise ValueError(f"{self.path}: no block was written")
        self._file.close()
        want = {"cube": int(np.size(self.head.time)), "reference": int(np.size(self.head.reference_time))}
        if self._at != want:
            raise RuntimeError(f"{self.path}: wrote {self._at} rows, the recording has {want}")

    def _start(self, first) -> None:
        """Write the file's layout (every series at its full length, empty), then open its datasets."""
        import h5py
        from pynwb import NWBHDF5IO  # deferred: optional dependency (extra "interop"), over 1 s to load

        head, md = self.head, self.metadata
        nwb = _nwb_file(head, experimenter=md.get("experimenter"), session_description=md.get("session_description"),
                        institution=md.get("institution"), lab=md.get("lab"), identifier=md.get("identifier"))
        _add_subject(nwb, subject_id=md.get("subject_id"), species=md.get("species"), sex=md.get("sex"),
                     age=md.get("age"))
        self._series = _series(head, first)
        _add_series(nwb, head, self._series, first)
        if head.calibration is not None:
            _add_calibration(nwb, head.calibration)
        with NWBHDF5IO(self.path, "w") as io:
            io.write(nwb)
        self._file = h5py.File(self.path, "r+")
        for s in self._series:
            s.dataset = self._file[s.h5path]


class _Series:
    """One series of the file: where it goes, what it holds, and how to take its rows from a block."""

    def __init__(self, where, name, unit, description, rows, values, dtype, width, kind="ts"):
        self.where, self.name, self.unit, self.description = where, name, unit, description
        self.rows, self.values, self.dtype, self.width, self.kind = rows, values, dtype, width, kind
        self.dataset = None

    @property
    def h5path(self) -> str:
        if self.kind == "point":
            return f"processing/{BEHAVIOR_MODULE}/{self.name}/point/data"
        return f"acquisition/{self.name}/data" if self.where == "acquisition" else \
            f"processing/{BEHAVIOR_MODULE}/{self.name}/data"


def _series(head, first) -> list:
    """Every series of an export whose first block is ``first`` (which of them exist: wrenches, contacts, the test)."""
    ref_desc = ("reference sensor (ATI Net F/T) {} [x, y, z] in the reference frame S_A, every record at its own time "
                "(the cube's clock), tared")
    out = [_Series("acquisition", "pito_raw_counts", "counts", "PITO cube raw gauge counts, 36 channels (6 per face, "
                   "face-major)", "cube", lambda b: b.counts, np.int32, 36)]
    if first.host_time is not None:
        out.append(_Series("acquisition", "pito_host_time", "s", "host clock (time.monotonic) when each cube sample "
                           "reached the computer; samples arrive in batches", "cube", lambda b: b.host_time, float, None))
    if np.size(head.reference_time):
        out += [_Series("acquisition", "reference_force", "N", ref_desc.format("force"), "reference",
                        lambda b: b.reference_wrench[:, :3], float, 3),
                _Series("acquisition", "reference_torque", "N*m", ref_desc.format("torque"), "reference",
                        lambda b: b.reference_wrench[:, 3:], float, 3)]
    if first.face_wrenches is not None:
        for i in range(1, 7):
            out += [_Series("behavior", f"face_{i}_force", "N", f"force on face {i}, [fx, fy, fz] in "
                            f"{FACE_FRAME.format(i=i)}", "cube", lambda b, k=i - 1: b.face_wrenches[:, k, :3], float, 3),
                    _Series("behavior", f"face_{i}_torque", "N*m", f"torque on face {i} about its frame origin, "
                            f"[tx, ty, tz] in {FACE_FRAME.format(i=i)}", "cube",
                            lambda b, k=i - 1: b.face_wrenches[:, k, 3:], float, 3)]
    c = first.contacts
    if c is not None:
        names = ", ".join(f"{r.value} {r.name.lower()}" for r in SingleContactReason)
        for i in range(1, 7):
            k = i - 1
            out += [
                _Series("behavior", f"contact_face_{i}", "meters", f"contact point on face {i}'s patch, m, core frame",
                        "cube", lambda b, k=k: b.contacts.point[:, k], float, 3, kind="point"),
                _Series("behavior", f"contact_face_{i}_normal", "1", "outward unit normal at the contact point, core "
                        "frame", "cube", lambda b, k=k: b.contacts.normal[:, k], float, 3),
                _Series("behavior", f"contact_face_{i}_force", "N", "finger force [x, y, z] at the contact point, core "
                        "frame", "cube", lambda b, k=k: b.contacts.force[:, k], float, 3),
                _Series("behavior", f"contact_face_{i}_torsion", "N*m", "torsion about the normal", "cube",
                        lambda b, k=k: b.contacts.torsion[:, k], float, None),
                _Series("behavior", f"contact_face_{i}_valid", "1", "1 where the face carries a contact, else 0", "cube",
                        lambda b, k=k: b.contacts.valid[:, k], np.uint8, None)]
            if getattr(c, "single_contact", None) is not None:
                out += [
                    _Series("behavior", f"contact_face_{i}_single_contact", "1", "1 where one fingertip on the patch "
                            "can produce the face's wrench within its noise, 0 where not (a valid contact with 0 is "
                            "flagged) or no force", "cube", lambda b, k=k: b.contacts.single_contact[:, k], np.uint8, None),
                    _Series("behavior", f"contact_face_{i}_single_contact_p", "1", "p-value of the single-contact test "
                            "(0..1; NaN: no force)", "cube", lambda b, k=k: b.contacts.single_contact_p[:, k], float, None),
                    _Series("behavior", f"contact_face_{i}_single_contact_reason", "1", f"why the test fails: {names}",
                            "cube", lambda b, k=k: b.contacts.single_contact_reason[:, k],
                            c.single_contact_reason.dtype, None)]
    return out


def _add_series(nwb, head, series: list, first) -> None:
    """Every series in ``nwb``, its data an empty dataset of the full length (filled by :class:`NwbWriter`)."""
    from hdmf.backends.hdf5 import H5DataIO  # deferred: optional dependency (extra "interop", with pynwb)
    from pynwb import TimeSeries
    from pynwb.behavior import Position, SpatialSeries

    n, m = int(np.size(head.time)), int(np.size(head.reference_time))
    timing = {"cube": _timing(head.time), "reference": _timing(head.reference_time)}
    mod = None
    if any(s.where == "behavior" for s in series):
        what = ["face wrenches"] * (first.face_wrenches is not None) + [
            f"one point contact per face on the patch assembly {(head.assembly or {}).get('name')} (NaN where no "
            "contact)"] * (first.contacts is not None)
        mod = nwb.create_processing_module(BEHAVIOR_MODULE, f"PITO {' and '.join(what)}, computed from the "
                                           f"counts: {head.note}")
    for s in series:
        rows = n if s.rows == "cube" else m
        data = H5DataIO(shape=(rows,) if s.width is None else (rows, s.width), dtype=np.dtype(s.dtype))
        if s.kind == "point":
            pos = Position(name=s.name)
            pos.add_spatial_series(SpatialSeries(name="point", data=data, **timing[s.rows], unit=s.unit,
                                                 reference_frame=CORE_FRAME, description=s.description))
            mod.add(pos)
            continue
        extra = {"comments": "channel 6(i-1)+g = face i gauge g (1..6)"} if s.name == "pito_raw_counts" else {}
        ts = TimeSeries(name=s.name, data=data, unit=s.unit, **timing[s.rows], description=s.description, **extra)
        if "timestamps" in timing[s.rows] and not isinstance(timing[s.rows]["timestamps"], TimeSeries):
            timing[s.rows] = {"timestamps": ts}  # the next series of these rows share its timestamps
        if s.where == "acquisition":
            nwb.add_acquisition(ts)
        else:
            mod.add(ts)


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


def _timing(t) -> dict:
    """TimeSeries timing of sample times ``t`` (s): ``starting_time`` and ``rate`` (Hz) when they are evenly
    spaced (to 1 ns: no dropped sample), else ``timestamps``."""
    t = np.asarray(t, float)
    d = np.diff(t)
    if d.size and float(d.max() - d.min()) <= 1e-9:
        return {"starting_time": float(t[0]), "rate": float(np.round(1.0 / d.mean(), 6))}
    return {"timestamps": t}


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

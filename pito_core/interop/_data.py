"""What every export carries: a recording's samples through the one pipeline, with provenance."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..contact import ContactEstimate
from ..io import read_recording
from ..pipeline import Pipeline, RecordingReader, concatenate_bundles, device_time_base, replay_blocks
from ._provenance import assembly_record, calibration_record, recording_calibration

__all__ = ["ExportData", "export_data"]

#: Samples per block when contacts are solved (and progress reported).
BLOCK = 20000


@dataclass
class ExportData:
    """A recording ready to export (cube samples in order, paired reference).

    Attributes
    ----------
    time : ndarray, shape (n,)
        Cube sample times, s: the cube's device clock from its first sample
        (:func:`~pito_core.pipeline.device_time_base`), strictly increasing; a dropped frame is a gap.
    start_unix : float
        UNIX time of ``time == 0`` (the recording's creation time), s.
    tick : ndarray, shape (n,)
        Cube device clock, µs (unwrapped).
    host_time : ndarray, shape (n,)
        When each cube sample reached the host, s (``time.monotonic`` of the recorder; batches).
    counts : ndarray, shape (n, 36)
        Raw gauge counts.
    reference : ndarray, shape (n, 6) or None
        Reference sensor wrench paired with each cube sample, tared, ``[fx, fy, fz, tx, ty, tz]``
        N, N·m in the reference frame S_A; None without a reference.
    reference_time : ndarray, shape (m,)
        Every reference record of the recording, its time on the same base as ``time``, s.
    reference_wrench : ndarray, shape (m, 6)
        Those records, tared as the recording's tare events say, ``[fx, fy, fz, tx, ty, tz]`` N, N·m, frame S_A.
    reference_host_time : ndarray, shape (m,)
        When each record reached the host, s.
    face_wrenches : ndarray, shape (n, 6, 6) or None
        Face i at index i − 1: ``[fx, fy, fz, tx, ty, tz]`` N, N·m in face i's frame; None
        without a calibration.
    contacts : ContactEstimate or None
        Per sample and face (core frame, fields ``(n, 6, …)``): point (m), normal, force (N),
        torsion (N·m), valid, the single-contact test.
    calibration : dict or None
        :func:`~pito_core.interop.calibration_record` of the calibration used.
    assembly : dict or None
        :func:`~pito_core.interop.assembly_record` of the patch assembly.
    note : str
        Which calibration computed the wrenches (``recomputed with ... instead of ...``).
    meta : dict
        The recording's own metadata.
    """

    time: np.ndarray
    start_unix: float
    tick: np.ndarray
    counts: np.ndarray
    reference: np.ndarray | None
    face_wrenches: np.ndarray | None
    contacts: ContactEstimate | None
    calibration: dict | None
    assembly: dict | None
    note: str
    meta: dict = field(default_factory=dict)
    simulated: bool = False
    host_time: np.ndarray | None = None
    reference_time: np.ndarray = field(default_factory=lambda: np.zeros(0))
    reference_wrench: np.ndarray = field(default_factory=lambda: np.zeros((0, 6)))
    reference_host_time: np.ndarray = field(default_factory=lambda: np.zeros(0))

    @property
    def n(self) -> int:
        return int(self.time.size)


def export_data(path, calibration=None, assembly=None, *, calibration_source: str | None = None,
                contacts: bool = True, progress=None, recover: bool = False) -> ExportData:
    """Run recording ``path`` through the pipeline (:func:`pito_core.pipeline.replay_recording`).

    Parameters
    ----------
    path : str or Path
        A pito recording.
    calibration : Calibration, optional
        Recompute with this one instead of the recording's embedded calibration.
    assembly : str or Assembly, optional
        Object for the contacts (default: the recording's ``meta["assembly"]`` name, else ``cube``).
    contacts : bool
        Solve contacts (needs a calibration).
    progress : callable(fraction in [0, 1], text), optional
    """
    def report(f, text):
        if progress is not None:
            progress(float(f), text)

    rec = read_recording(path, recover=recover) if recover else read_recording(path)
    meta = dict(rec.meta)
    cal, note = recording_calibration(meta, calibration, calibration_source)
    if assembly is None:
        assembly = (meta.get("assembly") or {}).get("name") or "cube"
    report(0.05, "pipeline")
    reader = RecordingReader(rec, speed=float("inf"), loop=False)
    pipe = Pipeline(cal, assembly, has_reference=reader.has_reference)
    bundle = concatenate_bundles(list(replay_blocks(reader, pipe)))
    n_rec = reader.cube["time"].size
    if len(bundle) != n_rec or not np.array_equal(bundle.tick, reader.cube["tick"]):
        raise RuntimeError(f"{path}: the pipeline gave {len(bundle)} cube samples of the recording's {n_rec}")
    time, ref_time = device_time_base(reader.cube, reader.reference if reader.has_reference else None)
    W = None if cal is None else np.asarray(bundle.face_wrenches, float)
    cont = None
    if W is not None and contacts and time.size:
        parts = []
        for s in range(0, len(W), BLOCK):
            parts.append(pipe.contacts(W[s:s + BLOCK]))
            report(0.1 + 0.6 * min(1.0, (s + BLOCK) / len(W)), "contacts")
        cont = ContactEstimate.concatenate(parts)
    reference = getattr(bundle, "reference", None)
    if reference is not None and (not pipe.has_reference or np.size(reference) == 0):
        reference = None
    report(0.7, "pipeline done")
    ref = reader.reference
    return ExportData(
        time=time,
        host_time=np.asarray(reader.cube["host_time"], float),
        reference_time=ref_time,
        reference_wrench=_tared_reference(reader) if ref_time.size else np.zeros((0, 6)),
        reference_host_time=np.asarray(ref["host_time"], float) if ref_time.size else np.zeros(0),
        start_unix=float(meta.get("created_unix", 0.0)),
        tick=np.asarray(bundle.tick),
        counts=np.asarray(bundle.counts),
        reference=None if reference is None else np.asarray(reference, float),
        face_wrenches=W,
        contacts=cont,
        calibration=None if cal is None else (meta["calibration"] if calibration is None and meta.get("calibration")
                                              else calibration_record(cal, calibration_source)),
        assembly=assembly_record(pipe.assembly if pipe.assembly is not None else assembly),
        note=note,
        meta=meta,
        simulated=bool(meta.get("simulated", False)),
    )


def _tared_reference(reader) -> np.ndarray:
    """Every reference record of ``reader``'s recording ``(m, 6)``, less the bias of the tare in force at its time.

    The tare in force is the one of the last tare event (``from_tick``) at or before the cube
    sample the record pairs with (the last cube sample not later, by the pairing rule), as the
    pipeline applies it to the paired reference.
    """
    cube, ref = reader.cube, reader.reference
    wrench = np.asarray(ref["wrench"], float)
    events = sorted(reader.events, key=lambda e: int(e["from_tick"]))
    if not events:
        return wrench.copy()
    k = np.clip(np.searchsorted(cube["time"], ref["time"], side="right") - 1, 0, cube["time"].size - 1)
    ticks = np.array([int(e["from_tick"]) for e in events])
    which = np.searchsorted(ticks, cube["tick"][k], side="right") - 1  # -1: before the first tare
    bias = np.vstack([np.zeros(6)] + [np.asarray(e["reference_bias"], float) for e in events])
    return wrench - bias[which + 1]

"""What every export carries: a recording's samples through the one pipeline, with provenance."""

from __future__ import annotations

from dataclasses import dataclass, field
from types import SimpleNamespace

import time as _time

import numpy as np

from ..contact import ContactEstimate
from ..frames import N_GAUGES
from ..io import RecordingChunks
from ..pipeline import Pipeline, concatenate_bundles, device_time_base, recording_samples, replay_blocks
from ._mcap import McapWriter
from ._nwb import NwbWriter
from ._provenance import assembly_record, calibration_record, recording_calibration

__all__ = ["ExportData", "ExportStream", "export_data", "export_files"]

#: Cube samples per export block (contacts solved, files written, progress reported).
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

    def blocks(self):
        """The export as blocks (:class:`ExportStream` gives many; a whole ``ExportData`` is one)."""
        yield self


class ExportStream:
    """A recording ready to export block by block, in bounded memory (a 1-hour recording: ~0.3 GB).

    The recording is read chunk by chunk (:class:`~pito_core.io.RecordingChunks`) and run
    through the one pipeline (:func:`~pito_core.pipeline.replay_blocks`: 1 s blocks, the live
    pairing and tares); :meth:`blocks` yields :class:`ExportData` of about ``block`` cube
    samples each, in order, every cube and every reference sample in exactly one block.
    Parameters as :func:`export_data`.

    Attributes
    ----------
    time : ndarray, shape (n,)
        Every cube sample's time, s (the export's one time base, as ``ExportData.time``).
    reference_time : ndarray, shape (m,)
        Every reference record's time on the same base, s.
    start_unix, calibration, assembly, note, meta, simulated
        As :class:`ExportData`.
    wrenches, contacts : bool
        The blocks carry face wrenches (a calibration) / contacts.
    """

    def __init__(self, path, calibration=None, assembly=None, *, calibration_source: str | None = None,
                 contacts: bool = True, progress=None, recover: bool = False, block: int = BLOCK):
        if not block >= 1:
            raise ValueError(f"block: expected at least 1 sample, got {block!r}")
        self.path, self.block, self.progress = path, int(block), progress
        self._rec = rec = RecordingChunks(path, recover=recover)
        self.meta = meta = dict(rec.meta)
        self._cal, self.note = recording_calibration(meta, calibration, calibration_source)
        if assembly is None:
            assembly = (meta.get("assembly") or {}).get("name") or "cube"
        self._assembly = assembly
        cube, ref = recording_samples(rec)  # the clocks only: counts and wrenches are read per block
        if cube["time"].size == 0:
            raise ValueError("recording: no cube samples")
        cube["counts"] = rec.column("pito", "counts")
        ref["wrench"] = rec.column("netft", "wrench")
        has_ref = ref["time"].size > 0
        self._reader = SimpleNamespace(cube=cube, reference=ref, has_reference=has_ref, events=[
            e for e in rec.events if e.get("type") == "tare" and e.get("from_tick") is not None])
        self.time, self.reference_time = device_time_base(cube, ref if has_ref else None)
        del cube["device_time"], ref["device_time"]  # in the times above; 16 B a sample less to hold
        self.start_unix = float(meta.get("created_unix", 0.0))
        self.simulated = bool(meta.get("simulated", False))
        self.wrenches = self._cal is not None
        self.contacts = bool(contacts) and self.wrenches
        pipe = Pipeline(self._cal, assembly, has_reference=has_ref)  # the assembly as the blocks' pipeline loads it
        self.calibration = None if self._cal is None else (
            meta["calibration"] if calibration is None and meta.get("calibration")
            else calibration_record(self._cal, calibration_source))
        self.assembly = assembly_record(pipe.assembly if pipe.assembly is not None else assembly)

    @property
    def n(self) -> int:
        return int(self.time.size)

    def blocks(self):
        """Yield :class:`ExportData` of consecutive cube samples (and the reference records up to the last one's time)."""
        pipe = Pipeline(self._cal, self._assembly, has_reference=self._reader.has_reference)
        parts, waiting, i0, j0 = [], 0, 0, 0
        for bundle in replay_blocks(self._reader, pipe):
            parts.append(bundle)
            waiting += len(bundle)
            if waiting >= self.block:
                out = self._block(pipe, concatenate_bundles(parts), i0, j0)
                i0, j0, parts, waiting = i0 + out.n, j0 + out.reference_time.size, [], 0
                yield out
        if parts or i0 == 0:
            out = self._block(pipe, concatenate_bundles(parts) if parts else None, i0, j0)
            i0, j0 = i0 + out.n, j0 + out.reference_time.size
            yield out
        if (i0, j0) != (self.n, self.reference_time.size):
            raise RuntimeError(f"{self.path}: the pipeline gave {i0} cube samples of the recording's {self.n} and "
                               f"{j0} reference records of {self.reference_time.size}")

    def _block(self, pipe, bundle, i0: int, j0: int) -> ExportData:
        """The :class:`ExportData` of ``bundle``, cube samples ``i0:``, reference records from ``j0``."""
        cube = self._reader.cube
        k = 0 if bundle is None else len(bundle)
        i1 = i0 + k
        if k and not np.array_equal(bundle.tick, cube["tick"][i0:i1]):
            raise RuntimeError(f"{self.path}: the pipeline's cube samples {i0}..{i1} are not the recording's")
        last = i1 >= self.n
        m = self.reference_time.size
        j1 = m if last else max(j0, int(np.searchsorted(self.reference_time, self.time[i1 - 1], side="right")))
        W = None if not self.wrenches or bundle is None else np.asarray(bundle.face_wrenches, float)
        cont = pipe.contacts(W) if self.contacts and k else None
        reference = None if bundle is None else getattr(bundle, "reference", None)
        if reference is not None and (not pipe.has_reference or np.size(reference) == 0):
            reference = None
        if self.progress is not None:
            self.progress(0.05 + 0.65 * i1 / max(self.n, 1), "pipeline")  # 0.7: as export_data always said
        ref = self._reader.reference
        return ExportData(
            time=self.time[i0:i1], host_time=np.asarray(cube["host_time"][i0:i1], float),
            reference_time=self.reference_time[j0:j1],
            reference_wrench=_tared_reference(self._reader, j0, j1),
            reference_host_time=np.asarray(ref["host_time"][j0:j1], float),
            start_unix=self.start_unix, tick=np.asarray(cube["tick"][i0:i1]),
            counts=np.zeros((0, N_GAUGES)) if bundle is None else np.asarray(bundle.counts),
            reference=None if reference is None else np.asarray(reference, float),
            face_wrenches=W, contacts=cont, calibration=self.calibration, assembly=self.assembly,
            note=self.note, meta=self.meta, simulated=self.simulated)



def export_data(path, calibration=None, assembly=None, *, calibration_source: str | None = None,
                contacts: bool = True, progress=None, recover: bool = False) -> ExportData:
    """Run recording ``path`` through the pipeline (:func:`pito_core.pipeline.replay_recording`), all in memory.

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

    :class:`ExportStream` gives the same in blocks, in bounded memory (long recordings).
    """
    stream = ExportStream(path, calibration, assembly, calibration_source=calibration_source, contacts=contacts,
                          progress=progress, recover=recover)
    parts = list(stream.blocks())

    def cat(name):
        vals = [getattr(b, name) for b in parts]
        return None if any(v is None for v in vals) else np.concatenate(vals)

    out = parts[0]
    for name in ("time", "host_time", "reference_time", "reference_wrench", "reference_host_time", "tick", "counts",
                 "reference", "face_wrenches"):
        setattr(out, name, cat(name))
    if stream.contacts:
        out.contacts = ContactEstimate.concatenate([b.contacts for b in parts if b.contacts is not None])
    return out


def export_files(path, *, nwb=None, mcap=None, calibration=None, assembly=None, calibration_source: str | None = None,
                 contacts: bool = True, recover: bool = False, raw_counts: bool = True, nwb_metadata: dict | None = None,
                 block: int = BLOCK, threads: int = 1, progress=None) -> dict:
    """Export recording ``path`` to NWB and/or MCAP in one streamed pass (bounded memory, any length).

    Parameters
    ----------
    path : str or Path
        A pito recording.
    nwb, mcap : str or Path, optional
        The files to write (at least one).
    calibration, assembly, calibration_source, contacts, recover
        As :func:`export_data`.
    raw_counts : bool
        MCAP ``/pito/raw_counts``.
    nwb_metadata : dict, optional
        Keyword arguments of :func:`~pito_core.interop.write_nwb` (``subject_id``, ``experimenter`` ...).
    block : int
        Cube samples per block (memory ∝ block).
    threads : int
        1: everything in the calling thread (one core). 2: the MCAP chunks are compressed and
        written by a second thread while the pipeline and the NWB writer go on (less wall time,
        the same CPU time and the same files; :class:`McapWriter` ``background``).
    progress : callable(fraction in [0, 1], text), optional

    Returns
    -------
    dict
        ``n`` cube samples, ``m`` reference records, ``note``, ``simulated``, ``wrenches`` and
        ``contacts`` (bool), ``topics`` ``{topic: MCAP messages}``, ``seconds`` spent in
        ``pipeline`` (reading, pairing, calibration, contacts), ``nwb`` and ``mcap`` (writing).
    """
    if nwb is None and mcap is None:
        raise ValueError("export_files: give nwb= and/or mcap=")
    if threads not in (1, 2):
        raise ValueError(f"threads: expected 1 or 2, got {threads!r}")
    t = _time.perf_counter()
    # the files are written as the pipeline goes: its 0.05..0.7 is the whole export's 0.05..0.95
    scaled = None if progress is None else (lambda f, text: progress(0.05 + (f - 0.05) * 0.9 / 0.65, "export"))
    stream = ExportStream(path, calibration, assembly, calibration_source=calibration_source, contacts=contacts,
                          progress=scaled, recover=recover, block=block)
    seconds = {"pipeline": _time.perf_counter() - t, "nwb": 0.0, "mcap": 0.0}
    writers = {}
    if nwb is not None:
        writers["nwb"] = NwbWriter(stream, nwb, **(nwb_metadata or {}))
    if mcap is not None:
        writers["mcap"] = McapWriter(stream, mcap, raw_counts=raw_counts, background=threads >= 2)
    blocks = stream.blocks()
    while True:
        t = _time.perf_counter()
        b = next(blocks, None)
        seconds["pipeline"] += _time.perf_counter() - t
        if b is None:
            break
        for name, w in writers.items():
            t = _time.perf_counter()
            w.append(b)
            seconds[name] += _time.perf_counter() - t
    topics = {}
    for name, w in writers.items():
        t = _time.perf_counter()
        out = w.close()
        seconds[name] += _time.perf_counter() - t
        if name == "mcap":
            topics = out
    want = {"/pito/raw_counts": stream.n if raw_counts else None, "/pito/reference/wrench": stream.reference_time.size}
    lost = {t: (topics.get(t, 0), k) for t, k in want.items() if topics and k and topics.get(t, 0) != k}
    if lost:  # counted at the hand-off: samples in = messages out
        raise RuntimeError(f"{mcap}: messages written / samples of the recording: {lost}")
    if progress is not None:
        progress(1.0, "export: done")
    return {"n": stream.n, "m": int(stream.reference_time.size), "note": stream.note, "simulated": stream.simulated,
            "wrenches": stream.wrenches, "contacts": stream.contacts, "topics": topics,
            "seconds": {k: v for k, v in seconds.items() if k == "pipeline" or k in writers}}


def _tared_reference(reader, j0: int, j1: int) -> np.ndarray:
    """Reference records ``j0:j1`` of ``reader``'s recording ``(j1 - j0, 6)``, less the bias of the tare in force at their time.

    The tare in force is the one of the last tare event (``from_tick``) at or before the cube
    sample the record pairs with (the last cube sample not later, by the pairing rule), as the
    pipeline applies it to the paired reference.
    """
    cube, ref = reader.cube, reader.reference
    wrench = ref["wrench"][j0:j1] if j1 > j0 else np.zeros((0, 6))
    events = sorted(reader.events, key=lambda e: int(e["from_tick"]))
    if not events or j1 <= j0:
        return wrench
    k = np.clip(np.searchsorted(cube["time"], ref["time"][j0:j1], side="right") - 1, 0, cube["time"].size - 1)
    ticks = np.array([int(e["from_tick"]) for e in events])
    which = np.searchsorted(ticks, cube["tick"][k], side="right") - 1  # -1: before the first tare
    bias = np.vstack([np.zeros(6)] + [np.asarray(e["reference_bias"], float) for e in events])
    return wrench - bias[which + 1]

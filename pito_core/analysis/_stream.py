"""A recording's contacts block by block, and a long recording's analysis in bounded memory.

:func:`contact_blocks` runs a recording through the one pipeline as
:func:`~pito_core.interop.export_data` does (the same blocks of the same bundles, the same
count check) but hands the contacts over block by block and keeps nothing else (no counts,
wrenches or covariances for the whole recording).

:func:`analyze_long` analyses a recording of any length in two passes, with the same tables
as the analysis of the whole arrays (:func:`~pito_core.analysis.analyze_contacts`):

1. every block's contacts are written to a temporary folder (``point``, ``normal``,
   ``force``, ``torsion``, ``valid``, ``single_contact``: 492 bytes per sample, on disk), and
   only the contact state (valid, pushing harder than the threshold) is kept in memory,
   14 bytes per sample; the state is debounced and the trials found over the whole recording;
2. the trials are analysed in windows of about :data:`WINDOW` samples read back from the
   folder. A window spans its trials, the figures' margins and, for each face, the whole of
   every contact run that reaches into them (a run's low-pass filtered path depends on all of
   it), so every number is the one the whole arrays give.

The series kept for the figures (:attr:`GraspAnalysis.series`) holds only the samples each
trial's figure draws (``decimated``), its floats as float32 (about 290 B a sample: 0.15 GB for
the 600 trials of an hour).
"""

from __future__ import annotations

import os
import shutil
import tempfile
from types import SimpleNamespace

import numpy as np

from ..contact import ContactEstimate

from ..io import RecordingChunks
from ..interop import assembly_record, recording_calibration
from ..pipeline import Pipeline, device_time_base, recording_samples, replay_blocks
from ._grasp import finite
from ._metrics import phase_rows
from ._segment import AnalysisSettings, trials_from_contacts
from ._series import FIGURE_PAD_S, FIGURE_POINTS, GraspSeries, contact_state, raw_contacts, sample_rate, series_of

__all__ = ["contact_blocks", "analyze_long", "STREAM_SAMPLES", "WINDOW"]

#: Contacts are solved in blocks of this many samples (as ``export_data``).
BLOCK = 20000
#: Seconds of cube samples per block fed to the pipeline: each block also costs the pipeline's
#: live-display work (the latest contacts, one solve), which the analysis does not use.
REPLAY_BLOCK_S = 20.0
#: Recordings with more cube samples than this are analysed by :func:`analyze_long`.
STREAM_SAMPLES = 200_000
#: Samples per window of the second pass (a longer trial is one window of its own).
WINDOW = 100_000

#: The contact fields the analysis reads: name → (shape per sample, dtype).
_FIELDS = {"point": ((6, 3), float), "normal": ((6, 3), float), "force": ((6, 3), float), "torsion": ((6,), float),
           "valid": ((6,), bool), "single_contact": ((6,), bool)}


class RecordingContacts:
    """A recording opened for its contacts: ``time (N,)`` s, ``meta`` (see ``recording_contacts``), ``n``, and
    :meth:`blocks`, the contacts of consecutive samples (core-frame :class:`ContactEstimate`, ``(k, 6, …)``)."""

    def __init__(self, path, calibration=None, assembly=None, *, calibration_source=None, recover=False):
        # Read chunk by chunk (as the export, :class:`~pito_core.interop.ExportStream`): the clocks whole,
        # the counts and reference wrenches from the file block by block, as the replay asks for them.
        rec = RecordingChunks(path, recover=recover)
        meta = dict(rec.meta)
        cal, note = recording_calibration(meta, calibration, calibration_source)
        if cal is None:
            raise ValueError(f"calibration: {path} has none embedded; give one (--calibration FILE)")
        if assembly is None:
            assembly = (meta.get("assembly") or {}).get("name") or "cube"
        self.path = path
        cube, ref = recording_samples(rec)  # the clocks only
        if cube["time"].size == 0:
            raise ValueError("recording: no cube samples")
        has_ref = ref["time"].size > 0
        self.time, _ = device_time_base(cube, ref if has_ref else None)
        for d in (cube, ref):  # what the replay does not read (8 B a sample each)
            for k in ("device_time", "host_time", "seq", "rdt_seq"):
                d.pop(k, None)
        cube["counts"] = rec.column("pito", "counts")
        ref["wrench"] = rec.column("netft", "wrench")
        rec.pito, rec.netft = {}, {}  # its clocks are in cube and ref now; rows are read by position
        self.reader = SimpleNamespace(cube=cube, reference=ref, has_reference=has_ref, events=[
            e for e in rec.events if e.get("type") == "tare" and e.get("from_tick") is not None])
        self.pipe = Pipeline(cal, assembly, has_reference=has_ref)
        self.n = int(cube["time"].size)
        obj = assembly_record(self.pipe.assembly if self.pipe.assembly is not None else assembly) or {}
        mass = meta.get("mass_kg") or obj.get("mass_kg")
        cog = meta.get("cog_m") or obj.get("center_of_gravity_m")
        self.meta = {"source": str(path), "simulated": bool(meta.get("simulated", False)), "note": note,
                     "assembly": obj.get("name"), "mass_kg": mass,
                     "cog_m": None if cog is None else np.asarray(cog, float).tolist()}

    def blocks(self):
        """Yield the contacts of every sample in order, :data:`BLOCK` samples at a time; checks the count.

        The blocks are those of ``export_data`` (rows ``[k·BLOCK, (k+1)·BLOCK)`` of the pipeline's wrenches).
        """
        tick = self.reader.cube["tick"]
        W, T, rows, done = [], [], 0, 0
        for bundle in replay_blocks(self.reader, self.pipe, REPLAY_BLOCK_S):
            W.append(np.asarray(bundle.face_wrenches, float))
            T.append(np.asarray(bundle.tick))
            rows += len(bundle)
            if rows >= BLOCK:
                w, t = np.concatenate(W), np.concatenate(T)
                k = (rows // BLOCK) * BLOCK
                for a in range(0, k, BLOCK):
                    done = self._check(t[a:a + BLOCK], tick, done)
                    yield self.pipe.contacts(w[a:a + BLOCK])
                W, T, rows = [w[k:]], [t[k:]], rows - k
        if rows:
            w, t = np.concatenate(W), np.concatenate(T)
            done = self._check(t, tick, done)
            yield self.pipe.contacts(w)
        if done != self.n:
            raise RuntimeError(f"{self.path}: the pipeline gave {done} cube samples of the recording's {self.n}")

    def _check(self, ticks, tick, done) -> int:
        k = len(ticks)
        if not np.array_equal(ticks, tick[done:done + k]):
            raise RuntimeError(f"{self.path}: the pipeline's cube samples differ from the recording's at {done}")
        return done + k



def contact_blocks(path, calibration=None, assembly=None, **kwargs) -> RecordingContacts:
    """:class:`RecordingContacts` of ``path`` (arguments as :func:`~pito_core.analysis.recording_contacts`)."""
    return RecordingContacts(path, calibration, assembly, **kwargs)


def analyze_long(rc: RecordingContacts, settings: AnalysisSettings, cog, mass, spill_dir=None):
    """``(trials, phase rows, patch rows, figure series)`` of a recording's contacts in bounded memory (module docstring)."""
    s = settings
    time, n = rc.time, rc.n
    if n > 1 and not (np.diff(time) > 0).all():
        raise ValueError("time: expected strictly increasing sample times, s")
    tmp = tempfile.mkdtemp(prefix="pito-analysis-", dir=spill_dir)
    try:
        valid = np.empty((n, 6), bool)
        raw = np.empty((n, 6), bool)
        files = {k: open(os.path.join(tmp, k), "wb") for k in _FIELDS}
        has_single = True
        i = 0
        for c in rc.blocks():
            k = np.shape(c.valid)[0]
            v = np.asarray(c.valid, bool)
            valid[i:i + k] = v
            raw[i:i + k] = raw_contacts(finite(c.force), finite(c.normal), v, s)
            has_single &= c.single_contact is not None
            for name, (shape, dtype) in _FIELDS.items():
                x = getattr(c, name)
                x = np.zeros((k, *shape), dtype) if x is None else np.ascontiguousarray(x, dtype)
                if x.shape != (k, *shape):
                    raise ValueError(f"contacts.{name}: expected shape {(k, *shape)}, got {x.shape}")
                x.tofile(files[name])
            i += k
        for f in files.values():
            f.close()
        on = contact_state(time, raw, valid, s)
        del raw, valid
        trials = trials_from_contacts(time, on, s)
        fs = sample_rate(time)
        phases, patches, picks = [], [], []
        for lo, hi, group in _windows(time, on, trials):
            c = _read_window(tmp, lo, hi, has_single)
            g = series_of(time[lo:hi], c, on[lo:hi], s, cog, fs=fs)
            ph, pa = phase_rows(g, group, s, mass)
            phases += ph
            patches += pa
            for tr in group:
                m = _figure_samples(time, tr)
                picks.append((m, _take(g, m - lo)))
        return trials, phases, patches, _figure_series(time, on, picks, has_single)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def _windows(time, on, trials):
    """Yield ``(lo, hi, trials)``: sample ranges covering groups of consecutive trials (module docstring)."""
    runs = []
    for f in range(6):
        edges = np.flatnonzero(np.diff(np.r_[0, on[:, f].astype(np.int8), 0]))
        runs.append((edges[::2], edges[1::2]))
    group, lo, hi = [], None, None
    for tr in trials:
        a, b = _span(time, tr)
        for starts, stops in runs:  # whole runs at both ends
            for x in (a, b - 1):
                j = int(np.searchsorted(starts, x, "right")) - 1
                if j >= 0 and stops[j] > x:
                    a, b = min(a, int(starts[j])), max(b, int(stops[j]))
        if group and max(hi, b) - min(lo, a) > WINDOW:
            yield lo, hi, group
            group = []
        lo, hi = (a, b) if not group else (min(lo, a), max(hi, b))
        group.append(tr)
    if group:
        yield lo, hi, group


def _span(time, tr):
    """Sample range ``[a, b)`` of a trial and its figure's margins."""
    return (int(np.searchsorted(time, tr.start - FIGURE_PAD_S, "left")), int(np.searchsorted(time, tr.stop + FIGURE_PAD_S, "right")))


def _figure_samples(time, tr):
    """The sample indices a trial's figure draws (as :class:`._figures._TrialCanvas` picks them)."""
    a, b = _span(time, tr)
    m = np.arange(a, b)
    return m[:: max(1, m.size // FIGURE_POINTS)]


def _read_window(tmp, lo, hi, has_single) -> ContactEstimate:
    out = {}
    for name, (shape, dtype) in _FIELDS.items():
        per = int(np.prod(shape))
        item = np.dtype(dtype).itemsize
        x = np.fromfile(os.path.join(tmp, name), dtype, count=(hi - lo) * per, offset=lo * per * item)
        out[name] = x.reshape((hi - lo, *shape))
    if not has_single:
        out["single_contact"] = None
    return ContactEstimate(frame="core", **out)


_SERIES = ("on", "f_n", "f_t", "f_manip", "f_int", "net_force", "net_moment", "path", "single")


def _take(g: GraspSeries, idx):
    """The figure's samples ``idx`` of ``g``; floats as float32 (a figure draws a few hundred pixels; half the memory)."""
    out = {}
    for k in _SERIES:
        x = getattr(g, k)
        out[k] = None if x is None else x[idx].astype(np.float32) if x.dtype.kind == "f" else x[idx]
    return out


def _figure_series(time, on, picks, has_single) -> GraspSeries:
    """One :class:`GraspSeries` of the figures' samples of every trial (in order, each sample once)."""
    if not picks:
        e = np.zeros((0, 6))
        return GraspSeries(time[:0], on[:0], e, e, np.zeros((0, 6, 3)), np.zeros((0, 6, 3)), np.zeros((0, 3)),
                           np.zeros((0, 3)), np.zeros((0, 6, 3)), np.zeros((0, 6), bool) if has_single else None,
                           decimated=True)
    idx = np.concatenate([m for m, _ in picks])
    keep = np.unique(idx, return_index=True)[1]
    pos = np.cumsum([0] + [m.size for m, _ in picks])
    cat = {}
    for k in _SERIES:  # one field at a time, each trial's part released once copied: no second copy of all
        if picks[0][1][k] is None:
            continue
        first = picks[0][1][k]
        full = np.empty((int(pos[-1]), *first.shape[1:]), first.dtype)
        for (_, p), a in zip(picks, pos[:-1]):
            x = p.pop(k)
            full[a:a + x.shape[0]] = x
        cat[k] = full[keep]
        del full
    return GraspSeries(time[idx[keep]], cat["on"], cat["f_n"], cat["f_t"], cat["f_manip"], cat["f_int"],
                       cat["net_force"], cat["net_moment"], cat["path"], cat.get("single"), decimated=True)

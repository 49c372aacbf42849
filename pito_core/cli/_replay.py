"""``pito replay FILE``: replay a recording at real speed or faster; export it."""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np

from ..calibration import load_calibration
from ..devices import STATUS_SATURATION
from ..interop import ExportStream, recording_calibration
from ..io import Recording, RecordingChunks, export_recording_files
from ..pipeline import Pipeline, RecordingReader, recording_times

HELP = """\
Replay a pito recording (written by `pito record`), print its content, or export it.

Without options the recording is replayed at real speed (--speed 2 is twice as fast,
--speed inf as fast as possible, read block by block in bounded memory) through the same
pipeline as the live view (the reference paired to the cube samples by the device clocks,
the recorded tare applied), printing each
second of recording: cube samples, and the paired reference's mean force magnitude (N);
with --calibration FILE also the largest force on each face (N). --csv PREFIX writes PREFIX_pito.csv
(time s, host_time s, seq, time_us µs, counts_1..36) and PREFIX_ati.csv (time s, host_time s,
rdt_seq, ft_seq, status, fx fy fz N, tx ty tz N·m); `time` is the one time base of every
export: the cube's device clock, unwrapped, from the first sample, strictly increasing; --mat FILE writes a MATLAB file (variables
listed in docs/devices.md). A recording whose recorder was killed is incomplete: add
--recover to read every intact chunk.
"""


def register(sub) -> None:
    p = sub.add_parser("replay", help="replay or export a recording", description=HELP,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("file", metavar="FILE", help="recording file")
    p.add_argument("--speed", type=float, default=1.0, help="replay speed, 1 = real time, inf = no pause (default 1)")
    p.add_argument("--calibration", metavar="FILE", help="calibration file: print the face forces too "
                   "(default: the one embedded in the recording, if any; a given file recomputes and says so)")
    p.add_argument("--recover", action="store_true", help="read an incomplete (killed) recording's intact part")
    p.add_argument("--info", action="store_true", help="print the summary only, no replay")
    p.add_argument("--csv", metavar="PREFIX", help="export to PREFIX_pito.csv and PREFIX_ati.csv (no replay)")
    p.add_argument("--mat", metavar="FILE", help="export to a MATLAB .mat file (no replay)")
    p.set_defaults(func=run)


def _summary(rec: RecordingChunks) -> str:
    p, a = rec.pito, rec.netft
    lasts = [x["host_time"][[0, -1]] for x in (p, a) if x["host_time"].size]
    duration = max(x[1] for x in lasts) - min(x[0] for x in lasts) if lasts else 0.0
    lines = [f"Recording({str(rec.path)!r}, pito={rec.n_pito}, netft={rec.n_netft}, duration={duration:.3f} s, "
             f"complete={rec.complete})"]
    if rec.simulated:
        lines.append(f"simulated data: {rec.meta.get('source') or 'yes'}")
    if rec.n_pito:
        gaps = (np.diff(p["seq"].astype(np.int64)) % 2**32) - 1
        lines.append(f"cube: {rec.n_pito} samples, {int(gaps[(gaps > 0) & (gaps < 2**31)].sum())} missing from the sequence")
    if rec.n_netft:
        sat = int(((a["status"] & STATUS_SATURATION) != 0).sum())
        lines.append(f"reference: {rec.n_netft} samples, {sat} with saturation status")
    if not rec.complete:
        lines.append(f"incomplete recording: {rec.damaged_bytes} bytes after the last intact chunk ignored")
    return "\n".join(lines)


#: The columns the summary and the exports' time base read whole; counts and wrenches stay in the file.
_KEEP = {"pito": ("seq", "time_us", "host_time"), "netft": ("rdt_seq", "host_time", "status")}


def run(args) -> int:
    if not args.speed > 0:
        raise ValueError(f"--speed: expected > 0, got {args.speed}")
    chunks = RecordingChunks(args.file, recover=args.recover, keep=_KEEP)  # bounded memory at any length
    print(_summary(chunks))
    if args.csv or args.mat:
        for written in export_recording_files(chunks, args.csv, args.mat, recording_times(chunks)):
            print(f"wrote {written}")
        return 0
    if args.info:
        return 0
    calibration = None
    if args.calibration:
        calibration = load_calibration(args.calibration)
    if np.isinf(args.speed):  # as fast as possible: block by block, bounded memory (an hour: < 1 GB)
        _replay_blocks(args, calibration)
        print("replay done")
        return 0
    rec = Recording(args.file, recover=args.recover)
    if calibration is not None or rec.meta.get("calibration"):  # provenance (docs/interop.md): say which one
        calibration, note = recording_calibration(rec.meta, calibration, args.calibration)
        print(note)
    reader = RecordingReader(rec, speed=args.speed, loop=False)
    pipe = Pipeline(calibration, has_reference=reader.has_reference)
    t_next, n, force, faces = 1.0, 0, [], []
    for b, pos, done in _bundles(reader, pipe, args.speed):
        n += len(b)
        if len(b):
            ok = np.isfinite(b.reference).all(axis=1)
            if ok.any():
                force.append(np.linalg.norm(b.reference[ok, :3], axis=1))
            if b.face_wrenches is not None:
                faces.append(np.nanmax(np.linalg.norm(b.face_wrenches[:, :, :3], axis=2), axis=0))
        if pos >= t_next - 1e-9 or (done and n):
            _second(pos, n, force, faces)
            t_next, n, force, faces = t_next + 1.0, 0, [], []
    print("replay done")
    return 0


def _second(pos: float, n: int, force: list, faces: list) -> None:
    """One line of the replay: a second of recording, its cube samples and forces (N)."""
    f = f", mean |F| {np.concatenate(force).mean():.3f} N" if force else ""
    if faces:
        f += "; max face |F| " + " ".join(f"{x:.2f}" for x in np.nanmax(faces, axis=0)) + " N"
    print(f"{pos:7.1f} s  cube {n} samples{f}", file=sys.stderr, flush=True)


def _replay_blocks(args, calibration) -> None:
    """``--speed inf``: the recording through the pipeline in blocks (:class:`~pito_core.interop.ExportStream`,
    no contacts), one line per second of the cube's device clock."""
    stream = ExportStream(args.file, calibration, calibration_source=args.calibration, contacts=False,
                          recover=args.recover)
    if stream.wrenches:
        print(stream.note)
    t_next, n, force, faces, pos = 1.0, 0, [], [], 0.0
    for d in stream.blocks():
        t, i = d.time, 0
        while i < t.size:
            j = int(np.searchsorted(t, t_next - 1e-9, side="left"))
            if j > i:
                n += j - i
                if d.reference is not None:
                    r = d.reference[i:j]
                    ok = np.isfinite(r).all(axis=1)
                    if ok.any():
                        force.append(np.linalg.norm(r[ok, :3], axis=1))
                if d.face_wrenches is not None:
                    faces.append(np.nanmax(np.linalg.norm(d.face_wrenches[i:j, :, :3], axis=2), axis=0))
                pos = float(t[j - 1])
            if j >= t.size:
                break
            _second(t_next, n, force, faces)
            n, force, faces = 0, [], []
            t_next = max(t_next + 1.0, np.floor(t[j]) + 1.0)
            i = j
    if n:
        _second(pos, n, force, faces)


def _bundles(reader, pipe, speed: float):
    """``(bundle, position s, last)`` of a paced replay at a finite ``speed`` (position on the recording's host clock)."""
    while True:
        samples = reader.read()
        done = reader.finished
        yield pipe.feed(samples, flush=done), reader.stats()["position"], done
        if done:
            return
        time.sleep(0.02)

"""``pito replay FILE``: replay a recording at real speed or faster; export it."""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np

from ..calibration import load_calibration
from ..devices import STATUS_SATURATION
from ..interop import recording_calibration
from ..io import Recording, export_recording_files
from ..pipeline import Pipeline, RecordingReader, recording_times, replay_blocks

HELP = """\
Replay a pito recording (written by `pito record`), print its content, or export it.

Without options the recording is replayed at real speed (--speed 2 is twice as fast,
--speed inf as fast as possible) through the same pipeline as the live view (the reference
paired to the cube samples by the device clocks, the recorded tare applied), printing each
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


def _summary(rec) -> str:
    lines = [repr(rec)]
    if rec.simulated:
        lines.append(f"simulated data: {rec.meta.get('source') or 'yes'}")
    p = rec.pito
    if p.size:
        gaps = (np.diff(p["seq"].astype(np.int64)) % 2**32) - 1
        lines.append(f"cube: {p.size} samples, {int(gaps[(gaps > 0) & (gaps < 2**31)].sum())} missing from the sequence")
    a = rec.netft
    if a.size:
        sat = int(((a["status"] & STATUS_SATURATION) != 0).sum())
        lines.append(f"reference: {a.size} samples, {sat} with saturation status")
    if not rec.complete:
        lines.append(f"incomplete recording: {rec.damaged_bytes} bytes after the last intact chunk ignored")
    return "\n".join(lines)


def run(args) -> int:
    if not args.speed > 0:
        raise ValueError(f"--speed: expected > 0, got {args.speed}")
    rec = Recording(args.file, recover=args.recover)
    print(_summary(rec))
    if args.csv or args.mat:
        for written in export_recording_files(rec, args.csv, args.mat, recording_times(rec)):
            print(f"wrote {written}")
        return 0
    if args.info:
        return 0
    calibration = None
    if args.calibration:
        calibration = load_calibration(args.calibration)
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
            f = f", mean |F| {np.concatenate(force).mean():.3f} N" if force else ""
            if faces:
                f += "; max face |F| " + " ".join(f"{x:.2f}" for x in np.nanmax(faces, axis=0)) + " N"
            print(f"{pos:7.1f} s  cube {n} samples{f}", file=sys.stderr, flush=True)
            t_next, n, force, faces = t_next + 1.0, 0, [], []
    print("replay done")
    return 0


def _bundles(reader, pipe, speed: float):
    """``(bundle, position s, last)`` of the replay: paced reads at a finite ``speed`` (position on the
    recording's host clock), else one second of samples at a time (position on the cube's device clock),
    so the pipeline's reference history always covers what it pairs."""
    if np.isinf(speed):
        tick0 = int(reader.cube["tick"][0])
        blocks = replay_blocks(reader, pipe)
        b = next(blocks)
        for nxt in blocks:
            yield b, (int(b.tick[-1]) - tick0) * 1e-6 if len(b) else 0.0, False
            b = nxt
        yield b, (int(reader.cube["tick"][-1]) - tick0) * 1e-6, True
        return
    while True:
        samples = reader.read()
        done = reader.finished
        yield pipe.feed(samples, flush=done), reader.stats()["position"], done
        if done:
            return
        time.sleep(0.02)

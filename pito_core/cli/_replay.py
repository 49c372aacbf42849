"""``pito replay FILE``: replay a recording at real speed or faster; export it."""

from __future__ import annotations

import argparse
import sys

import numpy as np

HELP = """\
Replay a pito recording (written by `pito record`), print its content, or export it.

Without options the recording is replayed at real speed (--speed 2 is twice as fast,
--speed inf as fast as possible), printing each second of recording: cube samples and
rate, and the reference's mean force magnitude (N). --csv PREFIX writes PREFIX_pito.csv
(host_time s, seq, time_us µs, counts_1..36) and PREFIX_ati.csv (host_time s, rdt_seq,
ft_seq, status, fx fy fz N, tx ty tz N·m); --mat FILE writes a MATLAB file (variables
listed in docs/devices.md). A recording whose recorder was killed is incomplete: add
--recover to read every intact chunk.
"""


def register(sub) -> None:
    p = sub.add_parser("replay", help="replay or export a recording", description=HELP,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("file", metavar="FILE", help="recording file")
    p.add_argument("--speed", type=float, default=1.0, help="replay speed, 1 = real time, inf = no pause (default 1)")
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
        from ..devices import STATUS_SATURATION

        sat = int(((a["status"] & STATUS_SATURATION) != 0).sum())
        lines.append(f"reference: {a.size} samples, {sat} with saturation status")
    if not rec.complete:
        lines.append(f"incomplete recording: {rec.damaged_bytes} bytes after the last intact chunk ignored")
    return "\n".join(lines)


def run(args) -> int:
    from ..io import Recording, export_recording_csv, export_recording_mat

    if not args.speed > 0:
        raise ValueError(f"--speed: expected > 0, got {args.speed}")
    rec = Recording(args.file, recover=args.recover)
    print(_summary(rec))
    if args.csv or args.mat:
        if args.csv:
            export_recording_csv(rec, f"{args.csv}_pito.csv", "pito")
            export_recording_csv(rec, f"{args.csv}_ati.csv", "netft")
            print(f"wrote {args.csv}_pito.csv and {args.csv}_ati.csv")
        if args.mat:
            export_recording_mat(rec, args.mat)
            print(f"wrote {args.mat}")
        return 0
    if args.info:
        return 0
    second, n_p, n_a, force = 1.0, 0, 0, []
    for batch in rec.replay(speed=args.speed, step=0.05):
        n_p += batch.pito.size
        n_a += batch.netft.size
        if batch.netft.size:
            force.append(np.linalg.norm(batch.netft["wrench"][:, :3], axis=1))
        if batch.t >= second - 1e-9:
            f = f", mean |F| {np.concatenate(force).mean():.3f} N" if force else ""
            print(f"{batch.t:7.1f} s  cube {n_p} samples, reference {n_a} samples{f}", file=sys.stderr, flush=True)
            second, n_p, n_a, force = second + 1.0, 0, 0, []
    print("replay done")
    return 0

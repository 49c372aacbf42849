"""Counts at every hand-off and peak memory of exporting an hour-long recording.

An hour of SIMULATED data made from a recording ``pito record`` wrote (``--minute``, e.g. one
minute of ``pito record --pito sim --ati sim --calibration F``): its rows repeated with both
device clocks, the sequences and the host times continued, so the hour is one unbroken
recording (the minute's header, with its embedded calibration, is kept; ``simulated``
stays true). Then, each in its own process: ``pito export --csv --mat --nwb --mcap
--no-contacts`` and the read-back of every output, printing the samples at each hand-off
(recording → CSV, MAT, NWB, MCAP) and the export's peak resident memory (``ru_maxrss`` of
the child, MiB) and wall time. Usage::

    python scripts/bench_hour_export.py --minute rec.pitorec [--minutes 60] [--dir /tmp/pito-hour]
"""

from __future__ import annotations

import argparse
import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from pito_core.io import RecordingWriter, read_recording


def make_hour(minute: Path, out: Path, minutes: int) -> tuple[int, int]:
    """Write ``minutes`` copies of ``minute``'s rows as one recording; returns (cube rows, reference rows)."""
    rec = read_recording(minute)
    p, a = rec.pito, rec.netft
    span_us = int((np.diff(p["time_us"].astype(np.int64)) % 2**32).sum()) + 1000  # one period after the last
    span_s = float(p["host_time"][-1] - p["host_time"][0]) + 1e-3
    span_ref = int((np.diff(a["rdt_seq"].astype(np.int64)) % 2**32).sum()) + 1
    span_seq = int((np.diff(p["seq"].astype(np.int64)) % 2**32).sum()) + 1
    meta = dict(rec.meta)
    meta["source"] = f"{meta.get('source')}; {minutes} copies of {minute.name} end to end (scripts/bench_hour_export.py)"
    with RecordingWriter(out, meta, flush_interval=1.0, fsync=False) as w:
        for k in range(minutes):
            w.append_pito((p["seq"].astype(np.int64) + k * span_seq) % 2**32,
                          (p["time_us"].astype(np.int64) + k * span_us) % 2**32,
                          p["host_time"] + k * span_s, p["counts"])
            w.append_netft((a["rdt_seq"].astype(np.int64) + k * span_ref) % 2**32, a["ft_seq"], a["status"],
                           a["host_time"] + k * span_s, a["wrench"])
            w.flush()
    return p.size * minutes, a.size * minutes


def timed(cmd: list[str]) -> tuple[float, float]:
    """Run ``cmd``; (wall s, peak RSS MiB of the child)."""
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
    return time.perf_counter() - t0, resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024.0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--minute", type=Path, required=True, help="a recording written by pito record")
    ap.add_argument("--minutes", type=int, default=60)
    ap.add_argument("--dir", type=Path, default=Path("/tmp/pito-hour"))
    args = ap.parse_args()
    args.dir.mkdir(parents=True, exist_ok=True)
    rec = args.dir / "hour.pitorec"
    n, m = make_hour(args.minute, rec, args.minutes)
    pito = [sys.executable, "-c", "import sys; from pito_core.cli import main; sys.exit(main())"]
    wall, rss = timed(pito + ["export", str(rec), "--csv", str(args.dir / "hour"), "--mat", str(args.dir / "hour.mat"),
                              "--nwb", str(args.dir / "hour.nwb"), "--mcap", str(args.dir / "hour.mcap"),
                              "--no-contacts", "--subject-id", "S", "--species", "Homo sapiens", "--sex", "U",
                              "--age", "P30Y", "--experimenter", "X", "--institution", "X"])
    counts = {"recording": (n, m)}
    from pito_core.io import read_recording_csv

    counts["csv"] = (read_recording_csv(args.dir / "hour_pito.csv")["time"].size,
                     read_recording_csv(args.dir / "hour_ati.csv", "netft")["time"].size)
    from scipy.io import loadmat

    mat = loadmat(args.dir / "hour.mat", variable_names=["pito_time", "ati_time"])
    counts["mat"] = (mat["pito_time"].size, mat["ati_time"].size)
    import pynwb

    with pynwb.NWBHDF5IO(str(args.dir / "hour.nwb"), "r") as io:
        f = io.read()
        counts["nwb"] = (f.acquisition["pito_raw_counts"].data.shape[0], f.acquisition["reference_force"].data.shape[0])
    from mcap.reader import make_reader

    with open(args.dir / "hour.mcap", "rb") as fh:
        s = make_reader(fh).get_summary()
    topic = {c.id: c.topic for c in s.channels.values()}
    by = {topic[k]: v for k, v in s.statistics.channel_message_counts.items()}
    counts["mcap"] = (by.get("/pito/raw_counts", 0), by.get("/pito/reference/wrench", 0))
    print(f"{args.minutes} min recording: {n} cube samples, {m} reference samples (SIMULATED)")
    for what, (c, r) in counts.items():
        print(f"  {what:<10} cube {c:>9}  reference {r:>9}  {'ok' if (c, r) == (n, m) else 'LOST'}")
    print(f"  export (csv, mat, nwb, mcap; no contacts): {wall:.0f} s wall, peak RSS {rss:.0f} MiB")


if __name__ == "__main__":
    main()

"""Throughput and memory of a study: ``pito analyze`` in process vs Dask with 1 and 2 workers.

SIMULATED recordings (``pito_core.sim.LiftTask``, 1 kHz, ideal calibration embedded) are
written into a scratch folder, then analysed (tables and figures) three ways; the table
printed gives samples/s of compute (first task to last result), the wall time with the local
cluster's start, the CPU time per sample of the tasks (independent of other load on the
machine), the peak resident memory of the process that ran the tasks (each Dask worker's own
peak) and the 1-minute load average at the end. Usage::

    python scripts/bench_study.py [--recordings 6] [--trials 10] [--many 100] [--dir /tmp/pito-bench-study]

``--many N`` also times N one-trial recordings (6 s each) on 2 workers: the per-task cost at
the scale of a study.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import time
from pathlib import Path

import numpy as np

from pito_core.analysis import analyze_to_dir, peak_rss_mib, run_serial, run_study
from pito_core.calibration import Calibration
from pito_core.interop import assembly_record, calibration_record
from pito_core.sim import LiftTask, VirtualCube, write_lift_recording


def make(directory: Path, n: int, trials: int) -> list[Path]:
    cube = VirtualCube()
    cal = Calibration("ideal", cube.ideal_calibration(), range(1, 7), "face", cube.offset, cube.core, np.eye(4),
                      meta={"simulated": True})
    meta = {"calibration": calibration_record(cal, "ideal"), "assembly": assembly_record("cube")}
    directory.mkdir(parents=True, exist_ok=True)
    out = []
    for k in range(n):
        p = directory / f"rec{k:03d}.pitorec"
        if not p.exists():
            write_lift_recording(p, LiftTask(trials, seed=k), cube, seed=k, meta=meta)
        out.append(p)
    return out


def row(name, res, wall, out):
    """One line of the table; samples from the outputs' summary.json (a task Dask ran twice reports "skipped")."""
    done = [json.loads(p.read_text()) for p in Path(out).glob("*/summary.json")]
    samples = sum(d["n_samples"] for d in done)
    rss = max((r.get("max_rss_MiB") or 0) for r in res.results) if res.results else float("nan")
    per = res.compute_seconds / max(len(done), 1)
    cpu = sum(r.get("cpu_seconds") or 0 for r in res.results)
    counted = sum(r.get("samples") or 0 for r in res.results)
    load = os.getloadavg()[0]
    return (f"{name:<22} {len(done):>4} {samples:>9} {res.compute_seconds:>8.1f} {wall:>7.1f} "
            f"{samples / res.compute_seconds:>10.0f} {per:>7.2f} {1e6 * cpu / max(counted, 1):>9.1f} {rss:>8.0f} "
            f"{load:>5.1f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--recordings", type=int, default=6)
    ap.add_argument("--trials", type=int, default=10, help="trials per recording (6 s each)")
    ap.add_argument("--many", type=int, default=0)
    ap.add_argument("--dir", default="/tmp/pito-bench-study")
    ap.add_argument("--repeat", type=int, default=1, help="run the three paths this many times, interleaved")
    args = ap.parse_args()
    d = Path(args.dir)
    recs = make(d / "recs", args.recordings, args.trials)
    print("SIMULATED recordings; analyse = tables + figures; samples/s over compute time")
    print(f"{'path':<22} {'recs':>4} {'samples':>9} {'compute':>8} {'wall':>7} {'samples/s':>10} {'s/rec':>7} "
          f"{'CPU µs/smp':>9} {'peak MiB':>8} {'load':>5}")
    for name, kw in (("in process", None), ("Dask, 1 worker", 1), ("Dask, 2 workers", 2)) * args.repeat:
        out = d / f"out-{kw}"
        shutil.rmtree(out, ignore_errors=True)
        t0 = time.perf_counter()
        if kw is None:
            res = run_serial(analyze_to_dir, recs, out_root=out)
            for r in res.results:
                r["max_rss_MiB"] = peak_rss_mib()
        else:
            res = run_study(analyze_to_dir, recs, n_workers=kw, out_root=out)
        print(row(name, res, time.perf_counter() - t0, out), flush=True)
    if args.many:
        many = make(d / "many", args.many, 1)
        out = d / "out-many"
        shutil.rmtree(out, ignore_errors=True)
        t0 = time.perf_counter()
        res = run_study(analyze_to_dir, many, n_workers=2, out_root=out)
        print(row(f"{args.many} x 6 s, 2 workers", res, time.perf_counter() - t0, out), flush=True)
        t0 = time.perf_counter()
        again = run_study(analyze_to_dir, many, n_workers=2, out_root=out)
        print(f"rerun of the {args.many} (all skipped): wall {time.perf_counter() - t0:.1f} s, "
              f"{sum(r['status'] == 'skipped' for r in again.results)} skipped")


if __name__ == "__main__":
    main()

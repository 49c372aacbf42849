"""``pito bench [--quick] [--json] [--out DIR]``, added to ``pito`` through the ``pito.commands`` entry point."""

from __future__ import annotations

import argparse
import json
import os
import sys

from pito_bench import SECTIONS, run_bench

from ._export import EXPORT_HELP, export_tables, run_export
from ._report import format_report, write_plots
from ._run import json_safe
from ._sensors import ENV as DATASETS_ENV, SENSORS_HELP, run_sensors, sensor_tables
from ._sim_sensors import QUICK_SEEDS as SIM_QUICK_SEEDS, SEEDS as SIM_SEEDS, run_simulated, simulated_tables

HELP = """\
Measure what pito exists for and print tables with units.

  calibration  fit time (ms, s) and held-out RMSE (N, N·m) against k = 10³ … 10⁷
               samples for each method, in memory and streamed from a session file,
               side by side with numpy.linalg.lstsq / pinv fits of the same data
               (time ratio and RMSE ratio), the least-squares cores alone, and the
               peak resident memory (MB) of each fit's process. Data: simulated
               (pito_core.sim.VirtualCube); file generation is timed separately.
  contact      solves per second on batches of 10⁵ wrenches (one core) and RMS
               contact-point error as a ratio to the Cramér–Rao bound (1.00 =
               efficient), per surface (plane, sphere, ellipsoid, 5,000-facet mesh),
               scenario (soft finger, near-tangent force, exact point contact) and
               wrench noise level (σ in N and N·m), side by side with a per-sample
               scipy.optimize.least_squares solve of the same model; a speed-vs-error
               (Pareto) table. Beside the ratios: the share flagged as no single
               contact, and where the bound is out of reach (normal force within
               5 σ, with the plane's maximum-likelihood error to 4th order; mesh
               wrenches with two exact solutions), each ratio with its 95 %
               bootstrap interval over the samples. The single-contact test:
               false alarms (%) on simulated single touches and detection (%) of
               two-finger touches by separation D (σ), the share no method can tell
               from one touch (D ≤ 0), per patch kind. Side by side in one run: the
               same model's closed form in plain numpy (pito_bench._baseline), the
               solver's ratio to it and the single-contact test's cost over the
               bare solve's.
  analysis     pito analyze stage by stage on a simulated lift recording: samples/s
               of the read, pairing, calibration, contacts, single-contact test,
               metrics, figures and CSV writing, each beside a bare read of the same
               file (CPU time of a one-thread worker), the whole analyze_recording,
               and the figures' cost as a share of it.
  pipeline     serial frames decoded per second (× real time at 1 kHz); cost per
               display tick (ms) of finding the new samples by copying the ring windows
               vs by write cursor, and of the whole pipeline step; latency (ms) from a
               frame written into a pseudo-terminal to the bundle of the one pipeline
               (pito_core.pipeline.Pipeline: calibrated, six contacts solved), CPU
               share (%) of the pipeline process.
  live         the whole pito-app --demo window (devices and pipeline in their child
               processes, 1440×900 px) on a private Xvfb display, grabbed from outside
               ~100 times a second: frames per second that showed new data, for the 3D
               scene and for the plots, and latency (ms, p50/p95/max) from a sample's
               time to the first grab showing it — needs the app extras (PySide6,
               pyvista) and Xvfb; otherwise reported as skipped.

""" + EXPORT_HELP + SENSORS_HELP + """
Every figure is measured in the same run as its baseline and given as a ratio, since
machines are noisy; each measurement runs in a fresh subprocess limited to --threads
BLAS threads (default 1: "one core"). A full run takes several minutes (10⁷ samples are
generated and fitted); --quick takes under a minute on an idle 2-core machine.
"""


def register(sub) -> None:
    p = sub.add_parser("bench", help="benchmark calibration, contact sensing, the analysis and the live pipeline",
                       description=HELP, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--quick", action="store_true", help="small sizes (k ≤ 10⁵ samples, short live runs)")
    p.add_argument("--json", action="store_true", help="print the results as JSON instead of tables (SI units, s, MB)")
    p.add_argument("--out", metavar="DIR",
                   help="also write bench.json, bench.txt (tables) and speed-vs-error plots (PNG) into DIR")
    p.add_argument("--sections", default=",".join(SECTIONS + ("export", "sensors")), metavar="LIST",
                   help=f"comma-separated sections to run (default: all of {','.join(SECTIONS)}, export, sensors; also: soak = a 10-minute recording soak, 1 min with --quick; export = pito export's rates and a 1-hour export; sensors = fit_sensor on simulated sensors and real public data sets)")
    p.add_argument("--datasets", metavar="DIR",
                   help=f"folder of the sensors section's .npz data sets (default: ${DATASETS_ENV}, else ./datasets)")
    p.add_argument("--sim-sensors", type=int, metavar="N",
                   help=f"SIMULATED sensors' seeds in the sensors section, 0 … N−1 (default {SIM_SEEDS}; --quick "
                        f"{SIM_QUICK_SEEDS}; 0: none)")
    p.add_argument("--sizes", metavar="K,K,...",
                   help="calibration sizes k in samples (default 1000,…,10000000; quick: up to 100000)")
    p.add_argument("--threads", type=int, default=1, help="BLAS/OpenMP threads per measurement (default 1)")
    p.add_argument("--workdir", metavar="DIR", help="where to put the simulated session files (default: a temporary dir)")
    p.set_defaults(func=run)


def run(args) -> int:
    sections = tuple(s.strip() for s in args.sections.split(",") if s.strip())
    sizes = None
    if args.sizes:
        try:
            sizes = [int(float(x)) for x in args.sizes.split(",") if x.strip()]
        except ValueError:
            raise ValueError(f"--sizes: expected comma-separated sample counts, got {args.sizes!r}") from None
        if not sizes or min(sizes) < 200:
            raise ValueError(f"--sizes: expected sample counts of at least 200, got {args.sizes!r}")
    if args.threads < 1:
        raise ValueError(f"--threads: expected at least 1, got {args.threads}")
    n_sim = (SIM_QUICK_SEEDS if args.quick else SIM_SEEDS) if args.sim_sensors is None else args.sim_sensors
    if n_sim < 0:
        raise ValueError(f"--sim-sensors: expected a number of seeds ≥ 0, got {args.sim_sensors}")
    progress = (lambda s: print(s, file=sys.stderr, flush=True))
    export = "export" in sections  # its own module (pito_bench._export), beside run_bench's sections
    sensors = "sensors" in sections  # likewise (pito_bench._sensors): real data sets, no timing
    result = run_bench(quick=args.quick, sections=tuple(s for s in sections if s not in ("export", "sensors")),
                       sizes=sizes, threads=args.threads, workdir=args.workdir, progress=progress)
    if export:
        result["export"] = run_export(quick=args.quick, threads=args.threads, progress=progress)
    if sensors:
        sec = run_sensors(args.datasets, progress=progress)
        if n_sim:
            sec["simulated"] = run_simulated(range(n_sim), progress)
        result["sensors"] = json_safe(sec)
    text = format_report(result) + ("\n" + "\n".join(export_tables(result["export"])) + "\n" if export else "") \
        + ("\n" + "\n".join(sensor_tables(result["sensors"], simulated_tables(result["sensors"]["simulated"])
                                          if "simulated" in result["sensors"] else ())) + "\n" if sensors else "")
    if args.out:
        os.makedirs(args.out, exist_ok=True)
        with open(os.path.join(args.out, "bench.json"), "w") as f:
            json.dump(result, f, indent=1)
        with open(os.path.join(args.out, "bench.txt"), "w") as f:
            f.write(text)
        for p in write_plots(result, args.out):
            print(f"wrote {p}", file=sys.stderr)
    if args.json:
        print(json.dumps(result, indent=1))
    else:
        print(text)
    return 0

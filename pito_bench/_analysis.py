"""Analysis benchmark: where the time of ``pito analyze`` goes, stage by stage, beside a bare read.

One SIMULATED lift-hold-replace recording (``pito_core.sim.write_lift_recording``, the ideal
calibration embedded, 6 s and 6,000 samples per trial) is analysed stage by stage in a
one-thread worker, each stage timed alone (best of ``repeat``, CPU time of the worker):

- ``read``: the bare read pass (``read_recording``: file → arrays), the baseline;
- ``pair``: the recording through the one pipeline without a calibration (pairing, clocks);
- ``calibrate``: the same with the embedded calibration, less ``pair``;
- ``contacts``: ``solve_object`` of the face wrenches without the single-contact test;
- ``single-contact test``: ``solve_object`` with it, less ``contacts``;
- ``metrics``: ``analyze_contacts`` (series, trials, phase metrics, tables);
- ``figures``: ``save_overview_figure`` (``overview.png``, the one figure ``pito analyze``
  draws per recording by default);
- (beside the table: ``trial_figures_s``, ``save_trial_figures``, one PNG per trial, ``--figures trials``);
- ``write``: ``write_analysis`` without figures (CSV tables, summary).

Every stage is given in samples per second and as a share of the bare read's rate; the
whole ``analyze_recording`` (no figures) is timed end to end beside them, and the figures'
cost as a share of it (``figures_share``: the default overview; ``trial_figures_share``: with
a figure per trial as well). Peak resident memory of the worker is reported with the section.
"""

from __future__ import annotations

import os
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np

from ._timing import best_time, run_worker

__all__ = ["task_analysis", "run_analysis"]


def _recording(directory: Path, n_trials: int, seed: int = 0) -> Path:
    from pito_core.calibration import Calibration
    from pito_core.interop import assembly_record, calibration_record
    from pito_core.sim import LiftTask, VirtualCube, write_lift_recording

    cube = VirtualCube()
    cal = Calibration("ideal", cube.ideal_calibration(), range(1, 7), "face", cube.offset, cube.core, np.eye(4),
                      meta={"simulated": True})
    meta = {"calibration": calibration_record(cal, "ideal"), "assembly": assembly_record("cube")}
    path = directory / f"lift{n_trials}.pitorec"
    write_lift_recording(path, LiftTask(n_trials, seed=seed), seed=seed, meta=meta)
    return path


def task_analysis(n_trials: int = 5, repeat: int = 3, seed: int = 0) -> dict:
    """Seconds and samples/s of every stage of the analysis of one simulated lift recording."""
    from pito_core.analysis import (analyze_contacts, analyze_recording, recording_contacts, save_trial_figures,
                                    write_analysis)
    try:
        from pito_core.analysis import save_overview_figure
    except ImportError:  # a pito_core before the overview figure: its only figures were per trial
        save_overview_figure = save_trial_figures
    from pito_core.contact import solve_object
    from pito_core.interop import recording_calibration
    from pito_core.io import read_recording
    from pito_core.pipeline import replay_recording

    tmp = Path(tempfile.mkdtemp(prefix="pito-bench-analysis-"))
    try:
        path = _recording(tmp, n_trials, seed)
        clock = time.process_time
        t = {}
        t["read"], rec = best_time(lambda: read_recording(path), repeat, clock=clock)
        cal, _ = recording_calibration(dict(rec.meta), None, None)
        t["pair"], _ = best_time(lambda: replay_recording(rec, None, "cube"), repeat, clock=clock)
        t_cal, (bundle, pipe) = best_time(lambda: replay_recording(rec, cal, "cube"), repeat, clock=clock)
        t["calibrate"] = t_cal - t["pair"]
        W = np.asarray(bundle.face_wrenches, float)
        n = len(W)
        t_test, _ = best_time(lambda: solve_object(pipe.assembly or "cube", W, pipe.force_threshold), repeat,
                              clock=clock)
        try:
            t["contacts"], _ = best_time(lambda: solve_object(pipe.assembly or "cube", W, pipe.force_threshold,
                                                              single_contact=False), repeat, clock=clock)
        except TypeError:  # a pito_core before solve_object(single_contact=...): the two together
            t["contacts"] = float("nan")
        t["single-contact test"] = t_test - t["contacts"]
        time_s, contacts, meta = recording_contacts(path)
        cog = meta["cog_m"] if meta["cog_m"] is not None else (0.0, 0.0, 0.0)
        t["metrics"], analysis = best_time(lambda: analyze_contacts(time_s, contacts, cog=cog, mass=meta["mass_kg"],
                                                                    meta=meta), repeat, clock=clock)
        out = tmp / "out"
        out.mkdir()
        t["figures"], _ = best_time(lambda: save_overview_figure(analysis, out), repeat, clock=clock)
        t_trials, _ = best_time(lambda: save_trial_figures(analysis, out), repeat, clock=clock)
        t["write"], _ = best_time(lambda: write_analysis(analysis, out, figures=False), repeat, clock=clock)
        t_all, a2 = best_time(lambda: analyze_recording(path), repeat, clock=clock)
        assert a2.meta["n_samples"] == n, "samples in = samples out"
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    rows = [{"stage": k, "s": v, "samples_per_s": n / v if v > 0 else float("inf"),
             "ratio_read": (t["read"] / v) if v > 0 else float("inf")} for k, v in t.items()]
    rows.insert(5, {"stage": "contacts with the test", "s": t_test, "samples_per_s": n / t_test,
                    "ratio_read": t["read"] / t_test})
    return {"samples": n, "trials": n_trials, "rows": rows, "analyze_recording_s": t_all,
            "analyze_recording_samples_per_s": n / t_all, "figures_share": t["figures"] / t_all,
            "trial_figures_s": t_trials, "trial_figures_share": (t["figures"] + t_trials) / t_all,
            "read_samples_per_s": n / t["read"]}


def run_analysis(*, quick: bool = False, threads: int = 1, progress=print) -> dict:
    """Run the analysis benchmark in a one-thread subprocess; returns the JSON section."""
    params = {"n_trials": 5 if quick else 20, "repeat": 2 if quick else 3}
    progress(f"analysis: where the time goes, stage by stage ({params['n_trials']} simulated lift trials)")
    r = run_worker("analysis", params, threads=threads)
    r["data"] = "SIMULATED lift-hold-replace recording (pito_core.sim), ideal calibration embedded"
    r["threads"] = threads
    r["study"] = run_analysis_study(quick=quick, threads=threads, progress=progress)
    return r


def task_analysis_study(n_recordings: int = 8, n_trials: int = 5, seed: int = 0) -> dict:
    """``pito analyze`` of ``n_recordings`` SIMULATED lift recordings (no figures): in process and on Dask.

    The single-process path (:func:`~pito_core.analysis.run_serial`) on one recording and on
    all; then a loopback ``LocalCluster`` of 1 and of 2 workers (one thread each), each warmed
    up on a recording of its own first (imports), running all recordings. Samples per second
    of compute (first submit to last result, wall clock), the tasks' own CPU time per sample
    (which other work on the machine does not change; the load average is given) and the cost
    of 100 one-hour recordings (3.6·10⁶ samples each) at those rates.
    """
    from pito_core.analysis import analyze_to_dir, local_cluster, run_serial, run_study

    tmp = Path(tempfile.mkdtemp(prefix="pito-bench-study-"))
    try:
        paths = []
        for k in range(n_recordings + 1):
            p = _recording(tmp, n_trials, seed + k)
            paths.append(p.rename(tmp / f"rec{k:02d}.pitorec"))
        warm, recs = paths[0], paths[1:]
        rows = []

        def row(name, workers, res):
            cpu = sum(r.get("cpu_seconds") or 0.0 for r in res.results)
            rows.append({"path": name, "workers": workers, "recordings": len(res.results), "samples": res.samples,
                         "s": res.compute_seconds, "samples_per_s": res.samples_per_s,
                         "cpu_us_per_sample": 1e6 * cpu / res.samples if res.samples else float("nan"),
                         "failed": len(res.failed), "load_average": os.getloadavg()[0]})

        run_serial(analyze_to_dir, [warm], out_root=tmp / "w0", figures=False)  # imports
        row("in process, 1 recording", 0, run_serial(analyze_to_dir, recs[:1], out_root=tmp / "s1", figures=False))
        row(f"in process, {len(recs)} recordings", 0, run_serial(analyze_to_dir, recs, out_root=tmp / "s", figures=False))
        for n in (1, 2):
            with local_cluster(n, memory_limit="2GiB") as cluster:
                addr = cluster.scheduler_address
                run_study(analyze_to_dir, paths[:1] if n == 1 else [warm, recs[0]], scheduler=addr,
                          out_root=tmp / f"w{n}", figures=False)  # every worker imports pito first
                row(f"Dask, {n} worker{'s' * (n > 1)}", n,
                    run_study(analyze_to_dir, recs, scheduler=addr, out_root=tmp / f"d{n}", figures=False))
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    by = {r["workers"]: r["samples_per_s"] for r in rows if r["path"].startswith("Dask")}
    hour = 3.6e6
    for r in rows:
        workers = max(1, r["workers"])
        r["hours_100_one_hour_recordings"] = 100 * hour / r["samples_per_s"] / 3600
        r["cpu_hours_100_one_hour_recordings"] = r["hours_100_one_hour_recordings"] * workers
    return {"rows": rows, "speedup_2_workers": by[2] / by[1], "samples_per_recording": rows[0]["samples"],
            "n_recordings": len(recs)}


def run_analysis_study(*, quick: bool = False, threads: int = 1, progress=print) -> dict:
    """Run the Dask part of the analysis benchmark in a one-thread subprocess; returns its JSON section."""
    params = {"n_recordings": 8, "n_trials": 2 if quick else 5}
    progress(f"analysis on Dask: {params['n_recordings']} simulated recordings of {params['n_trials']} trials, "
             "in process and on 1 and 2 workers")
    r = run_worker("analysis_study", params, threads=threads)
    r["data"] = "SIMULATED lift-hold-replace recordings (pito_core.sim), ideal calibration embedded, no figures"
    return r

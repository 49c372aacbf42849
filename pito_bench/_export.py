"""Export benchmark: ``pito export`` to NWB and MCAP, samples/s of each writer and peak memory of a long export.

A short SIMULATED recording is made by the real recorder (``pito record --pito sim --ati sim``,
the ideal calibration and the ``pito_mixed`` assembly embedded), then tiled in time to the
lengths measured (:func:`tiled_recording`: rows repeated, device clocks, sequences and host
times continued; the generation is timed apart). In a one-thread worker, CPU time:

- ``pipeline``: the recording through :class:`~pito_core.interop.ExportStream` (read, pairing,
  calibration, contacts), no file written — the baseline;
- ``nwb``, ``mcap``, ``nwb + mcap``: :func:`~pito_core.interop.export_files` writing that, less
  the pipeline: the writers' own samples/s; and end to end with the pipeline.

The 1-hour export (``nwb + mcap``) runs in its own process: wall time, peak resident memory
(``ru_maxrss``) and the samples and messages per topic written, against those of the recording.

``python -m pito_bench._export TASK JSON`` is the measuring subprocess (as ``pito_bench._worker``).
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from ._timing import best_time, peak_rss_mb, run_worker

__all__ = ["tiled_recording", "task_export", "task_export_long", "run_export", "export_tables", "EXPORT_HELP"]

EXPORT_HELP = """\
  export       pito export of a SIMULATED recording (made by pito record, tiled in time):
               samples/s of the pipeline alone, of the NWB writer, the MCAP writer and
               both (CPU time of a one-thread worker, less the pipeline), end to end;
               and a 1-hour export (3.6·10⁶ cube samples + reference) in its own
               process: wall time, peak RSS (MB), counts per topic (--quick: 60 s
               and 5 min recordings).
"""


def _source_recording(directory: Path, seconds: float, seed: int = 5) -> Path:
    """A SIMULATED recording by the real recorder, calibration and assembly embedded."""
    from pito_core.calibration import Calibration
    from pito_core.sim import VirtualCube

    cube = VirtualCube()
    cal_path = directory / "ideal.pitocal"
    Calibration("ideal", cube.ideal_calibration(), range(1, 7), "face", cube.offset, cube.core, np.eye(4),
                meta={"simulated": True}).save(cal_path)
    out = directory / "source.pitorec"
    cmd = [sys.executable, "-c", "import sys; from pito_core.cli import main; sys.exit(main())", "record",
           "--pito", "sim", "--ati", "sim", "--sim-speed", "10", "--duration", str(seconds / 10), "--seed", str(seed),
           "--progress", "0", "--tare", "0.2", "--calibration", str(cal_path), "--object", "pito_mixed", "-o", str(out)]
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    if r.returncode != 0:
        raise RuntimeError(f"pito record failed: {r.stderr[-2000:]}")
    return out


def tiled_recording(source, path, seconds: float, chunk_s: float = 0.5) -> dict:
    """Write ``path``: recording ``source`` repeated until ``seconds`` of cube samples (SIMULATED, labelled so).

    Each copy continues the device clocks (``time_us``, ``rdt_seq``), sequences and host
    times of the one before by the source's span; tare events stay those of the first copy.
    Rows are written in chunks of ``chunk_s`` s, as the recorder does. Returns
    ``{"n": cube rows, "m": reference rows}``.
    """
    from pito_core.io import RecordingWriter, read_recording

    src = read_recording(source)
    p, a = src.pito, src.netft
    span = {  # one copy's extent on each counter: a period past its last row
        "time_us": int((np.diff(p["time_us"].astype(np.int64)) % 2**32).sum()) + 1000,
        "seq": int((np.diff(p["seq"].astype(np.int64)) % 2**32).sum()) + 1,
        "rdt_seq": int((np.diff(a["rdt_seq"].astype(np.int64)) % 2**32).sum()) + 1 if a.size else 0}
    span_s = span["time_us"] * 1e-6
    copies = int(np.ceil(seconds / span_s))
    meta = dict(src.meta)
    meta["simulated"] = True
    meta["source"] = f"{meta.get('source', '')}; tiled {copies}x in time by pito_bench._export (SIMULATED)"
    meta.pop("created_unix", None)
    n_want = int(round(seconds / span_s * p.size))
    n = m = 0
    step = max(1, int(chunk_s / span_s * p.size))
    with RecordingWriter(path, meta, flush_interval=1.0, fsync=False) as w:
        for e in src.events:
            w.append_event(e)
        for k in range(copies):
            pk = p[: max(0, min(p.size, n_want - n))]
            ak = a
            if pk.size < p.size:  # the last copy: reference rows up to its last cube sample's host time
                ak = a[: int(np.searchsorted(a["host_time"], pk["host_time"][-1], side="right"))] if pk.size else a[:0]
            dt_host = span_s * k
            for s in range(0, pk.size, step):
                r = pk[s:s + step]
                w.append_pito((r["seq"].astype(np.int64) + k * span["seq"]) % 2**32,
                              (r["time_us"].astype(np.int64) + k * span["time_us"]) % 2**32,
                              r["host_time"] + dt_host, r["counts"])
                t_hi = r["host_time"][-1]
                lo = int(np.searchsorted(ak["host_time"], pk["host_time"][s - 1] if s else -np.inf, side="right"))
                hi = ak.size if s + step >= pk.size else int(np.searchsorted(ak["host_time"], t_hi, side="right"))
                q = ak[lo:hi]
                if q.size:
                    w.append_netft((q["rdt_seq"].astype(np.int64) + k * span["rdt_seq"]) % 2**32, q["ft_seq"], q["status"],
                                   q["host_time"] + dt_host, q["wrench"])
                w.flush()
            n += pk.size
            m += ak.size
            if n >= n_want:
                break
    return {"n": n, "m": m}


def task_export(path: str, repeat: int = 2) -> dict:
    """CPU seconds of the pipeline alone and of export_files to NWB, MCAP and both, on recording ``path``."""
    from pito_core.interop import ExportStream, export_files

    tmp = Path(tempfile.mkdtemp(prefix="pito-bench-export-"))
    clock = time.process_time
    try:
        export_files(path, nwb=tmp / "warm.nwb", mcap=tmp / "warm.mcap")  # imports, namespaces: not timed
        t = {}
        t["pipeline"], n = best_time(lambda: sum(b.n for b in ExportStream(path).blocks()), repeat, clock=clock)
        t["nwb"], _ = best_time(lambda: export_files(path, nwb=tmp / "a.nwb"), repeat, clock=clock)
        t["mcap"], _ = best_time(lambda: export_files(path, mcap=tmp / "a.mcap"), repeat, clock=clock)
        t["nwb + mcap"], out = best_time(lambda: export_files(path, nwb=tmp / "b.nwb", mcap=tmp / "b.mcap"), repeat,
                                         clock=clock)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    rows = [{"what": "pipeline (read, pair, calibrate, contacts)", "s": t["pipeline"],
             "samples_per_s": n / t["pipeline"], "with_pipeline_samples_per_s": n / t["pipeline"]}]
    for k in ("nwb", "mcap", "nwb + mcap"):
        own = max(t[k] - t["pipeline"], 1e-9)
        rows.append({"what": k, "s": own, "samples_per_s": n / own, "with_pipeline_samples_per_s": n / t[k]})
    return {"samples": n, "reference": out["m"], "messages": sum(out["topics"].values()), "rows": rows}


def task_export_long(path: str) -> dict:
    """One streamed export of ``path`` to NWB and MCAP: wall seconds, counts written, read back from the files."""
    from pito_core.interop import export_files

    tmp = Path(tempfile.mkdtemp(prefix="pito-bench-export-"))
    try:
        t0 = time.perf_counter()
        out = export_files(path, nwb=tmp / "long.nwb", mcap=tmp / "long.mcap")
        wall = time.perf_counter() - t0
        rss = peak_rss_mb()
        sizes = {"nwb_mb": (tmp / "long.nwb").stat().st_size / 1e6, "mcap_mb": (tmp / "long.mcap").stat().st_size / 1e6}
        import h5py
        from mcap.reader import make_reader

        with h5py.File(tmp / "long.nwb", "r") as f:
            nwb_rows = {"pito_raw_counts": f["acquisition/pito_raw_counts/data"].shape[0],
                        "reference_force": f["acquisition/reference_force/data"].shape[0]
                        if "reference_force" in f["acquisition"] else 0}
        with open(tmp / "long.mcap", "rb") as fh:
            s = make_reader(fh).get_summary()
            mcap_counts = {s.channels[c].topic: k for c, k in s.statistics.channel_message_counts.items()}
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return {"samples": out["n"], "reference": out["m"], "wall_s": wall, "seconds": out["seconds"],
            "export_peak_rss_mb": rss, "nwb_rows": nwb_rows, "mcap_counts": mcap_counts, **sizes}


def run_export(*, quick: bool = False, threads: int = 1, workdir: str | None = None, progress=print) -> dict:
    """The export section: rates on a tiled recording, and a long export in its own process."""
    own = workdir is None
    d = Path(tempfile.mkdtemp(prefix="pito-bench-export-") if own else workdir)
    rate_s, long_s = (60.0, 300.0) if quick else (600.0, 3600.0)
    try:
        progress("export: recording the source (pito record --pito sim --ati sim, 10 s of simulated devices)")
        src = _source_recording(d, 10.0 if quick else 30.0)
        res = {"data": "SIMULATED: a pito record recording (simulated cube and Net F/T, ideal calibration, "
                       "pito_mixed) tiled in time", "threads": threads}
        for name, secs in (("rates", rate_s), ("long", long_s)):
            t0 = time.perf_counter()
            counts = tiled_recording(src, d / f"{name}.pitorec", secs)
            res[f"{name}_recording"] = {"seconds": secs, **counts, "generate_s": time.perf_counter() - t0,
                                        "file_mb": (d / f"{name}.pitorec").stat().st_size / 1e6}
        progress(f"export: samples/s of the writers ({rate_s:.0f} s recording, one thread)")
        res["rates"] = run_worker("export", {"path": str(d / "rates.pitorec"), "repeat": 1 if quick else 2},
                                  threads=threads, module="pito_bench._export")
        progress(f"export: a {long_s:.0f} s recording to NWB + MCAP in its own process (peak memory)")
        res["long"] = run_worker("export_long", {"path": str(d / "long.pitorec")}, threads=threads,
                                 module="pito_bench._export")
    finally:
        if own:
            shutil.rmtree(d, ignore_errors=True)
    return res


def export_tables(ex: dict) -> list[str]:
    """The export section as text lines."""
    r = ex["rates"]
    lines = [f"EXPORT — {ex['data']}; one thread, CPU time",
             f"  rates on {r['samples']:,} cube samples, {r['reference']:,} reference records, "
             f"{r['messages']:,} MCAP messages",
             f"  {'what':44s} {'s':>8s} {'samples/s':>12s} {'with pipeline':>14s}"]
    for row in r["rows"]:
        lines.append(f"  {row['what']:44s} {row['s']:8.2f} {row['samples_per_s']:12.3g} "
                     f"{row['with_pipeline_samples_per_s']:14.3g}")
    lg, rec = ex["long"], ex["long_recording"]
    ok = lg["samples"] == rec["n"] and lg["reference"] == rec["m"] and lg["nwb_rows"]["pito_raw_counts"] == rec["n"] \
        and lg["mcap_counts"].get("/pito/raw_counts") == rec["n"] \
        and lg["mcap_counts"].get("/pito/reference/wrench", 0) == rec["m"]
    lines += [f"  {rec['seconds']:.0f} s recording ({rec['n']:,} cube + {rec['m']:,} reference samples, "
              f"{rec['file_mb']:.0f} MB): NWB + MCAP in {lg['wall_s']:.1f} s wall "
              f"({rec['n'] / lg['wall_s']:.3g} samples/s), peak RSS {lg['export_peak_rss_mb']:.0f} MB, "
              f"files {lg['nwb_mb']:.0f} + {lg['mcap_mb']:.0f} MB; every sample in both: {'yes' if ok else 'NO'}",
              "  MCAP messages per topic: " + ", ".join(f"{k} {v:,}" for k, v in lg["mcap_counts"].items())]
    return lines


TASKS = {"export": task_export, "export_long": task_export_long}


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    out = TASKS[argv[0]](**(json.loads(argv[1]) if len(argv) > 1 else {}))
    out["peak_rss_mb"] = peak_rss_mb()
    print(json.dumps(out, allow_nan=True))
    return 0


if __name__ == "__main__":
    sys.exit(main())

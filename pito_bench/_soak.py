"""The soak benchmark: record from the simulated devices for minutes, then verify.

Two ways, for ``minutes``:

- ``--app`` (the issue's soak): ``pito-app --demo --record FILE --duration S`` on a private
  Xvfb display — the window drawing live, the simulated devices and the pipeline process
  (drivers, pipeline, recorder) each a child process of the app;
- default (headless): ``pito record --pito sim --ati sim`` (the simulated devices in a child
  process, the same acquisition + pipeline + recorder, no window).

Every second it samples the memory (RSS) and CPU time of the recorder process (the app or
``pito record``) and of all its descendants from /proc, then reads the recording back and
checks it: complete (end marker, every chunk's CRC), cube frames lost (gaps in the device
sequence), Net F/T records lost, and no child process left behind.

Run: ``python -m pito_bench._soak --minutes 60 --app`` (or ``pito bench --sections soak``:
10 min with the app; 1 min with ``--quick``). Figures depend on the machine's load; the
result records the load average.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from pito_core.io import Recording

from ._live_window import display_env, start_xvfb

__all__ = ["run_soak"]

_PAGE = os.sysconf("SC_PAGE_SIZE")
_TICK = os.sysconf("SC_CLK_TCK")


def _proc(pid: int):
    """(rss bytes, cpu seconds) of ``pid``, or None once it is gone."""
    try:
        with open(f"/proc/{pid}/stat") as fh:
            f = fh.read().rsplit(")", 1)[1].split()
        return int(f[21]) * _PAGE, (int(f[11]) + int(f[12])) / _TICK
    except (OSError, IndexError, ValueError):
        return None


def _children(pid: int) -> list[int]:
    try:
        with open(f"/proc/{pid}/task/{pid}/children") as fh:
            return [int(v) for v in fh.read().split()]
    except OSError:
        return []


def _descendants(pid: int) -> list[int]:
    out, todo = [], _children(pid)
    while todo:
        c = todo.pop()
        out.append(c)
        todo.extend(_children(c))
    return out


def run_soak(minutes: float = 10.0, *, app: bool = False, workdir=None, progress=print) -> dict:
    """Record ``minutes`` from the simulated devices (the app's window open with ``app``), sample memory/CPU,
    verify the file. Returns a JSON-able dict."""
    workdir = Path(workdir or tempfile.mkdtemp(prefix="pito-soak-"))
    workdir.mkdir(parents=True, exist_ok=True)
    out = workdir / "soak.rec"
    seconds = float(minutes) * 60.0
    xvfb = None
    env = None
    if app:
        display, xvfb = start_xvfb()
        env = display_env(display)
        cmd = [sys.executable, "-c", "import sys; from app.main import main; sys.exit(main(sys.argv[1:]))", "--demo",
               "--record", str(out), "--duration", str(seconds)]
    else:
        cmd = [sys.executable, "-c", "import sys; from pito_core.cli import main; sys.exit(main(sys.argv[1:]))",
               "record", "--pito", "sim", "--ati", "sim", "-o", str(out), "--duration", str(seconds), "--progress", "10"]
    log = open(workdir / "record.log", "w")
    load0 = os.getloadavg()
    t_start = time.monotonic()
    proc = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, env=env)
    samples, child_pids = _sample_until_exit(proc, t_start, progress)
    wall = time.monotonic() - t_start
    log.close()
    if xvfb is not None:
        xvfb.terminate()
        xvfb.wait()
    orphans = [c for c in child_pids if _proc(c) is not None]
    result = {"minutes": minutes, "mode": "app window" if app else "headless", "wall_s": wall,
              "exit_code": proc.returncode, "loadavg_before": list(load0), "loadavg": os.getloadavg(),
              "cpus": os.cpu_count(), "orphan_device_processes": len(orphans)}
    result.update(_verify_recording(out))
    if samples:
        result.update(_memory_and_cpu(np.asarray(samples)))
    result["targets"] = {
        "no_lost_frames": result.get("cube_frames_lost") == 0,
        "memory_growth_le_50MB": bool(samples) and result["memory_mb"]["recorder_growth_after_first_min"] <= 50,
        "recording_verified": bool(result["recording"].get("verified")) and bool(result["recording"].get("complete")),
        "no_orphans": not orphans,
    }
    result["note"] = ("`pito-app --demo --record` on Xvfb: the window drawing live, the simulated devices and the "
                      "pipeline process (drivers, pipeline, recorder) each a child process of the app; 'recorder' = "
                      "the app process, 'devices' = all its descendants" if app else
                      "headless: `pito record --pito sim --ati sim` (simulated devices in their own process, the app's "
                      "acquisition + pipeline + recorder, no window)")
    return result


def _sample_until_exit(proc, t_start: float, progress) -> tuple[list, set]:
    """Once a second until ``proc`` ends: ``(t s, RSS recorder B, RSS descendants B, CPU recorder s, CPU
    descendants s)``; returns the samples and every descendant's pid seen."""
    samples = []  # (t, rss_recorder, rss_children, cpu_recorder, cpu_children)
    child_pids: set[int] = set()
    while proc.poll() is None:
        time.sleep(1.0)
        me = _proc(proc.pid)
        if me is None or me[0] == 0 or proc.poll() is not None:  # gone or a zombie: no more samples
            continue
        kids = _descendants(proc.pid)
        child_pids.update(kids)
        ks = [k for k in (_proc(c) for c in kids) if k is not None and k[0] > 0]
        samples.append((time.monotonic() - t_start, me[0], sum(k[0] for k in ks), me[1], sum(k[1] for k in ks)))
        if progress and len(samples) % 60 == 0:
            progress(f"soak: {samples[-1][0] / 60:.1f} min, recorder RSS {me[0] / 2**20:.1f} MB")
    return samples, child_pids


def _verify_recording(out) -> dict:
    """Read the recording back: complete, rows, frames and records lost, the cube's rate (Hz)."""
    result = {}
    try:
        rec = Recording(out)
        result["recording"] = {"complete": rec.complete, "verified": True, "pito_rows": int(rec.pito.size),
                               "netft_rows": int(rec.netft.size), "duration_s": rec.duration}
        seq = rec.pito["seq"].astype(np.int64)
        result["cube_frames_lost"] = int(((np.diff(seq) - 1).clip(0)).sum()) if seq.size > 1 else None
        rs = rec.netft["rdt_seq"].astype(np.int64)
        d = np.diff(rs)
        result["ati_records_lost"] = int(((d - 1)[d > 0]).sum()) if rs.size > 1 else None
        result["cube_rate_hz"] = (seq.size - 1) / max(1e-9, rec.pito["host_time"][-1] - rec.pito["host_time"][0])
    except Exception as exc:  # noqa: BLE001 - reported, not hidden
        result["recording"] = {"verified": False, "error": str(exc)}
    return result


def _memory_and_cpu(a: np.ndarray) -> dict:
    """Memory growth (MB) after the first minute and CPU share (of one core) from the samples ``a (n, 5)``."""
    result = {}
    after1 = a[a[:, 0] >= min(60.0, a[-1, 0] / 2)]
    base = after1[0]
    kid = a[a[:, 2] > 0]  # samples while the device process was alive (it exits before the recorder)
    kid = kid if len(kid) else a
    kbase = kid[kid[:, 0] >= base[0]][0] if (kid[:, 0] >= base[0]).any() else kid[0]
    result["memory_mb"] = {
        "recorder_first_min": float(base[1] / 2**20), "recorder_end": float(a[-1, 1] / 2**20),
        "recorder_growth_after_first_min": float((a[-1, 1] - base[1]) / 2**20),
        "devices_growth_after_first_min": float((kid[-1, 2] - kbase[2]) / 2**20),
        "recorder_max": float(a[:, 1].max() / 2**20),
    }
    span = a[-1, 0] - a[0, 0]
    result["cpu_share"] = {  # fraction of one core
        "recorder": float((a[-1, 3] - a[0, 3]) / span) if span > 0 else None,
        "devices": float((kid[-1, 4] - kid[0, 4]) / (kid[-1, 0] - kid[0, 0])) if kid[-1, 0] > kid[0, 0] else None,
    }
    return result


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m pito_bench._soak", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--minutes", type=float, default=10.0, help="recording length, minutes (default 10)")
    ap.add_argument("--workdir", help="where the recording and its log go (default: a new temporary folder)")
    ap.add_argument("--app", action="store_true", help="soak the desktop app (window on a private Xvfb display) "
                    "instead of the headless `pito record`")
    ap.add_argument("--json", action="store_true", help="print only the JSON result")
    args = ap.parse_args(argv)
    res = run_soak(args.minutes, app=args.app, workdir=args.workdir, progress=None if args.json else print)
    print(json.dumps(res, indent=None if args.json else 2, default=float))
    return 0


if __name__ == "__main__":
    sys.exit(main())

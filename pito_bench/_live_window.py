"""``pito bench --sections live``: the WHOLE live window as a user sees it.

``python -m pito_bench._live_window [--json] [--quick] [--seconds S]``

What runs: ``pito-app --demo``'s own :class:`app.window.MainWindow` — the simulated devices in
their child process (a pty and loopback UDP), the real drivers, acquisition and core pipeline
in the pipeline process, the live feed and the live tab at 1440×900 px — on a private Xvfb display
(software OpenGL; ``QT_QPA_PLATFORM`` unset, no off-screen rendering).

How it is measured, from outside the app's process:

- frame stamps (:mod:`pito_bench._stamp`): the app draws the time of the newest sample each
  view shows (host ``CLOCK_MONOTONIC``; sample times are the device clocks mapped onto it)
  as the colour of a 10×10 px square in the 3D scene and in the force plot, in the same
  paint as the data;
- a grabber in this process reads the scene's and the plots' rectangles 100 times a second
  and the two stamps' pixels 1000 times a second, through shared memory (``XShmGetImage``;
  :mod:`pito_bench._xgrab`);
- frame rate of a view = new stamps seen per second (frames that showed new data); also the
  whole-view grabs whose pixels changed at all (capped by their rate, reported);
- latency = (time of the first read showing a stamp) − (the stamped sample's time): from the
  sample's time on the device clock to the pixels on the X server; it overestimates by up to
  one read period (1 ms; with one read of whole views per 10 ms it was up to 10 ms, 5 on average).
- where the scene's latency goes: the app's drawing thread notes each frame's start and end
  (:class:`~pito_bench._stamp.WindowProbe`), joined with the reads by stamp: sample → frame
  start → frame end → first read showing it.

- first frame (``--first-frame N``, also in ``run``): the time from starting the app's process to
  the first read showing a stamp in each view (a frame with data: the demo's calibrated forces once
  its start-up calibration is cached), over N starts after one that is not counted (it fills the
  caches a user's first start fills: the calibration, the display meshes, Python's bytecode of
  pito's modules, which this machine's ``PYTHONDONTWRITEBYTECODE`` would have compiled at every
  start); the window's showing is the moment the app writes its regions;
  the CPU seconds the app and its children had used by the first stamp (``/proc``), and the app's
  own (its process alone: the critical path), are the figures a loaded machine moves least.

Figures depend on the machine and on its load: the load average before and after is in the
result. The app and the grabber share the machine with the simulated devices.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from ._stamp import WindowProbe, decode

__all__ = ["run", "main", "start_xvfb", "display_env", "first_frame"]

SIZE = (1440, 900)
#: Reads of the stamp pixels per second, Hz (default): the latency is resolved to 1/STAMP_RATE.
STAMP_RATE = 1000.0


def _run_app(regions: str, seconds: float, warmup: float) -> int:
    """In the app's process: the demo window with frame stamps; writes the regions JSON when warm.

    Started as ``pito-app --demo`` starts (``app.main``): the simulated devices boot before Qt and the
    window load, the application set up as pito-app's (``make_application``: the GUI thread's garbage
    collector, the app's font, the style)."""
    import gc

    from app.main import _boot_demo_devices, make_application  # deferred: the app loads only in the app's process

    gc.disable()  # as pito-app's main: no collection passes over the start-up's imports
    rig_boot = _boot_demo_devices(0, 1.5)
    app = make_application()
    # deferred: Qt and the app load only in the app's process (the grabber and the soak import this module)
    from PySide6.QtCore import QTimer

    from app.window import MainWindow

    w = MainWindow(demo=True, rig_boot=rig_boot)
    app.gc_collector.freeze_startup()  # as pito-app's main
    w.resize(*SIZE)
    w.move(0, 0)
    w.show()
    probe = WindowProbe(w)

    def write_regions():
        info = probe.regions()
        info["pid"] = os.getpid()
        info["renderer"] = _renderer(w.live.scene.plotter)
        Path(regions).write_text(json.dumps(info))

    QTimer.singleShot(int(warmup * 1000), write_regions)
    QTimer.singleShot(int((warmup + seconds) * 1000), app.quit)
    app.exec()
    Path(regions + ".frames").write_text(json.dumps(probe.frames))  # for the scene's breakdown (run)
    w.shutdown()
    w.release_views()
    return 0


def _renderer(plotter) -> str:
    try:
        caps = plotter.ren_win.ReportCapabilities()
    except Exception:  # noqa: BLE001 - a figure for the report only
        return "unknown"
    for line in caps.splitlines():
        if "renderer string" in line.lower():
            return line.split(":", 1)[1].strip()
    return "unknown"


def _percentiles(values) -> dict:
    v = np.asarray(values, dtype=float)
    if v.size == 0:
        return {"p50": None, "p95": None, "max": None, "n": 0}
    return {"p50": float(np.percentile(v, 50)), "p95": float(np.percentile(v, 95)), "max": float(v.max()),
            "n": int(v.size)}


def _grab(display: str, regions_path: Path, seconds: float, rate: float, stamp_rate: float, app_proc) -> dict:
    from ._xgrab import Grabber  # deferred: loads libX11 (ctypes) at import; only the grabbing process needs it

    t_wait = time.monotonic() + 180
    while not regions_path.exists():
        if app_proc.poll() is not None:
            raise RuntimeError(f"the app exited (code {app_proc.returncode}) before showing its window")
        if time.monotonic() > t_wait:
            raise RuntimeError("the app did not show its window within 180 s")
        time.sleep(0.1)
    time.sleep(0.3)
    reg = json.loads(regions_path.read_text())
    g = Grabber(display)
    keys = ("scene", "plots")
    stamp_xy = {"scene": reg["scene_stamp"], "plots": reg["plot_stamp"]}
    prev = dict.fromkeys(keys)
    changed = dict.fromkeys(keys, 0)
    fine = {k: _StampLog() for k in keys}  # the stamp pixel, read at every poll
    whole = {k: _StampLog() for k in keys}  # the stamp as the whole-view grabs show it (resolution 1/rate)
    n = polls = 0
    period = 1.0 / max(stamp_rate, rate)
    every = max(1, round(max(stamp_rate, rate) / rate))  # polls per whole-view grab
    t0 = time.monotonic()
    t_next, t_end = t0, t0 + seconds
    while time.monotonic() < t_end:
        now = time.monotonic()
        if now < t_next:
            time.sleep(t_next - now)
        t_next += period
        for key in keys:
            sx, sy = stamp_xy[key]
            if polls % every == 0:  # the whole view: did any pixel change
                x, y, w, h = reg[key]
                ta = time.monotonic()
                img = g.grab(x, y, w, h)
                whole[key].see(img[sy - y, sx - x], 0.5 * (ta + time.monotonic()))
                if prev[key] is None:
                    prev[key] = img.copy()
                elif not np.array_equal(img.view(np.uint32), prev[key].view(np.uint32)):  # a pixel a word: half the time
                    changed[key] += 1
                    np.copyto(prev[key], img)  # a shared-memory grab is overwritten by the next one
            ta = time.monotonic()
            px = g.grab(sx, sy, 1, 1)
            fine[key].see(px[0, 0], 0.5 * (ta + time.monotonic()))
        n += polls % every == 0
        polls += 1
    dt = time.monotonic() - t0
    g.close()
    out = {"grabs_per_s": n / dt, "stamp_reads_per_s": polls / dt,
           "grab": "XShmGetImage (MIT-SHM)" if g.uses_shm else "XGetImage", "seconds": dt, "renderer": reg.get("renderer"),
           "size": list(SIZE), "regions": {k: reg[k] for k in keys}}
    for key in keys:
        out[key] = {"frames_per_s": len(fine[key].lat) / dt, "changed_grabs_per_s": changed[key] / dt,
                    "latency_ms": _percentiles(fine[key].lat), "bad_stamps": fine[key].bad,
                    "latency_whole_grabs_ms": _percentiles(whole[key].lat)}
    out["scene"]["_seen"] = fine["scene"].seen
    return out


def _breakdown(frames, seen) -> dict:
    """Where the scene's latency goes, per frame whose stamp was seen: sample → frame start → frame
    end (the app's render thread, :class:`~pito_bench._stamp.WindowProbe`) → first read showing it (ms)."""
    first = {}
    for ts, t in seen:
        first.setdefault(int(round(ts * 1000)), t)
    rows = []
    for ts, t0, t1 in frames:
        t = first.get(int(round(ts * 1000))) if np.isfinite(ts) else None
        if t is not None and t >= t1 - 0.002:  # the frame that drew it (not an earlier one with the same data)
            rows.append((t0 - ts, t1 - t0, max(t - t1, 0.0)))
    r = 1000.0 * np.array(rows).reshape(-1, 3)
    return {"sample_to_frame_start": _percentiles(r[:, 0]), "frame": _percentiles(r[:, 1]),
            "frame_end_to_screen": _percentiles(r[:, 2])}


class _StampLog:
    """The latencies (ms) of one view's stamps as one sequence of reads sees them: each new stamp's
    first read time − its sample time."""

    def __init__(self):
        self.last, self.lat, self.bad = None, [], 0
        self.seen = []  # (stamp, first read showing it), s

    def see(self, bgra, t: float) -> None:
        """A read at time ``t`` (s, monotonic) of a stamp pixel ``bgra``."""
        b, g, r = (int(v) for v in bgra[:3])
        if (r, g, b) == (0, 0, 0):
            return  # no data shown yet
        ts = decode((r, g, b), t)
        if ts == self.last:
            return
        if self.last is not None:  # the first one may have been on screen for a while
            d = t - ts
            if 0.0 <= d < 5.0:
                self.lat.append(1000.0 * d)
                self.seen.append((ts, t))
            else:
                self.bad += 1
        self.last = ts


def _cpu_seconds(pid: int, children: bool = True) -> float | None:
    """CPU time (user + system, s) of process ``pid`` and (``children``) every live descendant (Linux ``/proc``), or None."""
    tick = os.sysconf("SC_CLK_TCK")
    stats = {}
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                f = (d / "stat").read_text().rsplit(")", 1)[1].split()
            except OSError:
                continue
            stats[int(d.name)] = (int(f[1]), (int(f[11]) + int(f[12])) / tick)  # ppid, utime + stime
    if pid not in stats:
        return None
    total, todo = 0.0, [pid]
    while todo:
        p = todo.pop()
        total += stats[p][1]
        todo += [c for c, (pp, _) in stats.items() if pp == p] if children else []
    return total


def _first_frame_once(display: str, timeout: float = 90.0, pycache: str | None = None) -> dict:
    """One start of the demo app: seconds from starting its process to its window shown and to the
    first read showing a data stamp in the scene and in the plots; the CPU seconds the app and its
    child processes (the simulated devices, the pipeline) had used when the first stamp was seen.

    ``pycache``: a folder for Python's bytecode cache (``PYTHONPYCACHEPREFIX``), written even where
    the environment says not to (``PYTHONDONTWRITEBYTECODE``), as an install's first start writes it."""
    from ._xgrab import Grabber  # deferred: loads libX11 (ctypes) at import

    regions = Path(f"/tmp/pito_bench_first_{os.getpid()}.json")
    regions.unlink(missing_ok=True)
    env = display_env(display)
    if pycache is not None:
        env.pop("PYTHONDONTWRITEBYTECODE", None)
        env["PYTHONPYCACHEPREFIX"] = str(pycache)
    t0 = time.monotonic()
    app = subprocess.Popen([sys.executable, "-m", "pito_bench._live_window", "--run-app", str(regions),
                            "--seconds", "4", "--warmup", "0"], env=env,
                           stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    out = {"window_s": None, "scene_s": None, "plots_s": None, "cpu_s": None, "app_cpu_s": None}
    try:
        while not regions.exists():
            if app.poll() is not None or time.monotonic() - t0 > timeout:
                return out
            time.sleep(0.002)
        out["window_s"] = time.monotonic() - t0
        time.sleep(0.01)
        reg = json.loads(regions.read_text())
        g = Grabber(display)
        try:
            stamps = {"scene_s": reg["scene_stamp"], "plots_s": reg["plot_stamp"]}
            while any(out[k] is None for k in stamps) and time.monotonic() - t0 < timeout:
                for key, (sx, sy) in stamps.items():
                    if out[key] is not None:
                        continue
                    px = g.grab(sx, sy, 1, 1)[0, 0]
                    t = time.monotonic()
                    b, gg, r = (int(v) for v in px[:3])
                    if (r, gg, b) != (0, 0, 0) and t0 <= decode((r, gg, b), t) <= t:  # a sample of this start
                        out[key] = t - t0
                        if out["cpu_s"] is None:
                            out["cpu_s"] = _cpu_seconds(app.pid)
                            out["app_cpu_s"] = _cpu_seconds(app.pid, children=False)
                time.sleep(0.001)
        finally:
            g.close()
    finally:
        app.terminate()
        try:
            app.wait(timeout=30)
        except subprocess.TimeoutExpired:
            app.kill()
            app.wait()
        regions.unlink(missing_ok=True)
        Path(str(regions) + ".frames").unlink(missing_ok=True)
    return out


def first_frame(runs: int = 3, display: str | None = None) -> dict:
    """The demo's start-up as a user sees it: ``runs`` starts (after one not counted), each timed from
    starting the process to the first frame with data on the screen (s); medians and every run."""
    if shutil.which("Xvfb") is None and display is None:
        return {"status": "skipped: Xvfb not installed"}
    xvfb = None
    if display is None:
        display, xvfb = start_xvfb()
    # the bytecode of pito's own modules is cached as on an install (pip's for the dependencies), not
    # compiled at every start as PYTHONDONTWRITEBYTECODE (set on the project's machine) would have it
    pycache = tempfile.TemporaryDirectory(prefix="pito_bench_pycache_")
    try:
        _first_frame_once(display, pycache=pycache.name)  # fills a first start's caches (calibration, meshes, bytecode)
        rows = [_first_frame_once(display, pycache=pycache.name) for _ in range(runs)]
    finally:
        pycache.cleanup()
        if xvfb is not None:
            xvfb.terminate()
            xvfb.wait()
    res = {"status": "ok", "runs": rows}
    for key in ("window_s", "scene_s", "plots_s", "cpu_s", "app_cpu_s"):
        v = [r[key] for r in rows if r[key] is not None]
        res[key] = {"median": float(np.median(v)) if v else None, "min": min(v, default=None),
                    "max": max(v, default=None), "n": len(v)}
    res["loadavg"] = list(os.getloadavg())
    res["method"] = ("process start → first read of each view's data stamp on a private Xvfb (1 ms polls), "
                     f"{runs} starts after one not counted (calibration, display meshes and bytecode cached)")
    return res


def start_xvfb(screen: str = "1600x1000x24") -> tuple[str, subprocess.Popen]:
    """A private Xvfb display for a window to be watched from outside: ``(":N", process)`` (terminate it after)."""
    display = f":{90 + os.getpid() % 400}"
    xvfb = subprocess.Popen(["Xvfb", display, "-ac", "-nolisten", "tcp", "-screen", "0", screen],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    time.sleep(1.5)
    return display, xvfb


def display_env(display: str) -> dict:
    """The environment of an app on ``display``: a real window (no off-screen Qt or pyvista)."""
    env = dict(os.environ, DISPLAY=display)
    env.pop("QT_QPA_PLATFORM", None)
    env.pop("PYVISTA_OFF_SCREEN", None)
    return env


def run(quick: bool = False, seconds: float | None = None, rate: float = 100.0, warmup: float = 12.0,
        stamp_rate: float = STAMP_RATE) -> dict:
    """Measure the demo window; returns a JSON-able dict (``status`` "ok" or why not)."""
    if shutil.which("Xvfb") is None:
        return {"status": "skipped: Xvfb not installed (the window is measured on a private X display)"}
    seconds = seconds or (8.0 if quick else 20.0)
    display, xvfb = start_xvfb()
    regions = Path(f"/tmp/pito_bench_live_{os.getpid()}.json")
    regions.unlink(missing_ok=True)
    load0 = os.getloadavg()
    try:
        env = display_env(display)
        app = subprocess.Popen([sys.executable, "-m", "pito_bench._live_window", "--run-app", str(regions),
                                "--seconds", str(seconds + 3), "--warmup", str(warmup)], env=env,
                               stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        try:
            res = _grab(display, regions, seconds, rate, stamp_rate, app)
        except RuntimeError as exc:
            app.kill()
            err = " | ".join((app.stderr.read() or "").strip().splitlines()[-3:])
            return {"status": f"failed: {exc}: {err}"}
        finally:
            try:
                app.wait(timeout=60)
            except subprocess.TimeoutExpired:
                app.kill()
                app.wait()
        frames = Path(str(regions) + ".frames")
        seen = res["scene"].pop("_seen")
        if frames.exists():
            res["scene"]["breakdown_ms"] = _breakdown(json.loads(frames.read_text()), seen)
    finally:
        xvfb.terminate()
        xvfb.wait()
        regions.unlink(missing_ok=True)
        Path(str(regions) + ".frames").unlink(missing_ok=True)
    res["status"] = "ok"
    res["first_frame"] = first_frame(2 if quick else 3)
    res["loadavg_before"], res["loadavg_after"], res["cpus"] = list(load0), list(os.getloadavg()), os.cpu_count()
    res["method"] = ("pito-app --demo window (devices in a child process) on Xvfb, grabbed from outside (whole views "
                     f"at {rate:g} Hz, the stamp pixels at {stamp_rate:g} Hz); frames = new data stamps seen per s; "
                     "latency = sample time → first read showing it")
    return res


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m pito_bench._live_window", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--json", action="store_true", help="print one JSON object (frames/s, latencies in ms)")
    p.add_argument("--quick", action="store_true", help="8 s of grabbing instead of 20 s")
    p.add_argument("--seconds", type=float, help="seconds of grabbing (s)")
    p.add_argument("--rate", type=float, default=100.0, help="whole-view grabs per second (Hz, default 100)")
    p.add_argument("--stamp-rate", type=float, default=STAMP_RATE,
                   help=f"reads of the two stamp pixels per second (Hz, default {STAMP_RATE:g}): the latency's resolution")
    p.add_argument("--first-frame", type=int, metavar="N",
                   help="only the start-up: N starts of the demo app timed to their first frame with data (s)")
    p.add_argument("--run-app", metavar="REGIONS", help=argparse.SUPPRESS)
    p.add_argument("--warmup", type=float, default=12.0, help="seconds from start to measuring (s, default 12)")
    args = p.parse_args(argv)
    if args.run_app:
        return _run_app(args.run_app, args.seconds or 20.0, args.warmup)
    if args.first_frame:
        ff = first_frame(args.first_frame)
        if args.json or ff["status"] != "ok":
            print(json.dumps(ff) if args.json else ff["status"])
        else:
            _print_first_frame(ff)
        return 0 if ff["status"] == "ok" or ff["status"].startswith("skipped") else 1
    out = run(args.quick, args.seconds, args.rate, args.warmup, args.stamp_rate)
    if args.json:
        print(json.dumps(out))
    elif out["status"] != "ok":
        print(out["status"])
    else:
        print(f"window {out['size'][0]}×{out['size'][1]} px, renderer {out['renderer']}, {out['grabs_per_s']:.0f} grabs/s, "
              f"load average {out['loadavg_before'][0]:.1f} → {out['loadavg_after'][0]:.1f} on {out['cpus']} CPUs")
        for key in ("scene", "plots"):
            r = out[key]
            L = r["latency_ms"]
            print(f"{key}: {r['frames_per_s']:.1f} frames/s with new data ({r['changed_grabs_per_s']:.1f} changed grabs/s); "
                  f"latency p50 {L['p50']:.1f} ms, p95 {L['p95']:.1f} ms, max {L['max']:.1f} ms (n = {L['n']})")
        if out["first_frame"].get("status") == "ok":
            _print_first_frame(out["first_frame"])
        bd = out["scene"].get("breakdown_ms")
        if bd:
            print("scene, per frame (p50 / p95 ms): sample → frame start "
                  f"{bd['sample_to_frame_start']['p50']:.1f} / {bd['sample_to_frame_start']['p95']:.1f}, frame "
                  f"{bd['frame']['p50']:.1f} / {bd['frame']['p95']:.1f}, frame end → screen "
                  f"{bd['frame_end_to_screen']['p50']:.1f} / {bd['frame_end_to_screen']['p95']:.1f}")
    return 0 if out["status"] == "ok" or out["status"].startswith("skipped") else 1


def _print_first_frame(ff: dict) -> None:
    def fmt(d):
        return "–" if d["median"] is None else f"{d['median']:.2f} s ({d['min']:.2f}–{d['max']:.2f}, n = {d['n']})"
    print(f"start-up (process start →, median (min–max)): window shown {fmt(ff['window_s'])}, first frame with data: "
          f"scene {fmt(ff['scene_s'])}, plots {fmt(ff['plots_s'])}; CPU used by then (app and its children) "
          f"{fmt(ff['cpu_s'])}, the app's own {fmt(ff['app_cpu_s'])}; load average {ff['loadavg'][0]:.1f}")


if __name__ == "__main__":
    sys.exit(main())

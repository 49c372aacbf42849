"""Live-scene benchmark for ``pito bench``: render rate and latency with the app's scene.

``python -m app.bench_live [--json] [--quick]`` renders off screen (pyvista
``Plotter(off_screen=True)``, EGL/OSMesa, anti-aliasing off) the cube with the app's own
:class:`app.scene.ContactGlyphs` — six contact spheres, force arrows and torsion rings,
created once and moved in place — and measures:

- frames per second with six moving contacts (glyph update + render per frame), against
  the bare cube (same run, ratio), and its two parts: the render alone with six contacts
  on screen, and the time of one ``ContactGlyphs.update`` call; and two variants of the
  same scene: torsion rings drawn opaque, and a 640×480 window;
- latency from a frame written into a pseudo-terminal at 1 kHz to the calibrated, solved
  bundle *and* the scene update call returning (``pito_core.bench.run_live`` with the
  glyph update as ``on_bundle``), processed as frames arrive; and at a 60 Hz timer with
  update + render, as the app's worker and view do;
- the CPU share of the process during those runs.

Lives in ``app`` because ``pito_core`` never imports Qt or VTK; ``pito bench`` runs it
in a subprocess when the app extras are installed.
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np

WIDTH, HEIGHT = 1024, 768


def _renderer_name(plotter) -> str:
    try:
        caps = plotter.ren_win.ReportCapabilities()
    except Exception:  # pragma: no cover - VTK without the call
        return "unknown"
    for line in caps.splitlines():
        if "renderer string" in line.lower():
            return line.split(":", 1)[1].strip()
    return "unknown"


def build_scene():
    """An off-screen plotter with the cube, face plates and the app's contact glyphs."""
    import pyvista as pv

    from pito_core.frames import FACES, CubeCore

    from .scene import BACKGROUND, CORE_COLOR, PLATE_COLOR, ContactGlyphs

    core = CubeCore()
    e = core.edge
    plotter = pv.Plotter(off_screen=True, window_size=(WIDTH, HEIGHT))
    plotter.disable_anti_aliasing()
    plotter.set_background(BACKGROUND)
    plotter.add_mesh(pv.Cube(x_length=0.9 * e, y_length=0.9 * e, z_length=0.9 * e), color=CORE_COLOR)
    for i in FACES:
        plate = pv.Box(bounds=(-0.42 * e, 0.42 * e, -0.42 * e, 0.42 * e, -0.04 * e, 0.0)).transform(core.face_pose(i), inplace=False)
        plotter.add_mesh(plate, color=PLATE_COLOR)
    plotter.camera_position = [(4.5 * e, -6 * e, 3.6 * e), (0, 0, 0), (0, 0, 1)]
    plotter.show(auto_close=False)
    return plotter, core


def _fps(plotter, seconds: float, step=None) -> float:
    n, t0 = 0, time.perf_counter()
    while True:
        if step is not None:
            step(n)
        plotter.render()
        n += 1
        dt = time.perf_counter() - t0
        if dt >= seconds and n >= 10:
            return n / dt


def _moving_contacts(core, k: int):
    """Six contacts (core frame) at animation step ``k``."""
    pts, nrm, frc = np.zeros((6, 3)), np.zeros((6, 3)), np.zeros((6, 3))
    for i in range(6):
        T = core.face_pose(i + 1)
        a = 0.05 * k + i
        p = np.array([0.012 * np.cos(a), 0.012 * np.sin(a), 0.0])
        pts[i] = T[:3, :3] @ p + T[:3, 3]
        nrm[i] = T[:3, 2]
        frc[i] = -nrm[i] * (5 + 2 * np.sin(a)) + T[:3, 0] * np.cos(a)
    return pts, nrm, frc, 0.01 * np.sin(0.05 * k + np.arange(6)), np.ones(6, bool)


def run(quick: bool = False) -> dict:
    import pyvista  # noqa: F401 - fail early if missing

    from pito_core.bench import run_live

    from .scene import ContactGlyphs

    seconds = 1.5 if quick else 5.0
    plotter, core = build_scene()
    renderer = _renderer_name(plotter)
    glyphs = ContactGlyphs(plotter, core.edge)

    def step(k):
        glyphs.update(*_moving_contacts(core, k))

    # alternate the scene and its baseline (best of two each), so load on the machine hits both
    fps_bare = fps_six = fps_static = 0.0
    for _ in range(2):
        glyphs.hide()
        fps_bare = max(fps_bare, _fps(plotter, seconds / 2))
        fps_six = max(fps_six, _fps(plotter, seconds / 2, step))
        fps_static = max(fps_static, _fps(plotter, seconds / 2))  # six on screen, not moved: the render alone
    shown = glyphs.shown_count()
    t0, n_up = time.perf_counter(), 100
    for k in range(n_up):
        step(k)
    update_ms = (time.perf_counter() - t0) / n_up * 1e3

    def step_opaque(k):  # design alternative: torsion rings drawn opaque (no translucent pass)
        step(k)
        for ring in glyphs.rings.values():
            ring.prop.opacity = 1.0

    fps_opaque = _fps(plotter, seconds / 2, step_opaque)
    plotter.window_size = [640, 480]  # software GL is fill-rate bound: the same scene, fewer pixels
    fps_small = _fps(plotter, seconds / 2, step)
    plotter.window_size = [WIDTH, HEIGHT]

    def update(bundle):
        glyphs.update(bundle["points"], bundle["normals"], bundle["forces"], bundle["torsions"], bundle["valid"])

    def update_render(bundle):
        update(bundle)
        plotter.render()

    duration = 2.0 if quick else 10.0
    lat_event = run_live(duration, on_bundle=update)
    lat_event["label"] = "as frames arrive, scene update"
    out = {
        "status": "ok",
        "render": {"fps_six_contacts": fps_six, "fps_bare": fps_bare, "ratio_bare": fps_six / fps_bare,
                   "fps_six_static": fps_static, "update_ms": update_ms, "fps_six_contacts_640x480": fps_small,
                   "fps_six_opaque_rings": fps_opaque,
                   "contacts_shown": shown, "renderer": renderer, "width": WIDTH, "height": HEIGHT,
                   "anti_aliasing": False, "seconds": seconds},
        "latency_event": lat_event,
    }
    if not quick:
        lat_render = run_live(duration, on_bundle=update_render, tick_hz=60.0)
        lat_render["label"] = "60 Hz timer, update + render"
        out["latency_render"] = lat_render
    plotter.close()
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m app.bench_live", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--json", action="store_true", help="print one JSON object (fps in 1/s, latencies in ms)")
    p.add_argument("--quick", action="store_true", help="short runs (1.5 s per render figure, 2 s live)")
    args = p.parse_args(argv)
    out = run(args.quick)
    if args.json:
        print(json.dumps(out))
    else:
        r = out["render"]
        print(f"renderer: {r['renderer']}, {r['width']}×{r['height']} px, anti-aliasing off")
        print(f"six contacts: {r['fps_six_contacts']:.1f} fps; bare cube: {r['fps_bare']:.1f} fps (ratio {r['ratio_bare']:.2f})")
        for key in ("latency_event", "latency_render"):
            if key in out:
                L = out[key]
                print(f"{L['label']}: latest-frame latency p50 {L['latest_latency_ms']['p50']:.1f} ms, "
                      f"p95 {L['latest_latency_ms']['p95']:.1f} ms; CPU share {100 * L['cpu_share']:.0f} %")
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""``pito-app``: the desktop application (PySide6 + pyvista + pyqtgraph), a thin shell over ``pito_core``.

Usage::

    pito-app                       # real devices (choose them in the wizard's Devices step)
    pito-app --demo                # simulated cube and reference, a looping grasp
    pito-app --calibration CAL.pitocal  # live view with a calibration file
    pito-app --pito PORT --ati HOST[:PORT]   # devices at these addresses (e.g. printed by `pito sim-devices`)
    pito-app --demo --screenshot live.png --page live   # render one screen to a PNG and exit
    pito-app --demo --record run.pitorec --duration 3600   # record for an hour with the window open, then quit
"""

from __future__ import annotations

import argparse
import gc
import sys
import threading
from concurrent.futures import Future

__all__ = ["main", "build_parser", "make_application"]

PAGES = ("live", "first", "mount", "load", "results")


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="pito-app",
        description="PITO desktop application: guided calibration wizard and live contact view. "
        "Units are SI (N, N·m, m, s); faces are numbered 1..6.",
    )
    p.add_argument("--demo", action="store_true",
                   help="run on the simulated devices (virtual cube on a pty, virtual Net F/T on loopback UDP)")
    p.add_argument("--calibration", metavar="FILE", help="calibration file for the live view")
    p.add_argument("--pito", metavar="PORT", help="connect the cube on this serial port at startup "
                   "(e.g. the port `pito sim-devices` prints)")
    p.add_argument("--ati", metavar="HOST", help="with --pito: the Net F/T at HOST or HOST:PORT (default: none)")
    p.add_argument("--seed", type=int, default=0, help="seed of the simulators (default 0)")
    p.add_argument("--rate", type=float, default=60.0, help="display ticks per second, Hz (default 60)")
    p.add_argument("--demo-k", type=int, default=1500,
                   help="samples per face for the startup calibration of the virtual cube (default 1500)")
    p.add_argument("--screenshot", metavar="FILE.png", help="render --page to this PNG and exit")
    p.add_argument("--page", choices=PAGES, default="live", help="screen for --screenshot (default live)")
    p.add_argument("--record", metavar="FILE.pitorec",
                   help="start recording both devices to FILE once the live view shows data (as the Record button)")
    p.add_argument("--duration", type=float, metavar="S",
                   help="quit after S seconds, closing any recording first (s; default: run until closed)")
    p.add_argument("--size", default="1440x900", help="window size for --screenshot, WxH pixels (at least 1280x800)")
    return p


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    if args.duration is not None and not args.duration > 0:
        print(f"pito-app: --duration: expected seconds > 0, got {args.duration}", file=sys.stderr)
        return 2
    if args.record and args.screenshot:
        print("pito-app: --record and --screenshot exclude each other", file=sys.stderr)
        return 2
    if args.screenshot and not args.demo:
        print("pito-app: --screenshot needs --demo (screens are rendered on the simulated devices)", file=sys.stderr)
        return 2
    period = 0.6 if args.screenshot else 1.5
    # no collection passes over the start-up's imports (a tenth of its CPU time); from the
    # application on, the GUI thread's collector runs them (make_application)
    gc.disable()
    # the demo's devices (two child processes, seconds of waiting) boot while Qt, VTK and the window load
    rig_boot = _boot_demo_devices(args.seed, period) if args.demo and not args.pito else None
    app = make_application()
    from .window import MainWindow  # deferred: Qt, pyvista, VTK and the window load only for a window (not --help)

    # screenshots: a brisker simulated operator (0.6 s per move-and-hold) so the wizard fills quickly
    window = MainWindow(demo=args.demo, calibration_path=args.calibration, rate=args.rate, seed=args.seed,
                        demo_k=args.demo_k, demo_period=period, wizard_k=600 if args.screenshot else 1000,
                        rig_boot=rig_boot)
    app.gc_collector.freeze_startup()  # no collection goes over the start-up's objects again
    if args.pito:
        window.connect_devices(args.pito, args.ati or "", False)
    if args.screenshot:
        from .screenshot import take_screenshot  # deferred with the window (above)

        w, h = (int(x) for x in args.size.lower().split("x"))
        if w < 1280 or h < 800:
            print("pito-app: --size must be at least 1280x800", file=sys.stderr)
            return 2
        ok = take_screenshot(window, args.page, args.screenshot, (w, h))
        window.shutdown()
        window.release_views()
        return 0 if ok else 1
    window.show()
    if args.record:
        _record_when_live(window, args.record)
    if args.duration:
        from PySide6.QtCore import QTimer  # deferred with QApplication (above)

        QTimer.singleShot(int(args.duration * 1000), window.close)
    code = app.exec()
    window.shutdown()
    window.release_views()
    return code


def make_application():
    """The ``QApplication`` as ``pito-app`` sets it up (also the start-up bench's, ``pito_bench._live_window``).

    Garbage cycles are collected in the GUI thread only (:mod:`app.gc_guard`; automatic collection
    stays off), one font with every glyph the app draws (‖ · ± σ, :mod:`app.fonts`), the style sheet."""
    # deferred: Qt loads only once a window is made (`pito-app --help` loads none)
    from PySide6.QtWidgets import QApplication

    from .fonts import install_app_font
    from .gc_guard import GuiThreadCollector
    from .theme import STYLE

    app = QApplication.instance() or QApplication(sys.argv[:1])
    app.setApplicationName("pito-app")
    app.gc_collector = GuiThreadCollector(app).install()  # cycles freed in the GUI thread only
    install_app_font(app)  # for Qt and matplotlib
    app.setStyleSheet(STYLE)
    return app


def _boot_demo_devices(seed: int, period: float):
    """Start the demo's simulated devices: a future of :class:`~app.demo.DemoDevices`.

    Both child processes (the simulated devices, the pipeline) start here, from the main thread,
    with the standard library only, and import while this process imports the core, Qt and VTK;
    a thread waits for their announcements and connects them."""
    from pito_core.pipeline import PipelineLaunch  # deferred: stdlib-only modules (pito_core/_lazy.py)
    from pito_core.sim import DevicesLaunch

    sim, pipe = DevicesLaunch(seed=seed, period=period), None
    try:
        pipe = PipelineLaunch()
        # deferred (`pito-app --help` loads no core), and here, in the main thread: imports in two
        # threads at once broke PySide6's first import (shiboken's signature bootstrap walks a
        # dictionary the other thread's imports grow: "dictionary changed size during iteration")
        from .demo import DemoDevices
    except BaseException:
        sim.close()
        if pipe is not None:
            pipe.close()
        raise

    hold = threading.Event()

    def boot():  # waits for the children's announcements and the hold (no interpreter lock held)
        try:
            future.set_result(DemoDevices(seed=seed, period=period, launches=(sim, pipe), hold=hold))
        except BaseException as exc:  # noqa: BLE001 - handed to the window, which reports it
            future.set_exception(exc)

    future = _HeldBoot(hold)
    # a daemon: a window that never asks for its devices (an error while it is built) does not keep
    # the process from exiting (the children end with it)
    threading.Thread(target=boot, name="demo-boot", daemon=True).start()
    return future


class _HeldBoot(Future):
    """The demo's devices booting: the pipeline opens them once :meth:`result` is first asked for.

    The window asks once it is built (``MainWindow.start_demo``): until then the children, imported
    and announced, do no work, so they leave the machine's cores to the window's build."""

    def __init__(self, hold: threading.Event):
        super().__init__()
        self.hold = hold

    def result(self, timeout=None):
        self.hold.set()
        return super().result(timeout)


def _record_when_live(window, path) -> None:
    """Press Record (to ``path``) as soon as the live view has shown a bundle."""
    from PySide6.QtCore import QTimer  # deferred: `pito-app --help` loads no Qt (main, above)

    def check():
        if window.live.bundles_shown > 0:
            window.live.record.blockSignals(True)
            window.live.record.setChecked(True)
            window.live.record.blockSignals(False)
            window.toggle_recording(True, path)
        else:
            QTimer.singleShot(100, check)

    check()


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())

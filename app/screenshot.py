"""``--screenshot``: bring one screen to a telling state on the simulators, grab it, write a PNG."""

from __future__ import annotations

import time

from PySide6.QtWidgets import QApplication

from .eventloop import process_for, wait_until
from .scene import grab_window
from .wizard.driver import run_to_page

__all__ = ["take_screenshot", "wait_until", "process_for"]


def _prepare_live(window) -> None:
    window.tabs.setCurrentWidget(window.live)
    # a moment of the grasp where the hand holds the object in the air, with some history
    live = window.live
    since = {}

    def holding():
        if window.calibration is None:  # the demo calibrates in the background at startup
            return False
        t_start = since.setdefault("t", time.monotonic())  # then 6 s of history in the plots
        g = live.scene.glyphs
        return (time.monotonic() - t_start > 6.0 and g.shown_count() >= 2 and not g.shown[5]
                and g.arrows[1].GetVisibility())

    wait_until(holding, timeout=60, step=0.02)


def _prepare_first(window) -> None:
    """The demo's first frame with forces: as soon as the live view has shown a calibrated bundle
    (the start-up time, timed from outside: ``farm-bench -- pito-app --demo --screenshot f.png --page first``)."""
    window.tabs.setCurrentWidget(window.live)
    live = window.live
    wait_until(lambda: window.calibration is not None and live._sums is not None, timeout=60, step=0.01)
    n0 = live.frames
    wait_until(lambda: live.frames > n0, timeout=10, step=0.01)  # drawn


def _prepare_mount(window) -> None:
    window.tabs.setCurrentWidget(window.wizard)
    window.model.set_mount(method="loaded_frame", flange="frame_hole", connected_face=6)
    window.wizard.go("mount")
    process_for(1.0)


def _prepare_load(window) -> None:

    window.tabs.setCurrentWidget(window.wizard)
    run_to_page(window, "load", partial_face=True, k=600)


def _prepare_results(window) -> None:
    """The results of the recommended method with its second mount and both validation passes (k = 600)."""
    window.tabs.setCurrentWidget(window.wizard)
    run_to_page(window, "results", method="unloaded_frame", flange="face", connected_face=6, k=600, timeout=200)


PREPARE = {"first": _prepare_first, "live": _prepare_live, "mount": _prepare_mount, "load": _prepare_load, "results": _prepare_results}


def take_screenshot(window, page: str, path, size=(1440, 900)) -> bool:
    """Show ``window`` at ``size`` (px), bring ``page`` up, grab the whole window to ``path``."""
    window.resize(*size)
    window.show()
    if page != "first":
        process_for(0.5)
    PREPARE[page](window)
    if page not in ("live", "first"):
        process_for(0.3)
    QApplication.processEvents()
    img = grab_window(window)  # the 3D views are native GL windows: painted in
    return bool(img.save(str(path)))

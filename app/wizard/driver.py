"""Drive the wizard through a calibration on the simulators (for tests, screenshots, demos).

Each step does what an operator does — click, confirm, wait for the page to say ready —
on the running application: nothing is bypassed, the data come from the simulated devices
through the real drivers.
"""

from __future__ import annotations

import os
import time

from ..eventloop import process_for, wait_until

__all__ = ["run_to_page", "complete_loading", "finish", "StepTimeout"]


class StepTimeout(RuntimeError):
    """A wizard step did not become ready in time."""


def _wait(pred, timeout, what):
    t0 = time.monotonic()
    ok = wait_until(pred, timeout=timeout)
    if os.environ.get("PITO_DRIVER_VERBOSE"):
        print(f"wizard driver: {what}: {'ready' if ok else 'TIMEOUT'} after {time.monotonic() - t0:.1f} s", flush=True)
    if not ok:
        raise StepTimeout(f"wizard: {what} not ready after {timeout:.0f} s")


def run_to_page(window, target: str = "results", *, method: str = "loaded_frame", flange: str = "frame_hole",
                connected_face: int = 6, k: int | None = None, required: float | None = None,
                partial_face: bool = False, timeout: float = 120.0, save_path=None, report_dir=None) -> None:
    """Run the wizard of ``window`` (a demo :class:`~app.window.MainWindow`) up to page ``target``.

    With ``partial_face`` the loading page stops after a few captures of the second face
    (a telling screenshot). With ``save_path`` / ``report_dir`` the results are accepted,
    saved and exported.
    """
    wiz = window.wizard
    model = window.model
    window.tabs.setCurrentWidget(wiz)
    wiz.go("method")
    model.set_mount(method=method, flange=flange, connected_face=connected_face)
    if k is not None:
        model.set_k(k)
    if required is not None:
        model.rules.required = required
    if target == "method":
        return
    wiz.go("mount")
    wiz.pages["mount"].confirm.setChecked(True)
    process_for(0.2)
    if target == "mount":
        return
    wiz.next.click()
    dev = wiz.pages["devices"]
    dev.simulated.setChecked(True)
    dev.connect_btn.click()
    _wait(dev.is_ready, 30, "devices")
    if target == "devices":
        return
    wiz.next.click()
    _record_tare(wiz)
    if target == "tare":
        return
    wiz.next.click()
    if partial_face:
        faces = list(model.faces)
        for face in faces[:2]:
            if model.current_face != face:
                model.set_current_face(face)
            if face == faces[1]:
                _wait(lambda: len(model.captures[face].captures) >= 4, timeout, f"face {face} captures")
                process_for(0.5)
                return
            _wait(lambda: model.captures[face].sufficient, timeout, f"face {face} coverage")
    complete_loading(window, timeout)
    if target == "load":
        return
    finish(window, save_path, report_dir)


def _record_tare(wiz) -> None:
    """On the tare page: record until the tare is kept (still, unloaded)."""
    tare = wiz.pages["tare"]
    tare.duration.setValue(1.0)
    process_for(0.5)  # the operator lets go
    for _ in range(3):
        tare.record.click()
        _wait(lambda: not tare.recording, 30, "tare")
        if tare.is_ready():
            break
        process_for(0.5)
    _wait(tare.is_ready, 1, "tare (stillness)")


def complete_loading(window, timeout: float = 120.0, *, stages: bool = True) -> None:
    """On the loading page: load every face that is not done yet, until Next is enabled.

    With ``stages`` also the stages after it: the validation pass, and the second mount (confirm
    it, record its tare, load its faces); it ends on the last loading page.
    """
    wiz, model = window.wizard, window.model
    _load_stage(window, timeout)
    while stages and model.stage + 1 < len(model.stages):
        wiz.next.click()
        if model.current.kind == "completing":
            _wait(lambda: wiz.current_name == "mount", 5, "second mount page")
            wiz.pages["mount"].confirm.setChecked(True)
            process_for(0.2)
            wiz.next.click()
            _record_tare(wiz)
            wiz.next.click()
        _load_stage(window, timeout)


def _load_stage(window, timeout: float) -> None:
    wiz, model = window.wizard, window.model
    load = wiz.pages["load"]
    for face in model.faces:
        if model.captures[face].sufficient:
            continue
        if model.current_face != face:
            model.set_current_face(face)
        _wait(lambda: model.captures[face].sufficient, timeout, f"face {face} coverage")
    process_for(0.2)
    _wait(load.is_ready, 5, "loading")


def finish(window, save_path=None, report_dir=None) -> None:
    """From the loading page: go to the results; accept, save and export if asked."""
    wiz, model = window.wizard, window.model
    wiz.next.click()
    res = wiz.pages["results"]
    _wait(lambda: model.calibration is not None, 60, "results")
    process_for(0.3)
    if save_path is not None or report_dir is not None:
        res.accept()
        if save_path is not None:
            res.save(save_path)
        if report_dir is not None:
            res.export(report_dir)
            _wait(lambda: not res.exporting, 60, "report export")
    process_for(0.3)

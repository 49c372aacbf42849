"""The main window: the calibration wizard and the live view as tabs, fed by one live feed."""

from __future__ import annotations

import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
from PySide6.QtCore import Qt, Signal
from PySide6.QtWidgets import QFileDialog, QLabel, QMainWindow, QMessageBox, QTabWidget, QWidget, QHBoxLayout

from pito_core.calibration import load_calibration
from pito_core.frames import CubeCore
from pito_core.io import calibration_hash, short_hash

from pito_core.pipeline import PipelineProcess, PipelineThread, RecordingReader
from pito_core.sim import reference_pose

from .filetypes import CALIBRATION_FILTER
from .demo import DEMO_METHOD, DEMO_OBJECT_MASS, DemoDevices, cached_demo_calibration, demo_cache_path, demo_calibration
from .live import LiveFeed, LiveView
from .tasks import TaskBar, cancel_tasks, run_in_process, run_task
from .objects import display_meshes, list_assemblies, load_assembly, weight
from .wizard.model import WizardModel
from .export_dialog import install_export_menu
from .live.lsl_toggle import install_lsl_toggle
from .health import install_health_indicator
from .press_test import install_press_test_menu
from .analysis import install_analysis_menu

__all__ = ["MainWindow"]


def _demo_calibration_job(k: int, seed: int, progress=None):
    """The demo's startup calibration, for :func:`~app.tasks.run_in_process` (SIMULATED data)."""
    if progress is not None:
        progress(None, f"simulating and fitting {k} samples per face")
    return demo_calibration(k=k, seed=seed)


class MainWindow(QMainWindow):
    """pito-app's window.

    Parameters
    ----------
    demo : bool
        Run on the simulated devices (labelled SIMULATED DEVICE everywhere).
    calibration_path : path, optional
        Calibration file for the live view; in demo mode without one, the virtual cube is
        calibrated at startup.
    rate : float
        Reads per second of a replayed recording (Hz).
    rig_boot : concurrent.futures.Future, optional
        Demo: the simulated devices (:class:`~app.demo.DemoDevices`) already booting (``pito-app`` starts
        them before it loads Qt's widgets and the window); without it the window starts them itself.

    Signals: ``recording_saved(str, int)`` — a recording was closed and is complete on disk
    (path, cube samples written); ``recording_failed(str)`` — starting or closing one failed.
    """

    recording_saved = Signal(str, int)
    recording_failed = Signal(str)

    def __init__(self, demo: bool = False, calibration_path=None, rate: float = 60.0, seed: int = 0,
                 demo_k: int = 1500, wizard_k: int = 1000, demo_speed: float = 1.0, demo_period: float = 1.5,
                 rig_boot=None):
        super().__init__()
        self.demo = demo
        self.seed = seed
        self.demo_speed, self.demo_period = demo_speed, demo_period
        # demo: the simulated devices' two processes boot (seconds of waiting) while the window is built
        self._rig_future = rig_boot if demo else None
        if demo and rig_boot is None:
            boot = ThreadPoolExecutor(1, thread_name_prefix="demo-boot")
            self._rig_future = boot.submit(DemoDevices, seed=seed, speed=demo_speed, period=demo_period)
            boot.shutdown(wait=False)  # the boot runs on; the thread ends with it
        self.core = CubeCore()
        self.setWindowTitle("pito — Patched Intrinsic Tactile Object" + ("  [SIMULATED DEVICE]" if demo else ""))
        self._build_tabs(wizard_k if demo else 10000)
        self._build_corner_and_status_bar(demo)
        self.rate = float(rate)
        self._start_feed(demo)
        self.errors: list[str] = []
        self.recording_path = None
        self.rig = None  # demo: the simulated devices and their scenarios
        self.calibration = None
        self.calibration_task = None  # the demo's startup calibration, while it runs
        self.assembly = None

        self._connect_views()
        if demo:
            self.model.simulated = True
        self.model.mount_changed.connect(self._mount_changed)
        self._mount_changed()
        self.set_assembly(self.live.assembly.currentText())
        if calibration_path is not None:
            self.load_calibration(calibration_path)
        if demo:
            self.start_demo(demo_k)

    def _build_tabs(self, wizard_k: int) -> None:
        """The wizard's model (collecting ``wizard_k`` samples on each face), the live view and the wizard as tabs.

        The wizard itself (two 3D views, a second of work) is built when first wanted (:attr:`wizard`):
        its tab holds a placeholder until then, so the live view's first frame does not wait for it."""
        self.model = WizardModel(self.core)
        self.model.set_k(wizard_k)
        self._wizard = None
        self._devices_status = ("not connected", False)  # the devices page's line, kept until the page exists
        self.live = LiveView(self.core, list_assemblies())
        self.tabs = QTabWidget()
        self.tabs.addTab(self.live, "Live view")
        self._wizard_placeholder = QLabel("Opening the calibration wizard…")
        self._wizard_placeholder.setAlignment(Qt.AlignmentFlag.AlignCenter)
        self.tabs.addTab(self._wizard_placeholder, "Calibration wizard")
        self.setCentralWidget(self.tabs)

    @property
    def wizard(self):
        """The calibration wizard (:class:`app.wizard.wizard.CalibrationWizard`), built on first use."""
        if self._wizard is None:
            self._build_wizard()
        return self._wizard

    def _build_wizard(self) -> None:
        """Build the wizard, put it in place of its tab's placeholder and connect it."""
        from .wizard.wizard import CalibrationWizard  # deferred: the live view's first frame does not need it

        wiz = self._wizard = CalibrationWizard(self.model)
        i = self.tabs.indexOf(self._wizard_placeholder)
        current = self.tabs.currentIndex() == i
        self.tabs.blockSignals(True)  # a swap of the tab's widget, not a change of tab
        try:
            self.tabs.removeTab(i)
            self.tabs.insertTab(i, wiz, "Calibration wizard")
            if current:
                self.tabs.setCurrentIndex(i)
        finally:
            self.tabs.blockSignals(False)
        self._wizard_placeholder.deleteLater()
        self._wizard_placeholder = None
        wiz.pages["devices"].connect_requested.connect(self.connect_devices)
        if self.demo:
            self._simulated_wizard()
        wiz.pages["devices"].set_connected(*self._devices_status)

    def _set_devices_status(self, text: str, ok: bool) -> None:
        """The wizard's devices page line (kept for the page if the wizard is not built yet)."""
        self._devices_status = (text, ok)
        if self._wizard is not None:
            self._wizard.pages["devices"].set_connected(text, ok)

    def _build_corner_and_status_bar(self, demo: bool) -> None:
        """The calibration's name and the SIMULATED badge beside the tabs; the task bar below; the size."""
        corner = QWidget()
        cl = QHBoxLayout(corner)
        cl.setContentsMargins(0, 0, 8, 0)
        self.badge = QLabel("SIMULATED DEVICE")
        self.badge.setObjectName("badge")
        self.badge.setVisible(demo)
        self.cal_label = QLabel("no calibration")
        self.cal_label.setObjectName("hint")
        cl.addWidget(self.cal_label)
        cl.addWidget(self.badge)
        self.tabs.setCornerWidget(corner, Qt.Corner.TopRightCorner)
        self.taskbar = TaskBar()  # file loads and fits in the background: progress and Cancel
        self.statusBar().addPermanentWidget(self.taskbar)
        self._loading_calibration = False
        self.resize(1440, 900)

    def _start_feed(self, demo: bool) -> None:
        """The live feed (bundles straight to the views) and the menus and indicators that use it."""
        # bundles from the running pipeline's thread straight to the views (app/live/feed.py)
        self.feed = LiveFeed(core=self.core)
        self.feed.bundle.connect(self.on_bundle)
        self.feed.contacts_sink = self.live.take_contacts  # the 3D view's contacts skip the GUI thread
        self.live.direct_contacts = True
        self.feed.error.connect(self.on_error)
        self.feed.recording_closed.connect(self._recording_closed)
        self.feed.recording_failed.connect(self._recording_failed)
        install_export_menu(self)
        install_lsl_toggle(self.live, self.feed, simulated=demo)
        install_health_indicator(self)
        install_press_test_menu(self)
        install_analysis_menu(self)  # File → Analyse recording

    def _connect_views(self) -> None:
        """The tabs', live view's and wizard's signals to this window's and the feed's handlers."""
        self.tabs.currentChanged.connect(self._tab_changed)
        self.live.tare_requested.connect(self._tare)
        self.live.scenario_requested.connect(self._scenario_requested)
        self.live.mass.valueChanged.connect(self._mass_changed)
        self.live.undo_tare_requested.connect(lambda: self.feed.post(self.feed.undo_tare))
        self.feed.tare_status.connect(self.live.set_tare_status)
        self.live.record_toggled.connect(self.toggle_recording)
        self.live.replay_requested.connect(self.open_replay)
        self.live.live_requested.connect(self.back_to_live)
        self.live.seek_requested.connect(self.seek)
        self.live.calibration_requested.connect(self.ask_calibration)
        self.live.assembly_requested.connect(self.set_assembly)
        self.live.show_uncertainty.toggled.connect(self._install_solver)
        self.model.result_changed.connect(self._wizard_result)

    def _simulated_wizard(self) -> None:
        """Demo: the wizard on the simulated devices; its tare and load pages move the simulated operator."""
        dev = self.wizard.pages["devices"]
        dev.simulated.setChecked(True)
        self.wizard.pages["tare"].operator = lambda face: self.rig and self.rig.set_operator_face(face)
        self.wizard.pages["load"].operator = lambda face: self.rig and self.rig.set_operator_face(face)

    def _tare(self) -> None:
        """The live view's Tare: the object's mass and base face as the operator set them, to the feed's thread."""
        support = self.live.tare_support()
        self.feed.post(lambda: self.feed.tare(support))

    def _mass_changed(self, mass: float) -> None:
        """The operator's object mass: its weight in the equilibrium plot (the assembly's default without one)."""
        self.live.equilibrium.set_weight(mass * 9.81 if mass > 0 else weight(self.assembly))

    def _scenario_requested(self, name: str) -> None:
        if self.rig is not None and self.tabs.currentWidget() is self.live:
            self.rig.set_scenario(name)

    def _live_scenario(self) -> str:
        """The demo scenario the live view shows (its combo box)."""
        return self.live.scenario.currentData() or "grasp"

    # ------------------------------------------------------------ demo
    def start_demo(self, k: int) -> None:
        """Open the simulated devices (pty + UDP) and, without a calibration, calibrate the virtual cube."""
        if self._rig_future is not None:  # booted while the window was built
            future, self._rig_future = self._rig_future, None
            self.rig = future.result()
        else:
            self.rig = DemoDevices(seed=self.seed, speed=self.demo_speed, period=self.demo_period)
        self.rig.set_scenario(self._live_scenario())
        self.live.scenario.setVisible(True)
        if not (self.assembly is not None and self.assembly.mass):
            self.live.mass.setValue(DEMO_OBJECT_MASS)  # the simulated object's
        source = self.rig.open_source()
        self.feed.post(lambda: self.feed.set_source(source))
        self._set_devices_status(f"✔ SIMULATED: {self.rig.describe()}", True)
        self.statusBar().showMessage(f"SIMULATED DEVICE: {self.rig.describe()}")
        if self.calibration is None and not self._loading_calibration:
            m = DEMO_METHOD
            cached = cached_demo_calibration(k, self.seed)
            if cached is not None:  # a previous start's, for today's code and simulator: forces at once
                self.set_calibration(cached, f"virtual cube, calibrated with the simulator ({m}, k = {k}/face)")
                self.cal_label.setToolTip(f"cached in {demo_cache_path(k, self.seed)}")  # a path of any length
                self.statusBar().showMessage(  # short enough for the bar at 1280 px (tests/app/test_demo_cache.py)
                    f"SIMULATED DEVICE — the virtual cube's calibration (simulator, {m}, k = {k}/face, "
                    f"1/cond = {cached.inverse_condition_number:.1e}), cached by an earlier start")
                return
            self.statusBar().showMessage(f"Calibrating the virtual cube (method '{m}', k = {k} per face)…")
            seed = self.seed

            def done(cal):
                if self.calibration is not None:  # a file was loaded meanwhile: it wins
                    return
                self.set_calibration(cal, f"virtual cube, calibrated at startup ({m}, k = {k}/face)")
                self.statusBar().showMessage(
                    f"SIMULATED DEVICE — the virtual cube's calibration (simulator, {m}, k = {k}/face, "
                    f"1/cond = {cal.inverse_condition_number:.1e}), fitted at startup")

            # in a child process (the fit's LAPACK holds the GIL): the window shows the raw demo meanwhile
            self.calibration_task = run_in_process(
                _demo_calibration_job, (k, seed), f"Calibrating the virtual cube ({m}, SIMULATED)", done,
                self.on_error, bar=self.taskbar, owner=self)

    def _tab_changed(self, index: int) -> None:
        if self._wizard_placeholder is not None and self.tabs.widget(index) is self._wizard_placeholder:
            self._build_wizard()  # its first showing: the wizard in place of the placeholder
        self.live.direct_contacts = self.tabs.widget(index) is self.live  # (bundles go to the wizard otherwise)
        if self.rig is None:
            return
        if self.tabs.widget(index) is self._wizard:
            self.rig.set_scenario("calibration")
            self._mount_changed()
        else:
            self.rig.set_scenario(self._live_scenario())

    def _mount_changed(self) -> None:
        self.model.T_core_ati = reference_pose(self.model.flange, self.model.connected_face, self.core)
        if self.rig is not None:
            self.rig.set_mount(self.model.flange, self.model.connected_face)

    # ------------------------------------------------------------ devices
    def connect_devices(self, port: str, host: str, simulated: bool) -> None:
        try:
            if simulated:
                if self.rig is None:
                    self.rig = DemoDevices(seed=self.seed, speed=self.demo_speed, period=self.demo_period)
                self.rig.set_scenario("calibration")
                self._mount_changed()
                source = self.rig.open_source()
                self.model.simulated = True
                self.badge.setVisible(True)
                text = f"✔ SIMULATED: {self.rig.describe()}"
            else:
                source = PipelineProcess(port, host or None)  # the drivers and the pipeline in their own process
                self.model.simulated = False
                text = f"✔ cube on {port}, reference at {host}"
        except Exception as exc:  # noqa: BLE001 - shown to the operator
            self._set_devices_status(f"✘ {exc}", False)
            return
        self.feed.post(lambda: self.feed.set_source(source))
        self._set_devices_status(text, True)

    # ------------------------------------------------------------ calibration and object
    def set_calibration(self, calibration, label: str = "") -> None:
        self.calibration = calibration
        self.feed.post(lambda: self.feed.set_calibration(calibration))
        h = short_hash(calibration_hash(calibration))  # the calibration's identity
        self.cal_label.setText(f"calibration: {label or calibration.method} [{h}]")
        self.cal_label.setToolTip("")
        self.cal_label.setStyleSheet("")
        self.live.set_notice(None)
        base = self.windowTitle().split("  — calibration")[0]
        self.setWindowTitle(f"{base}  — calibration {label or calibration.method} [{h}]")

    def load_calibration(self, path):
        """Load a calibration file in the background; returns the task (its ``done`` carries the calibration)."""
        self._loading_calibration = True

        def done(cal):
            self.set_calibration(cal, Path(path).name)
            self.statusBar().showMessage(f"Loaded calibration {path} ({cal.method})", 8000)

        def failed(message):
            self.calibration_failed(path, message)

        task = run_task(lambda progress: load_calibration(path), f"Loading {Path(path).name}", done, failed,
                        bar=self.taskbar, owner=self)
        task.ended.connect(lambda: setattr(self, "_loading_calibration", False))
        return task

    def calibration_failed(self, path, message: str) -> None:
        """A calibration file could not be loaded: say so in a dialog, the header and over the live view.

        The window goes on without a calibration (raw counts only: no forces, no contacts), and
        says that prominently until a calibration is loaded.
        """
        if self.calibration is None:
            self.cal_label.setText("NO CALIBRATION")
            self.cal_label.setStyleSheet("color: #ff6b6b; font-weight: bold;")
            self.live.set_notice(
                f"No calibration: {Path(path).name} could not be loaded ({message}). The view runs without "
                "one: no forces, no contacts, empty plots. Load a calibration file with “Load calibration…”.")
        self.statusBar().showMessage(f"calibration {Path(path).name} not loaded", 15000)
        QMessageBox.warning(self, "Calibration", f"Could not load {path}:\n{message}\n\n"
                            + ("The live view runs without a calibration." if self.calibration is None
                               else "The calibration in use is kept."))

    def ask_calibration(self) -> None:
        path, _ = QFileDialog.getOpenFileName(self, "Load a calibration", "", CALIBRATION_FILTER)
        if path:
            self.load_calibration(path)

    def _wizard_result(self) -> None:
        if self.model.calibration is not None and self.model.accepted:
            self.set_calibration(self.model.calibration, "from the wizard")

    def set_assembly(self, name: str) -> None:
        try:
            self.assembly = load_assembly(name)
        except Exception as exc:  # noqa: BLE001
            self.statusBar().showMessage(f"assembly {name}: {exc}", 8000)
            self.assembly = None
        self.live.scene.set_patches(display_meshes(self.assembly, name))  # a library name: cached by its description
        if self.assembly is not None and self.assembly.mass:
            self.live.mass.setValue(self.assembly.mass)
        cog = getattr(self.assembly, "center_of_gravity", None)
        self.live.cog = np.zeros(3) if cog is None else np.asarray(cog, dtype=float)
        self._mass_changed(self.live.mass.value())
        self._install_solver()
        if self.rig is not None:
            self.rig.set_assembly(self.assembly)

    def _install_solver(self, *_) -> None:
        """Contact solver for the pipeline; the Cramér–Rao covariance only while it is displayed (~4× the cost).

        The face wrenches' covariance is the calibration's own (fit and gauge noise, at the
        latest counts): the ellipsoids show how well this calibration places the contact.
        """
        cov = "calibration" if self.live.show_uncertainty.isChecked() else None
        assembly = self.assembly
        self.feed.post(lambda: self.feed.set_assembly(assembly, cov))

    # ------------------------------------------------------------ record / replay
    def toggle_recording(self, on: bool, path=None) -> None:
        """Start recording (asks for the file unless ``path``) or stop it.

        Stopping is done by the feed's command thread, which closes the file (end marker written, flushed to
        disk) and then emits ``recording_closed``: :attr:`recording_saved` follows, once the
        file is complete.
        """
        if not on:
            self.feed.post(self.feed.stop_recording)
            if self.recording_path is not None:
                self.statusBar().showMessage(f"Closing the recording {self.recording_path}…")
            return
        if path is None:
            path, _ = QFileDialog.getSaveFileName(self, "Record to", "pito-recording.pitorec",
                                                  "PITO recording (*.pitorec);;All files (*)")
        if not path:
            self.live.record.blockSignals(True)
            self.live.record.setChecked(False)
            self.live.record.setText("● Record")
            self.live.record.blockSignals(False)
            return
        self.recording_path = str(path)
        simulated = self.model.simulated or self.demo
        # the object's mass as the operator gave it (the analysis's force residual needs it)
        meta = {"mass_kg": self.live.mass.value()} if self.live.mass.value() > 0 else {}
        self.feed.post(lambda: self.feed.start_recording(path, simulated, meta))
        self.statusBar().showMessage(f"Recording both devices to {path}" + (" (SIMULATED)" if simulated else ""))

    def _recording_closed(self, path: str, rows: int) -> None:
        self.statusBar().showMessage(f"Recording saved to {path} ({rows} cube samples)", 8000)
        self.recording_saved.emit(path, rows)

    def _recording_failed(self, message: str) -> None:
        self.statusBar().showMessage(f"recording: {message}", 8000)
        if self.live.record.isChecked():  # the recording did not start (or is over): the button says so
            self.live.record.blockSignals(True)
            self.live.record.setChecked(False)
            self.live.record.setText("● Record")
            self.live.record.blockSignals(False)
        self.recording_failed.emit(message)

    def open_replay(self, path=None) -> None:
        if path is None:
            path, _ = QFileDialog.getOpenFileName(self, "Replay a recording", "",
                                                  "PITO recording (*.pitorec);;All files (*)")
        if not path:
            return

        def done(reader):
            # the recording read and processed in a thread of this process, at the replay rate
            source = PipelineThread(reader, core=self.core, rate_hz=self.rate)
            self.feed.post(lambda: self.feed.set_source(source))
            self.live.set_replay_mode(True, reader.duration)
            self._set_devices_status(f"▶ replaying {Path(path).name} (recorded data, not live devices)", True)

        def failed(message):
            QMessageBox.warning(self, "Replay", f"Could not open {path}:\n{message}")

        # reading a recording (checksums, pairing) can take seconds: in the background
        return run_task(lambda progress: RecordingReader(path), f"Opening {Path(path).name}", done, failed,
                        bar=self.taskbar, owner=self)

    def seek(self, t: float) -> None:
        self.feed.post(lambda: self.feed.seek(t))

    def back_to_live(self) -> None:
        self.live.set_replay_mode(False)
        if self.rig is not None:
            source = self.rig.open_source()
            self.feed.post(lambda: self.feed.set_source(source))
            self._set_devices_status(f"✔ SIMULATED: {self.rig.describe()}", True)
        else:
            self._set_devices_status("not connected", False)

    # ------------------------------------------------------------ data
    def on_error(self, message: str) -> None:
        self.errors.append(message)
        print(f"pito-app: acquisition: {message}", file=sys.stderr)
        self.statusBar().showMessage(f"acquisition: {message}", 8000)

    def on_bundle(self, bundle) -> None:
        try:
            if self.tabs.currentWidget() is self.live:
                self.live.on_bundle(bundle)
            elif self._wizard is not None:
                self._wizard.on_bundle(bundle)
        finally:
            self.feed.ack()

    def closeEvent(self, event):  # noqa: N802
        self.shutdown()
        super().closeEvent(event)

    def shutdown(self) -> None:
        """Cancel the window's background tasks, stop the feed and the devices (idempotent).

        A task still running (the demo's startup calibration, a file load, the wizard's fit)
        is cancelled here, so none of its callbacks reaches the window once it is gone.
        """
        cancel_tasks(self)
        self.feed.stop()
        if self.rig is not None:
            self.rig.close()
            self.rig = None

    def release_views(self) -> None:
        scenes = [self.live.scene]
        if self._wizard is not None:
            scenes += [self._wizard.pages["mount"].scene, self._wizard.pages["load"].scene]
        for scene in scenes:
            scene.close_scene()

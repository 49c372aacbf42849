"""The acquisition worker: takes the core's one pipeline's bundles in a thread, emits one per display tick.

The worker lives in its own ``QThread``. A timer in that thread ticks at the display rate
(default 60 Hz). Devices (real or simulated) are a :class:`pito_core.pipeline.PipelineProcess`:
the drivers, :class:`pito_core.pipeline.Pipeline` — pairing with the reference by the device
clocks, tare, calibration of every new sample, contacts of the latest — and the recorder run
in a child process; the worker takes each bundle as it arrives (the process calls back from
its receiving thread) and hands it to the GUI at once, or merged with the next if the GUI is
still drawing (so the drawing never waits for the devices' interpreter lock, nor they for
it, and no tick period is added to the latency). A recording (replay) is
read in this process: each tick reads its new rows (:class:`~pito_core.pipeline.RecordingReader`)
and runs the same :class:`~pito_core.pipeline.Pipeline` here. Recording runs beside the
pipeline, in the acquisition's collecting thread, so a slow screen never loses samples
(STYLE.md item 10).

Commands from the GUI thread (set calibration, tare, record, ...) are posted as callables
to a thread-safe queue the worker runs at the start of its next tick.
"""

from __future__ import annotations

import queue
import threading
import time
from typing import Callable, Protocol

import numpy as np
from PySide6.QtCore import QObject, Qt, QThread, QTimer, Signal, Slot

from pito_core.frames import CubeCore
from pito_core.interop import provenance_meta
from pito_core.pipeline import LiveBundle, NewSamples, Pipeline, TareRefused, face_sums

__all__ = ["Source", "Bundle", "DeviceWorker", "WorkerThread", "face_sums", "merge_bundles"]

#: What the worker emits: the core pipeline's bundle (one type from the pipeline to the screen).
Bundle = LiveBundle


class Source(Protocol):
    """What the worker reads: ``pito_core.pipeline.AcquisitionReader`` (devices, real or
    simulated) or ``RecordingReader`` (a recording).

    ``read()`` returns the rows that arrived since the previous call as
    :class:`~pito_core.pipeline.NewSamples`; ``has_reference`` says whether a reference
    device is connected (cube samples then wait for their reference record).
    """

    simulated: bool
    has_reference: bool

    def read(self) -> NewSamples: ...

    def stats(self) -> dict: ...

    def close(self) -> None: ...


def merge_bundles(old: Bundle, new: Bundle) -> Bundle:
    """One bundle with the samples of both (old first) and the latest derived values of ``new``."""
    return old.merged(new)


class DeviceWorker(QObject):
    """Reads a :class:`Source`, runs :class:`~pito_core.pipeline.Pipeline`, emits :data:`Bundle`.

    Parameters
    ----------
    rate : float
        Display ticks per second (Hz).
    core : CubeCore, optional

    Signals: ``bundle(object)``, ``error(str)``; ``recording_closed(str, int)`` once a
    recording's file is closed and complete on disk (path, cube samples written), whoever
    stopped it (the Record button, a change of source, the shutdown);
    ``recording_failed(str)`` when starting or closing a recording failed.
    """

    bundle = Signal(object)
    error = Signal(str)
    recording_closed = Signal(str, int)
    recording_failed = Signal(str)
    #: the tare in force or a refusal, in words; and whether a tare can be undone
    tare_status = Signal(str, bool)
    _wake = Signal()  # posted commands are waiting (queued to the worker's thread)
    _arrived = Signal()  # a pipeline process sent a bundle (emitted in its receiving thread)
    _acked = Signal()  # the GUI has shown the last bundle (emitted in the GUI thread)

    def __init__(self, rate: float = 60.0, core: CubeCore | None = None):
        super().__init__()
        self.rate = float(rate)
        self.core = core or CubeCore()
        self.pipeline = Pipeline(core=self.core)
        self.source: Source | None = None
        self._commands: queue.Queue = queue.Queue()
        self._timer: QTimer | None = None
        self._recording = None  # (acquisition, cube cursor at start) while recording
        self.ticks = 0
        self.emitted = 0
        self._pending: Bundle | None = None
        self._consumed = threading.Event()
        self._consumed.set()
        self._recording_path: str | None = None
        #: the last tare taken live (its event); a replay applies its own, Back to live this one again
        self.live_tare: dict | None = None
        #: ``fn(contacts, sample_time)`` called in the worker's thread with each bundle's contacts,
        #: before the bundle goes to the GUI thread (the live view's drawing thread takes them
        #: from here, so the 3D view does not wait for a busy GUI thread); must be thread-safe
        self.contacts_sink: Callable | None = None
        # a posted command runs as soon as the worker's thread is free, not at the next tick
        self._wake.connect(self._run_commands, Qt.ConnectionType.QueuedConnection)
        # a pipeline process's bundle is taken when it arrives, not at the next tick (the ticks
        # remain for replays and as a fallback); an unsent bundle goes as soon as the GUI is free
        self._arrived.connect(self.tick, Qt.ConnectionType.QueuedConnection)
        self._acked.connect(self._emit_pending, Qt.ConnectionType.QueuedConnection)

    # ------------------------------------------------------------ compatibility views
    @property
    def calibration(self):
        return self.pipeline.calibration

    @property
    def cog(self) -> np.ndarray:
        return self.pipeline.cog

    @cog.setter
    def cog(self, value) -> None:
        self.pipeline.cog = np.asarray(value, dtype=float)

    # ------------------------------------------------------------ thread side
    @Slot()
    def start(self) -> None:
        """Start ticking (call in the worker's thread: connect to ``QThread.started``)."""
        self._timer = QTimer()
        self._timer.setInterval(max(1, int(round(1000.0 / self.rate))))
        self._timer.timeout.connect(self.tick)
        self._timer.start()

    @Slot()
    def stop(self) -> None:
        if self._timer is not None:
            self._timer.stop()
        self._run_commands()
        self.stop_recording()
        self._listen(None)
        if self.source is not None:
            try:
                self.source.close()
            except Exception as exc:  # noqa: BLE001 - closing must not fail the shutdown; say so
                self.error.emit(f"closing the source: {type(exc).__name__}: {exc}")
            self.source = None

    def post(self, fn: Callable[[], None]) -> None:
        """Run ``fn()`` in the worker thread as soon as it is free, at the latest before its next tick (thread-safe)."""
        self._commands.put(fn)
        self._wake.emit()

    @Slot()
    def _run_commands(self) -> None:
        while True:
            try:
                fn = self._commands.get_nowait()
            except queue.Empty:
                return
            try:
                fn()
            except Exception as exc:  # noqa: BLE001 - report, keep the worker alive
                self.error.emit(f"{type(exc).__name__}: {exc}")

    @Slot()
    def tick(self) -> None:
        """Read the source, run the pipeline, emit one bundle (or merge it into the unsent one)."""
        self._run_commands()
        if self.source is None:
            return
        try:
            if self._remote:  # the pipeline ran in the source's own process: take its bundles
                b = self.source.take()
                if b is None:
                    return
            else:
                b = self.pipeline.feed(self.source.read())
                b.stats = self.source.stats()
                b.recorded = self.recorded()
        except Exception as exc:  # noqa: BLE001 - shown to the operator, the worker keeps running
            self.error.emit(f"{type(exc).__name__}: {exc}")
            return
        if "position" in b.stats:
            b.replay_position = b.stats["position"]
            b.replay_duration = b.stats.get("duration")
        sink = self.contacts_sink
        if sink is not None and b.contacts is not None and np.isfinite(b.contacts_time):
            try:
                sink(b.contacts, b.contacts_time)
            except Exception as exc:  # noqa: BLE001 - shown to the operator, the worker keeps running
                self.error.emit(f"showing contacts: {type(exc).__name__}: {exc}")
        self.ticks += 1
        self._pending = b if self._pending is None else self._pending.merged(b)
        self._emit_pending()

    @Slot()
    def _emit_pending(self) -> None:
        """Emit the unsent bundle if the GUI is done with the previous one."""
        if self._pending is not None and self._consumed.is_set():
            self._consumed.clear()
            pending, self._pending = self._pending, None
            self.emitted += 1
            self.bundle.emit(pending)

    def ack(self) -> None:
        """The GUI has shown the last bundle (thread-safe): the unsent one, if any, goes now.

        Without it a slow screen would queue bundles without end; with it, samples that
        arrive meanwhile are merged into the next bundle (none is lost).
        """
        self._consumed.set()
        self._acked.emit()

    def _listen(self, listener) -> None:
        """Have the source call ``listener`` on each new bundle (sources that can: ``PipelineProcess``)."""
        if self.source is not None and hasattr(self.source, "set_listener"):
            self.source.set_listener(listener)

    def process(self, samples: NewSamples) -> Bundle:
        """Run the pipeline on one read (also usable without a thread, e.g. in tests)."""
        return self.pipeline.feed(samples)

    # ------------------------------------------------------------ commands (run in the thread)
    @property
    def _remote(self) -> bool:
        """The source runs the pipeline itself (``PipelineProcess``): this worker only takes its bundles."""
        return bool(getattr(self.source, "runs_pipeline", False))

    def set_source(self, source) -> None:
        """Read ``source`` from now on (a reader, or a ``PipelineProcess`` that runs the pipeline itself)."""
        if self.source is not None and self.source is not source:
            self.stop_recording()
            self._listen(None)
            self.source.close()
        self.source = source
        self.pipeline.has_reference = bool(getattr(source, "has_reference", True))
        self.pipeline.reset()
        if not self.replaying and self.live_tare is not None and self.pipeline.tare_in_force is not self.live_tare:
            self.pipeline.apply_tare(self.live_tare)  # Back to live: the live tare again, not the replay's
        if self._remote:  # the settings shown in this process hold in the source's process too
            source.reset()
            source.set_calibration(self.pipeline.calibration)
            source.set_assembly(self.pipeline.assembly, self.pipeline.wrench_cov)
            if self.live_tare is not None:
                source.apply_tare(self.live_tare)
            self._listen(self._arrived.emit)
        self.tare_status.emit(self.tare_text(), self.pipeline.tare_in_force is not None)

    def set_calibration(self, calibration) -> None:
        self.pipeline.set_calibration(calibration)
        self.live_tare = None  # a new calibration starts from its own zero
        self.tare_status.emit(self.tare_text(), False)
        if self._remote:
            self.source.set_calibration(calibration)

    def set_assembly(self, assembly, wrench_cov=None) -> None:
        """Contacts on this object's patches (``Assembly``, library name or None); covariance with ``wrench_cov``."""
        self.pipeline.set_assembly(assembly, wrench_cov)
        if self._remote:
            self.source.set_assembly(self.pipeline.assembly, self.pipeline.wrench_cov)

    def tare(self) -> None:
        """Zero the face wrenches and the reference on the last 0.5 s — only if still and unloaded.

        The checks are the wizard's (:func:`pito_core.pipeline.check_tare`); a refusal is
        reported with its reason on ``tare_status``. The tare is recorded as an event when
        recording, and kept as the live tare (it survives a replay: Back to live restores it).
        """
        if self.replaying:
            self.tare_status.emit("✘ Tare: not during a replay (the recording's own tares apply)", False)
            return
        try:
            if self._remote:  # checked and tared where the samples are (and recorded there)
                event = self.source.tare(0.5, True)
                self.pipeline.apply_tare(event)
            else:
                event = self.pipeline.tare(0.5, check=True)
                if self._recording is not None:
                    self._recording[0].record_event(event)
        except ValueError as exc:  # TareRefused (reason), or nothing seen yet
            reason = exc.check.reason if isinstance(exc, TareRefused) else str(exc).removeprefix("tare refused: ")
            self.tare_status.emit(f"✘ Tare refused: {reason}", self.pipeline.tare_in_force is not None)
            return
        self.live_tare = event
        self.tare_status.emit(self.tare_text(), True)

    def undo_tare(self) -> None:
        """Bring back the tare before the last one (the calibration's own zero if none)."""
        if self.replaying:
            return
        try:
            if self._remote:
                self.source.undo_tare()
                self.pipeline.undo_tare()
            else:
                event = self.pipeline.undo_tare()
                if self._recording is not None:
                    self._recording[0].record_event(event)
        except ValueError as exc:
            self.tare_status.emit(f"✘ Undo tare: {exc}", self.pipeline.tare_in_force is not None)
            return
        self.live_tare = self.pipeline.tare_in_force
        self.tare_status.emit(self.tare_text(), self.live_tare is not None)

    def tare_text(self) -> str:
        """The tare in force, in words."""
        ev = self.pipeline.tare_in_force
        if self.replaying:
            return "Tare: as recorded (replay)"
        if ev is None:
            return "Tare: the calibration's own zero"
        when = time.strftime("%H:%M:%S", time.localtime(ev.get("taken_at", time.time())))
        return f"Tare: taken {when} ({ev.get('duration', 0.5):g} s, still and unloaded)"

    @property
    def replaying(self) -> bool:
        return self.source is not None and hasattr(self.source, "seek")

    def start_recording(self, path, simulated: bool = False, meta: dict | None = None) -> None:
        """Record every raw sample of both devices to ``path`` (``pito-recording`` format).

        Raises
        ------
        ValueError
            The source is not a running acquisition (e.g. a replay).
        """
        acq = self.source if self._remote else getattr(self.source, "acq", None)
        if acq is None:
            message = "recording: the source is not a device acquisition (a replay cannot be recorded)"
            self.recording_failed.emit(message)
            raise ValueError(message)
        self.stop_recording()
        info = {"simulated": bool(simulated), "source": "pito-app"}
        info.update(provenance_meta(self.pipeline))  # the calibration and object shown (docs/interop.md)
        info.update(meta or {})
        try:
            acq.open_recording(path, info)  # written where the devices are read (their own process in the app)
        except Exception as exc:
            self.recording_failed.emit(f"{path}: {type(exc).__name__}: {exc}")
            raise
        self._recording = (acq, None if self._remote else acq.cursors()[0])
        self._recording_path = str(path)

    def recorded(self) -> int:
        """Cube samples recorded so far in the current recording (0 when not recording)."""
        if self._recording is None or self._recording[1] is None:
            return 0  # (a pipeline process counts them itself: LiveBundle.recorded)
        acq, c0 = self._recording
        return acq.cursors()[0] - c0

    def stop_recording(self) -> int:
        """Close the recording (returns once the file is closed); returns the cube samples written."""
        rec, self._recording = self._recording, None
        if rec is None:
            return 0
        path, self._recording_path = self._recording_path, None
        try:
            closed = rec[0].close_recording()
        except Exception as exc:
            self.recording_failed.emit(f"closing {path}: {type(exc).__name__}: {exc}")
            raise
        rows = int(closed.get("rows", {}).get("pito", 0))
        self.recording_closed.emit(str(closed.get("path", path)), rows)  # the file is complete now
        return rows


class WorkerThread:
    """A :class:`DeviceWorker` moved to its own ``QThread``, started and stopped together."""

    def __init__(self, worker: DeviceWorker):
        self.worker = worker
        self.thread = QThread()
        self.thread.setObjectName("pito-acquisition")
        worker.moveToThread(self.thread)
        self.thread.started.connect(worker.start)

    def start(self) -> None:
        self.thread.start()

    def stop(self, timeout_ms: int = 3000) -> None:
        if not self.thread.isRunning():
            return
        done = {"ok": False}

        def _stop():
            self.worker.stop()
            done["ok"] = True
            self.thread.quit()

        self.worker.post(_stop)
        if not self.thread.wait(timeout_ms):
            self.thread.quit()
            self.thread.wait(timeout_ms)

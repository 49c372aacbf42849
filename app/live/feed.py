"""The live feed: bundles from the one pipeline that runs straight to the views, and the operator's settings to it.

A source is a :class:`pito_core.pipeline.PipelineProcess` (devices, real or simulated: the
drivers, the pipeline and the recorder in a child process) or a
:class:`pito_core.pipeline.PipelineThread` (a recording replayed in this process). Both hand each
:class:`~pito_core.pipeline.LiveBundle` to :meth:`LiveFeed.deliver` in their own thread (the
process's receiving thread, the replay's thread). There:

- the bundle's contacts go to the 3D view's drawing thread at once (:attr:`LiveFeed.contacts_sink`),
  without waiting for the GUI thread;
- the bundle goes to the GUI thread (the ``bundle`` signal, queued) if the GUI has shown the
  previous one (:meth:`LiveFeed.ack`); else it is merged into the unsent one
  (:meth:`LiveBundle.merged`: every sample once, the newest state), so a slow screen never
  queues work nor loses samples.

Settings (calibration, object, tare, recording) are the operator's, kept here and sent once to
the source's pipeline (and to a new source when the source changes); what the GUI shows of the
pipeline's state — the tare in force — is the source's (:attr:`tare_in_force`), the
calibration's coverage comes with each bundle (``measured``). Requests to a source can wait for
its answer (a file closing), so the GUI thread :meth:`~LiveFeed.post`\\ s them to the feed's
command thread, which runs them in order.
"""

from __future__ import annotations

import queue
import threading
import time
from typing import Callable

import numpy as np
from PySide6.QtCore import QObject, Qt, Signal, Slot

from pito_core.frames import CubeCore
from pito_core.interop import provenance_meta
from pito_core.pipeline import LiveBundle, TareRefused

__all__ = ["LiveFeed"]


class LiveFeed(QObject):
    """The route from the running pipeline to the views, and the settings it runs with.

    Parameters
    ----------
    core : CubeCore, optional

    Attributes
    ----------
    source : PipelineProcess or PipelineThread or None
        What runs the pipeline now.
    calibration, assembly, wrench_cov
        The settings the operator chose (the source's pipeline has them once accepted).
    sample_contacts : bool
        The bundles carry every sample's contacts (``arrived_contacts``; the LSL publisher asks).
    live_tare : dict or None
        The last tare taken live (its event): a replay applies its own, Back to live this one again.
    contacts_sink : callable or None
        ``fn(contacts, sample_time)``, called in the source's thread with each bundle's contacts
        (the live view's drawing thread takes them there); must be thread-safe.
    delivered, emitted : int
        Bundles received from sources, and bundles sent to the GUI (fewer: merged while it drew).

    Signals: ``bundle(object)`` (a :class:`LiveBundle`, in the GUI thread; answer with
    :meth:`ack`), ``error(str)``, ``tare_status(str, bool)`` (the tare in force or a refusal, in
    words; whether it can be undone), ``recording_closed(str, int)`` once a recording's file is
    closed and complete (path, cube samples), ``recording_failed(str)``.
    """

    bundle = Signal(object)
    error = Signal(str)
    recording_closed = Signal(str, int)
    recording_failed = Signal(str)
    tare_status = Signal(str, bool)
    _acked = Signal()  # the GUI has shown the last bundle (emitted in the GUI thread, queued)

    def __init__(self, core: CubeCore | None = None):
        super().__init__()
        self.core = core or CubeCore()
        self.source = None
        self.calibration = None
        self.assembly = None
        self.wrench_cov = None
        self.live_tare: dict | None = None
        self.sample_contacts = False
        self.contacts_sink: Callable | None = None
        self.delivered = 0
        self.emitted = 0
        self._lock = threading.Lock()  # _pending, _consumed: the source's thread and the GUI thread
        self._pending: LiveBundle | None = None
        self._consumed = True
        self._recording_path: str | None = None
        self._commands: queue.Queue = queue.Queue()
        self._acked.connect(self._emit_pending, Qt.ConnectionType.QueuedConnection)
        self._thread = threading.Thread(target=self._serve, name="pito-commands", daemon=True)
        self._thread.start()

    # ------------------------------------------------------------ bundles (the source's thread)
    def deliver(self, b: LiveBundle) -> None:
        """A bundle from the source (its thread): contacts to the drawing thread, the bundle to the GUI or merged."""
        self.delivered += 1
        sink = self.contacts_sink
        if sink is not None and b.contacts is not None and np.isfinite(b.contacts_time):
            try:
                sink(b.contacts, b.contacts_time)
            except Exception as exc:  # noqa: BLE001 - shown to the operator, the bundles go on
                self.error.emit(f"showing contacts: {type(exc).__name__}: {exc}")
        with self._lock:
            self._pending = b if self._pending is None else self._pending.merged(b)
        self._emit_pending()

    @Slot()
    def _emit_pending(self) -> None:
        """Send the unsent bundle if the GUI is done with the previous one."""
        with self._lock:
            if self._pending is None or not self._consumed:
                return
            self._consumed = False
            b, self._pending = self._pending, None
            self.emitted += 1
        self.bundle.emit(b)

    def ack(self) -> None:
        """The GUI has shown the last bundle (thread-safe): the unsent one, if any, goes now (queued)."""
        with self._lock:
            self._consumed = True
        self._acked.emit()

    def _on_source_error(self, message: str) -> None:
        self.error.emit(message)

    # ------------------------------------------------------------ commands (the command thread)
    def post(self, fn: Callable[[], None]) -> None:
        """Run ``fn()`` in the feed's command thread, after those posted before (thread-safe)."""
        self._commands.put(fn)

    def _serve(self) -> None:
        while True:
            fn = self._commands.get()
            if fn is None:
                return
            try:
                fn()
            except Exception as exc:  # noqa: BLE001 - report, keep serving
                self.error.emit(f"{type(exc).__name__}: {exc}")

    def sync(self, timeout: float = 10.0) -> bool:
        """Wait until the commands posted so far have run (not from the command thread); False on timeout."""
        done = threading.Event()
        self.post(done.set)
        return done.wait(timeout)

    def stop(self, timeout: float = 10.0) -> None:
        """Close the recording and the source, end the command thread (idempotent; call from the GUI thread)."""
        if not self._thread.is_alive():
            return
        self.post(self._close_source)
        self._commands.put(None)
        self._thread.join(timeout)

    def _close_source(self) -> None:
        """Stop taking the source's bundles, close its recording (said on ``recording_closed``), close it."""
        source = self.source
        if source is None:
            return
        source.set_sink(None)
        try:
            self.stop_recording()
        finally:
            self.source = None
            source.close()

    # ------------------------------------------------------------ settings (run them through post)
    @property
    def replaying(self) -> bool:
        return bool(getattr(self.source, "replay", False))

    @property
    def tare_in_force(self) -> dict | None:
        """The source pipeline's tare in force (None: the calibration's own zero, or no source)."""
        return None if self.source is None else self.source.tare_in_force

    def set_source(self, source) -> None:
        """Take bundles from ``source`` from now on (the previous one is closed); give it the settings it lacks."""
        if self.source is not None and self.source is not source:
            self._close_source()
        with self._lock:
            self._pending = None  # the previous source's unsent samples belong to another timeline
        self.source = source
        if source.calibration is not self.calibration:
            source.set_calibration(self.calibration)
        if source.assembly is not self.assembly or not _same_cov(source.wrench_cov, self.wrench_cov):
            source.set_assembly(self.assembly, self.wrench_cov)
        if self.sample_contacts:
            source.set_sample_contacts(True)
        if not self.replaying and self.live_tare is not None and source.tare_in_force is None:
            source.apply_tare(self.live_tare)  # Back to live (or new devices): the live tare again
        source.set_sink(self.deliver, self._on_source_error)
        self.tare_status.emit(self.tare_text(), self.tare_in_force is not None)

    def set_calibration(self, calibration) -> None:
        if self.source is not None:
            self.source.set_calibration(calibration)
        self.calibration = calibration
        self.live_tare = None  # a new calibration starts from its own zero
        self.tare_status.emit(self.tare_text(), False)

    def set_assembly(self, assembly, wrench_cov=None) -> None:
        """Contacts on this object's patches (``Assembly`` or None); their covariance with ``wrench_cov``."""
        if self.source is not None:
            self.source.set_assembly(assembly, wrench_cov)
        self.assembly, self.wrench_cov = assembly, wrench_cov

    def set_sample_contacts(self, on: bool) -> None:
        """Bundles with every sample's contacts (``arrived_contacts``: the LSL publisher's), or not.

        Kept for the next source; the source is asked from the command thread (it may wait for its answer)."""
        self.sample_contacts = bool(on)
        self.post(lambda: self.source is not None and self.source.set_sample_contacts(self.sample_contacts))

    def seek(self, t: float) -> None:
        """Replay: continue from ``t`` s into the recording (nothing live)."""
        if self.replaying:
            self.source.seek(t)

    def tare(self, support=None) -> None:
        """Zero the face wrenches and the reference on the last 0.5 s — only if still and every load is known.

        Checked and taken where the samples are (the source's pipeline: the wizard's checks,
        :func:`pito_core.pipeline.check_tare`): unloaded, or with ``support`` (a ``TareSupport``: the
        object's mass and base face) at rest on the table; recorded there when recording. A refusal
        is reported with its reason on ``tare_status``. The tare is kept as the live tare.
        """
        if self.replaying:
            self.tare_status.emit("✘ Tare: not during a replay (the recording's own tares apply)", False)
            return
        if self.source is None:
            self.tare_status.emit("✘ Tare refused: no devices", False)
            return
        if self.calibration is None:
            self.tare_status.emit("✘ Tare refused: no calibration — load one (or calibrate) first", False)
            return
        try:
            self.source.tare(0.5, True, support)
        except ValueError as exc:  # TareRefused (reason), or nothing seen yet
            reason = exc.check.reason if isinstance(exc, TareRefused) else str(exc).removeprefix("tare refused: ")
            self.tare_status.emit(f"✘ Tare refused: {reason}", self.tare_in_force is not None)
            return
        self.live_tare = self.tare_in_force
        self.tare_status.emit(self.tare_text(), True)

    def undo_tare(self) -> None:
        """Bring back the tare before the last one (the calibration's own zero if none)."""
        if self.replaying or self.source is None:
            return
        try:
            self.source.undo_tare()
        except ValueError as exc:
            self.tare_status.emit(f"✘ Undo tare: {exc}", self.tare_in_force is not None)
            return
        self.live_tare = self.tare_in_force
        self.tare_status.emit(self.tare_text(), self.live_tare is not None)

    def tare_text(self) -> str:
        """The tare in force, in words."""
        if self.replaying:
            return "Tare: as recorded (replay)"
        ev = self.tare_in_force
        if ev is None:
            return "Tare: the calibration's own zero" if self.calibration is not None else "Tare: none (no calibration)"
        when = time.strftime("%H:%M:%S", time.localtime(ev.get("taken_at", time.time())))
        state = ev.get("state", "unloaded")
        if ev.get("known_load") is not None:
            W = np.asarray(ev["known_load"], dtype=float)
            j = int(np.argmax(np.linalg.norm(W[:, :3], axis=1)))
            state += f": face {j + 1} reads its weight, {np.linalg.norm(W[j, :3]):.2f} N"
        return f"Tare: taken {when} ({ev.get('duration', 0.5):g} s, still, {state})"

    # ------------------------------------------------------------ recording
    def start_recording(self, path, simulated: bool = False, meta: dict | None = None) -> None:
        """Record every raw sample of both devices to ``path`` (``pito-recording``), written where they are read.

        Raises
        ------
        ValueError
            No source, or one that cannot record (a replay).
        """
        self.stop_recording()
        info = {"simulated": bool(simulated), "source": "pito-app"}
        info.update(provenance_meta(self))  # the calibration and object shown (docs/interop.md)
        info.update(meta or {})
        try:
            if self.source is None:
                raise ValueError("recording: no devices are connected")
            self.source.open_recording(path, info)
        except Exception as exc:
            self.recording_failed.emit(f"{path}: {type(exc).__name__}: {exc}" if not isinstance(exc, ValueError)
                                       else str(exc))
            raise
        self._recording_path = str(path)

    def stop_recording(self) -> int:
        """Close the recording (returns once the file is closed); returns the cube samples written."""
        path, self._recording_path = self._recording_path, None
        if path is None or self.source is None:
            return 0
        try:
            closed = self.source.close_recording()
        except Exception as exc:
            self.recording_failed.emit(f"closing {path}: {type(exc).__name__}: {exc}")
            raise
        rows = int(closed.get("rows", {}).get("pito", 0))
        self.recording_closed.emit(str(closed.get("path", path)), rows)  # the file is complete now
        return rows


def _same_cov(a, b) -> bool:
    """The same ``wrench_cov`` setting (None, ``"calibration"`` or the same array object)."""
    return a is b or (isinstance(a, str) and a == b)

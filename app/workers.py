"""The acquisition worker: owns the devices in a thread, emits one bundle per display tick.

The worker lives in its own ``QThread``. A timer in that thread ticks at the display rate
(default 60 Hz): each tick drains every new sample from the source, applies the
calibration and the tare to the whole chunk, records the chunk if recording, solves the
contacts of the latest sample, and emits one :class:`Bundle` (numpy arrays). The GUI never
sees individual samples; a slow screen loses no samples (STYLE.md item 10).

Commands from the GUI thread (set calibration, tare, record, ...) are posted as callables
to a thread-safe queue the worker runs at the start of its next tick.
"""

from __future__ import annotations

import queue
import threading
from dataclasses import dataclass, field
from typing import Callable, Protocol

import numpy as np
from PySide6.QtCore import QObject, QThread, QTimer, Signal, Slot

from pito_core.frames import CubeCore, invert_pose, transform_wrench

__all__ = ["Source", "Bundle", "DeviceWorker", "WorkerThread"]


class Source(Protocol):
    """What the worker reads: the real drivers, the simulators or a recording.

    ``read()`` returns the samples that arrived since the previous call:
    ``time (n,)`` s, ``counts (n, 36)``, ``reference (n, 6)`` N and N·m in the reference
    frame (NaN rows where there is no reference).
    """

    simulated: bool

    def read(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]: ...

    def stats(self) -> dict: ...

    def close(self) -> None: ...


@dataclass
class Bundle:
    """One display tick's worth of data (numpy arrays, SI units).

    Attributes
    ----------
    time, counts, reference : ndarray, shapes (n,), (n, 36), (n, 6)
        The new samples of this tick (s, counts, N and N·m in the reference frame).
    stats : dict
        Device figures: ``rate_cube``/``rate_reference`` (Hz), ``saturated``, ``dropped`` (frames).
    wrenches : ndarray, shape (6, 6) or None
        Wrench on each face in its frame at the latest sample ``[fx, fy, fz, tx, ty, tz]``
        (N, N·m), tared; NaN for faces without output. None without a calibration.
    contacts : dict or None
        Core frame: ``points (6, 3)`` m, ``normals (6, 3)``, ``forces (6, 3)`` N (on the
        object), ``torsions (6,)`` N·m, ``valid (6,)`` bool, ``covariance (6, 3, 3)`` m².
    sum_force, sum_torque : ndarray, shape (3,)
        Σ of the face loads in the core frame (N; N·m about the core centre).
    recorded : int
        Samples recorded so far in the current recording (0 when not recording).
    """

    time: np.ndarray
    counts: np.ndarray
    reference: np.ndarray
    stats: dict = field(default_factory=dict)
    wrenches: np.ndarray | None = None
    contacts: dict | None = None
    sum_force: np.ndarray | None = None
    sum_torque: np.ndarray | None = None
    recorded: int = 0
    replay_position: float | None = None
    replay_duration: float | None = None

    @property
    def latest_time(self) -> float:
        return float(self.time[-1]) if self.time.size else float("nan")


def face_sums(wrenches: np.ndarray, core: CubeCore, cog=(0.0, 0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    """Σ of the face wrenches ``(6, 6)`` (face frames) in the core frame: ``(ΣF (3,) N, ΣT (3,) N·m)``.

    Faces with NaN (no output) are left out. Moments about ``cog`` (core frame, m), the
    object's centre of gravity: in a still grasp ‖ΣF‖ = m·g and ΣT = 0 about it.
    """
    total = np.zeros(6)
    for k in range(6):
        w = wrenches[k]
        if not np.all(np.isfinite(w)):
            continue
        total += transform_wrench(w, invert_pose(core.face_pose(k + 1)))
    force = total[:3]
    return force, total[3:] - np.cross(np.asarray(cog, dtype=float), force)


def merge_bundles(old: Bundle, new: Bundle) -> Bundle:
    """One bundle with the samples of both (old first) and the latest derived values of ``new``."""
    new.time = np.concatenate([old.time, new.time])
    new.counts = np.concatenate([old.counts, new.counts])
    new.reference = np.concatenate([old.reference, new.reference])
    if new.wrenches is None and old.wrenches is not None:
        new.wrenches, new.contacts = old.wrenches, old.contacts
        new.sum_force, new.sum_torque = old.sum_force, old.sum_torque
    return new


class DeviceWorker(QObject):
    """Reads a :class:`Source`, applies calibration and contact solving, emits :class:`Bundle`.

    Parameters
    ----------
    rate : float
        Display ticks per second (Hz).
    solver : callable, optional
        ``solver(wrenches (6, 6)) -> dict`` of contacts (see :class:`Bundle`), run on the
        latest tared face wrenches each tick.
    """

    bundle = Signal(object)
    error = Signal(str)

    def __init__(self, rate: float = 60.0, core: CubeCore | None = None):
        super().__init__()
        self.rate = float(rate)
        self.core = core or CubeCore()
        self.source: Source | None = None
        self.calibration = None
        self.offset = None  # (36,) counts: tare of the calibration
        self.reference_offset = np.zeros(6)
        self.solver: Callable | None = None
        self.cog = np.zeros(3)  # m, core frame: centre of gravity of the object
        self._commands: queue.Queue = queue.Queue()
        self._timer: QTimer | None = None
        self._recorder = None  # a pito_core.io.RecordingWriter while recording
        self._recorded = 0
        self._last_counts = np.zeros((0, 36))
        self._last_reference = np.zeros((0, 6))
        self._tail = None  # (counts, reference) of the last 0.5 s, for the tare
        self.ticks = 0
        self.emitted = 0
        self._pending: Bundle | None = None
        self._consumed = threading.Event()
        self._consumed.set()

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
        if self.source is not None:
            try:
                self.source.close()
            except Exception:  # noqa: BLE001 - closing must not fail the shutdown
                pass
            self.source = None

    def post(self, fn: Callable[[], None]) -> None:
        """Run ``fn()`` in the worker thread before its next tick (thread-safe)."""
        self._commands.put(fn)

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
        """Drain the source, process, emit one bundle."""
        self._run_commands()
        if self.source is None:
            return
        try:
            chunk = self.source.read()
            if self._recorder is not None:
                from . import backend

                backend.record_raw(self._recorder, getattr(self.source, "last_raw", None))
                self._recorded += len(chunk[0])
            b = self.process(*chunk)
        except Exception as exc:  # noqa: BLE001
            self.error.emit(f"{type(exc).__name__}: {exc}")
            return
        b.stats = self.source.stats()
        if "position" in b.stats:
            b.replay_position = b.stats["position"]
            b.replay_duration = b.stats.get("duration")
        self.ticks += 1
        self._pending = b if self._pending is None else merge_bundles(self._pending, b)
        if self._consumed.is_set():  # the GUI is done with the previous bundle: send the next
            self._consumed.clear()
            pending, self._pending = self._pending, None
            self.emitted += 1
            self.bundle.emit(pending)

    def ack(self) -> None:
        """The GUI has shown the last bundle (thread-safe): the next tick may emit again.

        Without it a slow screen would queue bundles without end; with it, samples that
        arrive meanwhile are merged into the next bundle (none is lost).
        """
        self._consumed.set()

    # ------------------------------------------------------------ processing (pure)
    def process(self, t, counts, reference) -> Bundle:
        """Turn one chunk into a bundle (also usable without a thread, e.g. in tests)."""
        t = np.asarray(t, dtype=float).reshape(-1)
        counts = np.asarray(counts, dtype=float).reshape(-1, 36)
        reference = np.asarray(reference, dtype=float).reshape(-1, 6) - self.reference_offset
        self._keep_tail(counts, reference)
        b = Bundle(t, counts, reference)
        b.recorded = self._recorded if self._recorder is not None else 0
        if self.calibration is not None and counts.shape[0]:
            latest = counts[-min(5, counts.shape[0]):].mean(axis=0)  # average a few samples against noise
            W = self.calibration.wrenches(latest, offset=self.offset)
            b.wrenches = W
            b.sum_force, b.sum_torque = face_sums(W, self.core, self.cog)
            if self.solver is not None:
                b.contacts = self.solver(W)
        return b

    def _keep_tail(self, counts, reference) -> None:
        n_keep = 500
        if self._tail is None:
            self._tail = (counts[-n_keep:], reference[-n_keep:])
        else:
            c = np.concatenate([self._tail[0], counts])[-n_keep:]
            r = np.concatenate([self._tail[1], reference])[-n_keep:]
            self._tail = (c, r)

    # ------------------------------------------------------------ commands (run in the thread)
    def set_source(self, source) -> None:
        if self.source is not None and self.source is not source:
            self.source.close()
        self.source = source
        self._tail = None

    def set_calibration(self, calibration) -> None:
        self.calibration = calibration
        self.offset = None if calibration is None else np.asarray(calibration.offset, dtype=float)

    def tare(self) -> None:
        """Zero the face wrenches and the reference on the last ~0.5 s of samples."""
        if self._tail is None or self._tail[0].shape[0] == 0:
            return
        c, r = self._tail
        self.offset = c.mean(axis=0)
        ref = r + self.reference_offset
        finite = np.isfinite(ref).all(axis=1)
        if finite.any():
            self.reference_offset = ref[finite].mean(axis=0)

    def start_recording(self, path, simulated: bool = False) -> None:
        """Record every raw sample of both devices to ``path`` (``pito-recording`` format)."""
        from . import backend

        self.stop_recording()
        self._recorder = backend.open_recorder(path, simulated)
        self._recorded = 0

    def stop_recording(self) -> int:
        """Close the recording; returns the cube samples written."""
        rec, self._recorder = self._recorder, None
        if rec is not None:
            rec.close()
        return self._recorded


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

"""Slow work off the GUI thread: calibration fits, file loads, exports.

:func:`run_task` runs ``fn(progress)`` on Qt's global thread pool and delivers its result to
the GUI thread by signal; the window keeps repainting meanwhile. ``progress(fraction, text)``
reports how far the work is (``fraction`` 0..1, or ``None`` when unknown) and is also the
cancellation point: after :meth:`Task.cancel` the next call raises :class:`Cancelled`, the
work stops there and its result is never delivered. A :class:`TaskBar` shows a task's
progress with a Cancel button.

A task may have an *owner* (the widget whose callbacks it calls): closing the owner cancels
its tasks (:func:`cancel_tasks`, called by the window when it closes), and a task whose owner
is gone (deleted) delivers nothing — no ``done``, no ``failed`` — so no callback ever reaches
a deleted widget.
"""

from __future__ import annotations

import os
import pickle
import select
import subprocess
import sys
import threading
import traceback
import weakref
from typing import Callable

import shiboken6
from PySide6.QtCore import QObject, QRunnable, QThreadPool, QTimer, Signal, Slot
from PySide6.QtWidgets import QHBoxLayout, QLabel, QProgressBar, QPushButton, QWidget

__all__ = ["Task", "Cancelled", "run_task", "run_in_process", "cancel_tasks", "TaskBar"]

_alive: set = set()  # tasks are kept alive until they end


class Cancelled(Exception):
    """Raised by ``progress()`` inside a task that was cancelled."""


class Task(QObject):
    """One piece of work on the thread pool; lives in the GUI thread, so its signals arrive there.

    Signals: ``progressed(float, str)`` (fraction 0..1, or −1 when unknown; text),
    ``done(object)`` (the result), ``failed(str)`` (the error, shown to the operator),
    ``ended()`` (after any of done, failed, or a cancel).
    """

    progressed = Signal(float, str)
    done = Signal(object)
    failed = Signal(str)
    ended = Signal()

    def __init__(self, fn: Callable, label: str):
        super().__init__()
        self.fn = fn
        self.label = label
        self._cancel = threading.Event()
        self.running = True
        self.thread_name = None  # the thread that ran ``fn`` (for tests and logs)
        self._owner = None  # weak reference to the owner, if any

    # ------------------------------------------------------------ owner
    @property
    def owner(self):
        """The owner given to :func:`run_task` (None if none, or once it is gone)."""
        owner = self._owner() if self._owner is not None else None
        return owner if owner is not None and shiboken6.isValid(owner) else None

    def owner_alive(self) -> bool:
        """True without an owner; else whether the owner still exists (its C++ object too)."""
        return self._owner is None or self.owner is not None

    def set_owner(self, owner: QObject) -> None:
        """Bind the task to ``owner``: when the owner is destroyed the task is cancelled, delivering nothing."""
        self._owner = weakref.ref(owner)
        owner.destroyed.connect(self._owner_destroyed)

    @Slot()
    def _owner_destroyed(self) -> None:
        # The owner is being destroyed (its children may be gone already): stop the work now,
        # but emit ``ended`` only once the destruction is over, so that it reaches no part of it.
        if self.running:
            self._cancel.set()
            QTimer.singleShot(0, self._finish)

    @property
    def cancelled(self) -> bool:
        return self._cancel.is_set()

    def cancel(self) -> None:
        """Stop at the next progress point; the result, if any, is dropped."""
        if self.running:
            self._cancel.set()
            self._finish()

    def progress(self, fraction: float | None = None, text: str = "") -> None:
        """Report progress from inside ``fn`` (any thread); raises :class:`Cancelled` after a cancel."""
        if self._cancel.is_set():
            raise Cancelled(self.label)
        if fraction is not None and fraction <= -2.0:
            return  # only a cancellation point
        self.progressed.emit(-1.0 if fraction is None else float(fraction), text)

    def _run(self) -> None:  # in a pool thread
        self.thread_name = threading.current_thread().name
        try:
            result = self.fn(self.progress)
        except Cancelled:
            return
        except Exception as exc:  # noqa: BLE001 - reported to the operator through `failed`
            if not self._cancel.is_set():
                # one line for the terminal (the operator gets the message in the window); the
                # traceback only for errors that are not about the input (a bug)
                print(f"pito-app: {self.label}: {type(exc).__name__}: {exc}", file=sys.stderr)
                if not isinstance(exc, (OSError, ValueError, KeyError)):
                    traceback.print_exc()
                self._deliver_failure(f"{type(exc).__name__}: {exc}")
            return
        if not self._cancel.is_set():
            self._deliver(result)

    # the signals are emitted from the pool thread; Qt queues them to the GUI thread
    def _deliver(self, result) -> None:
        self._result_ready.emit(result)

    def _deliver_failure(self, message: str) -> None:
        self._failure_ready.emit(message)

    _result_ready = Signal(object)
    _failure_ready = Signal(str)

    def _on_result(self, result) -> None:  # GUI thread
        if self.running and not self._cancel.is_set() and self.owner_alive():
            self.done.emit(result)
        self._finish()

    def _on_failure(self, message: str) -> None:  # GUI thread
        if self.running and not self._cancel.is_set() and self.owner_alive():
            self.failed.emit(message)
        self._finish()

    def _finish(self) -> None:
        if self.running:
            self.running = False
            if self._owner is not None and not self.owner_alive():
                self._cancel.set()  # the owner is gone: nothing of it may be called any more
            self.ended.emit()
        _alive.discard(self)


class _Runnable(QRunnable):
    def __init__(self, task: Task):
        super().__init__()
        self.task = task

    def run(self) -> None:
        self.task._run()


def run_task(fn: Callable, label: str, on_done: Callable | None = None, on_failed: Callable | None = None,
             bar: "TaskBar | None" = None, owner: QObject | None = None) -> Task:
    """Run ``fn(progress)`` in the thread pool; ``on_done(result)`` / ``on_failed(message)`` run in the GUI thread.

    Parameters
    ----------
    fn : callable
        ``fn(progress) -> result``; call ``progress(fraction, text)`` now and then.
    label : str
        What the operator sees ("Fitting the calibration").
    bar : TaskBar, optional
        Shows the task's progress and its Cancel button.
    owner : QObject, optional
        The widget ``on_done`` / ``on_failed`` belong to. :func:`cancel_tasks` on it (or on
        an ancestor) cancels the task; once the owner is destroyed the task is cancelled and
        delivers nothing. Give it whenever the callbacks touch a widget.
    """
    task = Task(fn, label)
    if owner is not None:
        task.set_owner(owner)
    task._result_ready.connect(task._on_result)
    task._failure_ready.connect(task._on_failure)
    if on_done is not None:
        task.done.connect(on_done)
    if on_failed is not None:
        task.failed.connect(on_failed)
    if bar is not None:
        bar.follow(task)
    _alive.add(task)
    QThreadPool.globalInstance().start(_Runnable(task))
    return task


def _within(obj: QObject, root: QObject) -> bool:
    while obj is not None:
        if obj is root:
            return True
        obj = obj.parent()
    return False


def cancel_tasks(root: QObject) -> list[Task]:
    """Cancel every running task owned by ``root`` or by a descendant of it; returns them.

    A window calls it when it closes: the work stops (a child process is terminated) and
    none of the callbacks run.
    """
    cancelled = []
    for task in list(_alive):
        owner = task.owner
        if task.running and owner is not None and _within(owner, root):
            task.cancel()
            cancelled.append(task)
    return cancelled


def _in_process(fn, args, progress):
    """Run ``fn(*args, progress=...)`` in a fresh Python process; relay its progress; return its result.

    Work that holds the GIL for long stretches (LAPACK through f2py, e.g. the calibration's
    streamed QR) would stall the GUI thread if run in a thread of this process. The child is
    ``python -m app._taskchild``: ``(fn, args)`` go to it pickled on stdin, messages come back
    pickled and framed on its stdout; ``fn`` must be importable by name (a module-level function).
    """
    proc = subprocess.Popen([sys.executable, "-m", "app._taskchild"], stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE, bufsize=0)
    try:
        try:
            pickle.dump((fn, args), proc.stdin, protocol=pickle.HIGHEST_PROTOCOL)
            proc.stdin.close()
        except BrokenPipeError:
            raise RuntimeError(f"the worker process ended at start (exit code {proc.poll()})") from None
        fd, buf = proc.stdout.fileno(), bytearray()
        while True:
            if len(buf) >= 8 and len(buf) >= 8 + int.from_bytes(buf[:8], "little"):
                n = int.from_bytes(buf[:8], "little")
                msg = pickle.loads(bytes(buf[8:8 + n]))
                del buf[:8 + n]
                if msg[0] == "progress":
                    progress(msg[1], msg[2])
                    continue
                if msg[0] == "done":
                    return msg[1]
                raise RuntimeError(msg[1])
            ready, _, _ = select.select([fd], [], [], 0.05)
            if not ready:
                progress(-2.0, "")  # a cancellation point only
                continue
            chunk = os.read(fd, 1 << 20)
            if not chunk:
                raise RuntimeError(f"the worker process ended without a result (exit code {proc.wait()})")
            buf += chunk
    finally:
        if proc.poll() is None:
            proc.terminate()  # cancelled (or failed): the child stops now
        try:
            proc.wait(5)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
        proc.stdout.close()


def run_in_process(fn, args: tuple, label: str, on_done: Callable | None = None, on_failed: Callable | None = None,
                   bar: "TaskBar | None" = None, owner: QObject | None = None) -> Task:
    """Like :func:`run_task`, but ``fn(*args, progress=...)`` runs in a child Python process
    (``fn`` importable by name, ``args`` picklable). Cancel terminates the child at once."""
    return run_task(lambda progress: _in_process(fn, args, progress), label, on_done, on_failed, bar, owner)


class TaskBar(QWidget):
    """A progress bar, the task's label and a Cancel button; hidden while nothing runs."""

    def __init__(self, parent=None):
        super().__init__(parent)
        lay = QHBoxLayout(self)
        lay.setContentsMargins(0, 0, 0, 0)
        self.label = QLabel("")
        self.bar = QProgressBar()
        self.bar.setMinimumWidth(220)
        self.cancel = QPushButton("Cancel")
        lay.addWidget(self.label)
        lay.addWidget(self.bar, 1)
        lay.addWidget(self.cancel)
        self.task: Task | None = None
        self.cancel.clicked.connect(self._cancel)
        self.setVisible(False)

    def follow(self, task: Task) -> None:
        self.task = task
        self.label.setText(task.label + "…")
        self.bar.setRange(0, 0)  # busy until the first figure
        # bound methods of this widget (not lambdas): Qt drops the connections when the bar is deleted
        task.progressed.connect(self._progress)
        task.ended.connect(self._task_ended)
        self.setVisible(True)

    def _progress(self, fraction: float, text: str) -> None:
        if fraction < 0:
            self.bar.setRange(0, 0)
        else:
            self.bar.setRange(0, 100)
            self.bar.setValue(int(round(100 * fraction)))
        if text:
            self.label.setText(f"{self.task.label if self.task else ''}: {text}")

    def _cancel(self) -> None:
        if self.task is not None:
            self.task.cancel()

    @Slot()
    def _task_ended(self) -> None:
        if self.task is not None and not self.task.running:  # the task shown has ended (not an older one)
            self.task = None
            self.setVisible(False)

"""Lifetimes across threads: a background task never calls into a widget that is gone, closing
the window cancels its tasks, and stopping a recording says when the file is complete."""

import threading

import pytest
import shiboken6
from PySide6.QtCore import QThreadPool
from PySide6.QtWidgets import QLabel, QVBoxLayout, QWidget

pytestmark = pytest.mark.needs_display


def _pool_idle(qtbot):
    assert QThreadPool.globalInstance().waitForDone(15_000)  # every task's work has returned
    qtbot.wait(50)  # and its queued signals (if any) were delivered


def test_a_task_outliving_its_owner_calls_nothing(qtbot, styled):
    from app.tasks import TaskBar, _alive, run_task

    owner = QWidget()
    lay = QVBoxLayout(owner)
    label, bar = QLabel("waiting"), TaskBar()
    lay.addWidget(label)
    lay.addWidget(bar)
    release, got = threading.Event(), []

    def work(progress):
        release.wait(10)
        return "result"

    def done(result):
        got.append(result)
        label.setText(result)  # would raise "Internal C++ object already deleted"

    task = run_task(work, "slow work", on_done=done, on_failed=got.append, bar=bar, owner=owner)
    assert task.running and bar.task is task
    shiboken6.delete(owner)  # the owner (with its label and task bar) is deleted while the task runs
    release.set()
    qtbot.waitUntil(lambda: not task.running, timeout=10_000)
    _pool_idle(qtbot)
    assert got == [] and task.cancelled and task not in _alive


def test_cancel_tasks_cancels_the_tasks_of_a_window_and_of_its_children(qtbot, styled):
    from app.tasks import cancel_tasks, run_task

    window, other = QWidget(), QWidget()
    qtbot.addWidget(window)
    qtbot.addWidget(other)
    child = QLabel(window)
    release, got = threading.Event(), []

    def work(progress):
        release.wait(10)
        progress(1.0, "done")  # a cancellation point
        return "result"

    mine = run_task(work, "the window's", on_done=got.append, owner=child)
    theirs = run_task(work, "another window's", on_done=got.append, owner=other)
    assert cancel_tasks(window) == [mine]
    assert not mine.running and mine.cancelled and theirs.running
    release.set()
    qtbot.waitUntil(lambda: not theirs.running, timeout=10_000)
    _pool_idle(qtbot)
    assert got == ["result"]  # only the task that was not cancelled delivered


@pytest.mark.slow
def test_closing_the_window_cancels_the_startup_calibration(qtbot, styled):
    from app.window import MainWindow

    window = MainWindow(demo=True, demo_k=1500)
    qtbot.addWidget(window)
    try:
        task = window.calibration_task
        assert task is not None and task.running and window.taskbar.task is task
        window.close()  # closeEvent → shutdown
        assert not task.running and task.cancelled
        _pool_idle(qtbot)  # the child process was terminated: the pool thread returned
        assert window.calibration is None and window.errors == []
    finally:
        window.shutdown()
        window.release_views()


class _FakeAcquisition:
    def __init__(self):
        self.path = None
        self.meta = {"simulated": True}
        self.events = []

    def open_recording(self, path, meta):
        self.path = str(path)

    def close_recording(self):
        return {"rows": {"pito": 1234, "netft": 1200}, "path": self.path}

    def record_event(self, event):
        self.events.append(event)

    def cursors(self):
        return (0, 0)


class _FakeReader:
    simulated = True
    has_reference = True

    def __init__(self, acq=None):
        if acq is not None:
            self.acq = acq

    def read(self):
        from pito_core.pipeline import NewSamples

        return NewSamples(None)

    def stats(self):
        return {}

    def close(self):
        pass


def test_the_feed_says_when_a_recording_is_closed(qtbot, tmp_path):
    from app.live import LiveFeed
    from pito_core.pipeline import PipelineThread

    feed = LiveFeed()
    try:
        acq = _FakeAcquisition()
        feed.set_source(PipelineThread(_FakeReader(acq)))
        closed, failed = [], []
        feed.recording_closed.connect(lambda path, rows: closed.append((path, rows)))
        feed.recording_failed.connect(failed.append)
        path = tmp_path / "r.pitorec"
        feed.start_recording(path, simulated=True)
        assert closed == [] and acq.path == str(path)
        assert feed.stop_recording() == 1234
        assert closed == [(str(path), 1234)]  # emitted once the file is closed
        assert feed.stop_recording() == 0 and len(closed) == 1  # nothing open: nothing said
        feed.start_recording(path, simulated=True)
        feed.set_source(PipelineThread(_FakeReader()))  # a source that cannot record (a replay)
        assert closed == [(str(path), 1234)] * 2  # the change of source closed the recording, and said so
        with pytest.raises(ValueError, match="cannot be recorded"):
            feed.start_recording(path)
        assert len(failed) == 1 and "cannot be recorded" in failed[0]
    finally:
        feed.stop()

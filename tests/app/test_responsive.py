"""No blocking on the GUI thread: a 10⁵-sample calibration fit runs off the GUI thread (in a
child process) and the event loop keeps turning meanwhile — a 10 ms timer never waits more
than 100 ms longer than it does on the same machine with nothing running; cancel drops the
result.

A responsiveness check, not a speed figure: the bound is ten timer periods above the
machine's own scheduling noise (measured first, in the same test: on a machine shared with
other jobs the OS alone can hold the GUI thread off the CPU for tens of ms), and the test
also checks *where* the fit ran (not the GUI thread), which does not depend on the machine.
"""

import threading
import time

import pytest
from PySide6.QtCore import QTimer

pytestmark = pytest.mark.needs_display


@pytest.fixture(scope="module")
def big_session():
    from pito_core.sim import simulate_calibration

    s = simulate_calibration("frame_hole", 6, k=16700, seed=3)  # 6 faces × 16 700 + unloaded ≈ 10⁵ samples
    assert s.counts.shape[0] >= 100_000
    return s


@pytest.fixture
def page(qtbot, styled):
    from app.wizard.model import WizardModel
    from app.wizard.results_page import ResultsPage

    model = WizardModel()
    model.set_mount(method="loaded_frame", flange="frame_hole", connected_face=6)
    p = ResultsPage(model)
    qtbot.addWidget(p)
    p.resize(1200, 800)
    p.show()
    qtbot.waitExposed(p)
    return p


def test_fit_of_1e5_samples_keeps_the_event_loop_turning(qtbot, page, big_session):
    gaps, last = [], [time.monotonic()]

    def beat():
        now = time.monotonic()
        gaps.append(now - last[0])
        last[0] = now

    timer = QTimer()
    timer.timeout.connect(beat)
    timer.start(10)
    qtbot.wait(100)
    gaps.clear()
    last[0] = time.monotonic()
    qtbot.wait(1500)  # the machine's own noise: the same timer with nothing else running
    noise = max(gaps)
    gaps.clear()
    last[0] = time.monotonic()
    page.compute(big_session)
    assert page.fitting and page.taskbar.isVisible()  # returns at once, progress shown
    qtbot.waitUntil(lambda: not page.fitting, timeout=300_000)
    timer.stop()
    model = page.model
    assert model.calibration is not None and model.calibration.method == "loaded_frame"
    assert page.task.thread_name != threading.main_thread().name  # fitted off the GUI thread
    assert len(gaps) >= 5  # the timer kept firing while the fit ran
    assert max(gaps) < 0.100 + noise, (f"event loop stalled {1000 * max(gaps):.0f} ms during the fit "
                                       f"(idle: {1000 * noise:.0f} ms)")
    assert not page.taskbar.isVisible()


def test_cancel_drops_the_result(qtbot, page, big_session):
    page.compute(big_session)
    page.taskbar.cancel.click()
    assert not page.fitting and not page.taskbar.isVisible()
    qtbot.wait(200)
    assert page.model.calibration is None
    assert "cancelled" in page.values["status"].text()


def test_a_failing_task_reports_its_error(qtbot, styled):
    from app.tasks import run_task

    got = []

    def bad(progress):
        progress(0.5, "half")
        raise ValueError("counts: expected shape (N, 36)")

    task = run_task(bad, "bad task", on_done=got.append, on_failed=got.append)
    qtbot.waitUntil(lambda: not task.running, timeout=10_000)
    assert got == ["ValueError: counts: expected shape (N, 36)"]

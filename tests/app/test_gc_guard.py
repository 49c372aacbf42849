"""Garbage cycles are freed in the GUI thread, never in a worker (app/gc_guard.py)."""

import gc
import threading

from PySide6.QtWidgets import QWidget

from app.gc_guard import GuiThreadCollector


class _Cycle:
    """A reference cycle that records the thread it was freed in."""

    freed_in: list = []

    def __init__(self):
        self.me = self

    def __del__(self):
        _Cycle.freed_in.append(threading.current_thread().name)


def _churn(release: threading.Event, n=100_000):
    """What a worker does: allocate container objects that stay alive a while (the net count
    of allocations is the collector's trigger), here until ``release`` is set."""
    keep = [[i] for i in range(n)]
    release.wait(10)
    return len(keep)


def _worker():
    release = threading.Event()
    t = threading.Thread(target=_churn, args=(release,), name="worker")
    t.start()
    return t, release


def test_cycles_are_freed_by_the_gui_thread_while_a_worker_allocates(qtbot, qapp):
    collector = GuiThreadCollector(qapp, interval_ms=20).install()  # (the suite's own is installed too)
    try:
        assert not gc.isenabled()
        _Cycle.freed_in.clear()
        for _ in range(50):
            _Cycle()
        worker, release = _worker()
        try:
            qtbot.waitUntil(lambda: len(_Cycle.freed_in) == 50, timeout=5000)
        finally:
            release.set()
            worker.join()
        assert set(_Cycle.freed_in) == {threading.main_thread().name}
        assert collector.collections >= 1
    finally:
        collector.uninstall()


def test_a_closed_widget_in_a_cycle_is_destroyed_in_the_gui_thread(qtbot, qapp):
    destroyed_in = []
    w = QWidget()
    w.cycle = w  # only the collector can free it
    w.destroyed.connect(lambda: destroyed_in.append(threading.current_thread().name))
    del w
    worker, release = _worker()
    try:
        qtbot.waitUntil(lambda: bool(destroyed_in), timeout=5000)
    finally:
        release.set()
        worker.join()
    assert destroyed_in == [threading.main_thread().name]


def test_uninstall_gives_back_automatic_collection(qapp):
    was = gc.isenabled()  # (off: the suite's own collector is installed)
    gc.enable()
    try:
        c = GuiThreadCollector(qapp).install()
        assert not gc.isenabled()
        c.uninstall()
        assert gc.isenabled()
    finally:
        (gc.enable if was else gc.disable)()


def test_freeze_startup_leaves_the_start_ups_objects_out_of_later_collections(qapp):
    made_at_start = [[i] for i in range(1000)]  # the start-up's long-lived containers
    collector = GuiThreadCollector(qapp)
    before = gc.get_freeze_count()
    try:
        collector.freeze_startup()
        assert gc.get_freeze_count() >= before + len(made_at_start)
        assert not any(o is made_at_start for o in gc.get_objects())  # in no generation a collection goes over
        _Cycle()  # made after: still collected
        _Cycle.freed_in.clear()
        gc.collect()
        assert _Cycle.freed_in == [threading.current_thread().name]
    finally:
        gc.unfreeze()

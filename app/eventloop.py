"""Waiting on the Qt event loop (shared by the wizard driver, screenshots and tests)."""

from __future__ import annotations

import time

from PySide6.QtCore import QEventLoop, QTimer

__all__ = ["process_for", "wait_until"]


def process_for(seconds: float) -> None:
    """Run the event loop for ``seconds`` (s)."""
    loop = QEventLoop()
    QTimer.singleShot(int(seconds * 1000), loop.quit)
    loop.exec()


def wait_until(predicate, timeout: float = 30.0, step: float = 0.05) -> bool:
    """Run the event loop until ``predicate()`` is true or ``timeout`` s pass; return the predicate."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if predicate():
            return True
        process_for(step)
    return bool(predicate())

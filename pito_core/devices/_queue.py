"""The hand-over of batches from a driver's reader thread to its consumer."""

from __future__ import annotations

import threading
import time

__all__ = ["BatchQueue"]


class BatchQueue:
    """Batches waiting for :meth:`get`, bounded: beyond ``max_items`` samples the oldest go.

    Parameters
    ----------
    max_items : int
        Samples kept at most (the sum of ``len(batch)``); older batches are dropped first.
    concatenate : callable
        ``concatenate(list_of_batches) -> batch``.
    """

    def __init__(self, max_items: int, concatenate):
        self.max_items = int(max_items)
        self._concatenate = concatenate
        self._cond = threading.Condition()
        self._batches: list = []
        self._n = 0

    def put(self, batch) -> int:
        """Append ``batch``; returns how many samples were dropped to stay within the bound."""
        dropped = 0
        with self._cond:
            self._batches.append(batch)
            self._n += len(batch)
            while self._n > self.max_items and len(self._batches) > 1:
                old = self._batches.pop(0)
                self._n -= len(old)
                dropped += len(old)
            self._cond.notify_all()
        return dropped

    def get(self, timeout: float | None, stopped: threading.Event):
        """Every batch waiting, concatenated, or None if none came within ``timeout`` s.

        ``timeout=None`` waits until a batch arrives or ``stopped`` is set; ``0`` polls.
        """
        with self._cond:
            if not self._batches and (timeout is None or timeout > 0):
                deadline = None if timeout is None else time.monotonic() + timeout
                while not self._batches and not stopped.is_set():
                    remaining = None if deadline is None else deadline - time.monotonic()
                    if remaining is not None and remaining <= 0:
                        break
                    self._cond.wait(remaining if remaining is not None else 0.5)
            if not self._batches:
                return None
            batches, self._batches, self._n = self._batches, [], 0
        return self._concatenate(batches)

    def wake(self) -> None:
        """Wake every waiting :meth:`get` (after the driver stopped)."""
        with self._cond:
            self._cond.notify_all()

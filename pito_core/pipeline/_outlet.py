"""Where a running pipeline's bundles go: one consumer's sink, or kept (merged) for ``take``.

Shared by :class:`~pito_core.pipeline.PipelineProcess` (bundles from the child, in its
receiving thread) and :class:`~pito_core.pipeline.PipelineThread` (a replay in this
process), so the views have one route whichever source runs.
"""

from __future__ import annotations

import contextlib
import threading

from ._bundle import LiveBundle

__all__ = ["BundleOutlet"]


class BundleOutlet:
    """A sink for each bundle as it is made, or the bundles kept, merged, until :meth:`take`.

    ``sink(bundle)`` runs in the producing thread, one bundle at a time; bundles kept while
    no sink was set go first, merged into the next one. ``on_error(message)`` is told when
    the sink raises (the producer goes on) or the producer fails.
    """

    def __init__(self):
        self._outlet_lock = threading.Lock()
        self._sink = None
        self._on_error = None
        self._pending: LiveBundle | None = None
        self._latest_stats: dict = {}

    def set_sink(self, sink, on_error=None) -> None:
        """Hand each bundle to ``sink(bundle)`` as it is made (None: keep them for :meth:`take`).

        ``sink`` runs in the producing thread, one bundle at a time; bundles kept before go
        with the first. ``on_error(message)`` (optional) is told when ``sink`` raises or the
        producer fails.
        """
        with self._outlet_lock:
            self._sink, self._on_error = sink, on_error

    def take(self) -> LiveBundle | None:
        """The bundles made since the previous call while no sink was set, merged, or None."""
        with self._outlet_lock:
            b, self._pending = self._pending, None
        return b

    def _deliver(self, b: LiveBundle) -> None:
        """To the sink (with any kept before it), else kept; a failing sink is told, not raised."""
        with self._outlet_lock:
            self._latest_stats = b.stats
            sink = self._sink
            if self._pending is not None:  # kept while no sink was set: they go first
                b, self._pending = self._pending.merged(b), None
            if sink is None:
                self._pending = b
                return
        try:
            sink(b)
        except Exception as exc:  # noqa: BLE001 - a failing sink must not end the producer; it is told
            self._tell(f"{type(exc).__name__}: {exc}")

    def _tell(self, message: str) -> None:
        """``on_error(message)``, if one is set (its own failure is ignored)."""
        with self._outlet_lock:
            on_error = self._on_error
        if on_error is not None:
            with contextlib.suppress(Exception):
                on_error(message)

    def _last_stats(self) -> dict:
        with self._outlet_lock:
            return dict(self._latest_stats)

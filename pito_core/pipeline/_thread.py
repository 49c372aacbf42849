"""The one pipeline run in a thread of the caller's process: a replay, with the interface of the pipeline process.

:class:`PipelineThread` reads a reader (a :class:`~pito_core.pipeline.RecordingReader` in the
app's replay) at a fixed rate, runs :class:`~pito_core.pipeline.Pipeline` on the new rows
(:class:`~pito_core.pipeline._runner.PipelineRunner`, the runner of the pipeline process's child
too) and hands each :class:`~pito_core.pipeline.LiveBundle` to a sink, in its own thread. Its
methods are those of :class:`~pito_core.pipeline.PipelineProcess` (``set_sink``, ``take``, the
settings, tare and recording requests, ``stats``, ``close``), so a consumer has one route
whichever runs.
"""

from __future__ import annotations

import threading
import time

from ..frames import CubeCore
from ._controls import PipelineControls
from ._outlet import BundleOutlet
from ._pipeline import Pipeline
from ._runner import PipelineRunner

__all__ = ["PipelineThread"]


class PipelineThread(PipelineControls, BundleOutlet):
    """``reader`` read and processed ``rate_hz`` times a second in a thread of this process.

    Parameters
    ----------
    reader : RecordingReader or AcquisitionReader
        ``read()``, ``stats()``, ``close()``, ``has_reference``, ``simulated``; ``seek(t)`` for a
        recording; an ``acq`` (a running acquisition) to record.
    core : CubeCore, optional
    rate_hz : float
        Reads per second, Hz (the display rate: a replay shows no more than that).
    name : str
        The thread's name.

    Attributes
    ----------
    replay : bool
        The reader is a recording (it can :meth:`seek`; a replay cannot be recorded or tared).
    pipeline : Pipeline
        The one pipeline (changed by this object's methods only, under its lock).

    Notes
    -----
    The settings' methods hold the lock the thread holds while it reads and runs the pipeline,
    so a change applies between two reads. Each bundle is new arrays (or views of the
    recording's, which nobody writes): the sink may keep them.
    """

    def __init__(self, reader, *, core: CubeCore | None = None, rate_hz: float = 60.0, name: str = "pito-pipeline"):
        if not rate_hz > 0:
            raise ValueError(f"rate_hz: expected > 0 Hz, got {rate_hz!r}")
        self.simulated = bool(getattr(reader, "simulated", False))
        self.has_reference = bool(getattr(reader, "has_reference", True))
        self.replay = hasattr(reader, "seek")
        self.pipeline = Pipeline(core=core, has_reference=self.has_reference)
        self._runner = PipelineRunner(reader, self.pipeline)
        self.period = 1.0 / float(rate_hz)
        self._lock = threading.Lock()  # the runner's: one read or one request at a time
        BundleOutlet.__init__(self)
        self._stop = threading.Event()
        self.errors: list[str] = []
        self._closed = False
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        self._thread.start()

    # ------------------------------------------------------------------ the thread
    def _run(self) -> None:
        due = time.monotonic()
        while not self._stop.wait(max(0.0, due - time.monotonic())):
            due = max(due + self.period, time.monotonic())
            try:
                with self._lock:
                    b = self._runner.bundle()
            except Exception as exc:  # noqa: BLE001 - told to the consumer; the thread goes on
                self._error(f"{type(exc).__name__}: {exc}")
                continue
            self._deliver(b)

    def _error(self, message: str) -> None:
        self.errors.append(message)
        del self.errors[:-20]
        self._tell(message)

    def stats(self) -> dict:
        """The reader's latest figures (as the last bundle's ``stats``)."""
        return self._last_stats()

    # ------------------------------------------------------------------ the pipeline's state and settings
    @property
    def calibration(self):
        return self.pipeline.calibration

    @property
    def assembly(self):
        return self.pipeline.assembly

    @property
    def wrench_cov(self):
        return self.pipeline.wrench_cov

    @property
    def tare_in_force(self) -> dict | None:
        return self.pipeline.tare_in_force

    def _call(self, name: str, *args, timeout: float = 10.0):
        """A request of :class:`PipelineControls`, run on the runner under the lock (``timeout`` unused)."""
        with self._lock:
            return getattr(self._runner, name)(*args)

    def seek(self, t: float) -> None:
        """Continue the recording from ``t`` s into it (the pipeline starts over there).

        Raises
        ------
        ValueError
            The reader is not a recording.
        """
        if not self.replay:
            raise ValueError("seek: the source is not a recording")
        with self._lock:
            self._runner.reader.seek(t)

    # ------------------------------------------------------------------ lifetime
    def close(self, timeout: float = 5.0) -> None:
        """Stop the thread, close the recording (if any) and the reader (idempotent)."""
        self._stop.set()
        if self._thread.is_alive() and self._thread is not threading.current_thread():
            self._thread.join(timeout)
        with self._lock:
            if not self._closed:
                self._closed = True
                self._runner.close()

    def __enter__(self) -> "PipelineThread":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

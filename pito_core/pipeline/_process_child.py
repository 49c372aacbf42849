"""The pipeline process's side: ``python -m pito_core.pipeline._process_child START_JSON FD``.

The devices, the acquisition's collecting thread, the one :class:`~pito_core.pipeline.Pipeline`
and the recorder, served over the socket ``FD`` to the parent's
:class:`~pito_core.pipeline.PipelineProcess` (:mod:`pito_core.pipeline._process`: the protocol
and how the child ends with its parent). :class:`_Child` holds the acquisition and a
:class:`~pito_core.pipeline._runner.PipelineRunner` (the same runner as a replay's
``PipelineThread``), which answers the requests; :func:`_serve` is the loop: it waits for rows
or requests, runs the pipeline and sends a bundle. The package never imports this module, so ``-m`` runs it once.
"""

from __future__ import annotations

import contextlib
import json
import os
import sys
import time
from multiprocessing.connection import Connection, wait

import numpy as np

# the contact test's scipy.special (its import is deferred in contact/_plausibility), loaded while
# this child waits for its devices rather than at its first bundle
import scipy.special  # noqa: F401

from ..devices import die_with_parent, install_stop_signals
from ..frames import CubeCore
from ._bundle import LiveBundle
from ._open import open_acquisition
from ._pipeline import Pipeline
from ._process import _portable
from ._readers import AcquisitionReader
from ._runner import REQUESTS, PipelineRunner

__all__ = ["main"]


class _Child:
    """The child's state: the acquisition and its :class:`PipelineRunner`; :meth:`handle` answers the requests."""

    def __init__(self, cfg: dict):
        self.acq = open_acquisition(cfg["pito"], cfg.get("ati"), buffered=cfg["buffered"], buffer_seconds=10.0,
                                    reference_rate_hz=cfg["reference_rate_hz"], meta={"simulated": cfg["simulated"]})
        reader = AcquisitionReader(self.acq, simulated=cfg["simulated"], owns=True)
        core = CubeCore() if cfg.get("edge") is None else CubeCore(edge=cfg["edge"])
        self.runner = PipelineRunner(reader, Pipeline(core=core, has_reference=reader.has_reference))
        self.has_reference = reader.has_reference
        # the collecting thread writes a byte here when rows arrive: the serving loop waits on it
        # and on the parent's requests at once (no polling period in the latency)
        self.wake_r, self._wake_w = os.pipe2(os.O_NONBLOCK | os.O_CLOEXEC)
        self.acq.listener = self._rows_arrived

    def _rows_arrived(self) -> None:
        with contextlib.suppress(BlockingIOError, OSError):  # a full pipe is already a wake-up
            os.write(self._wake_w, b"\0")

    def drain_wakes(self) -> None:
        with contextlib.suppress(BlockingIOError, OSError):
            while os.read(self.wake_r, 4096):
                pass

    def handle(self, name: str, args: tuple):
        """The runner's method ``name`` (one of :data:`REQUESTS`) on ``args``."""
        if name not in REQUESTS:
            raise ValueError(f"request: unknown {name!r}")
        return getattr(self.runner, name)(*args)

    @property
    def tare_in_force(self) -> dict | None:
        return self.runner.pipeline.tare_in_force

    def bundle(self) -> LiveBundle:
        b = self.runner.bundle()
        b.stats = _plain(b.stats)
        return b

    def close(self) -> None:
        self.acq.listener = None
        with contextlib.suppress(Exception):
            self.acq.close_recording()
        self.runner.reader.close()
        for fd in (self.wake_r, self._wake_w):
            with contextlib.suppress(OSError):
                os.close(fd)


def _serve(conn: Connection, cfg: dict) -> None:
    try:
        child = _Child(cfg)
    except Exception as exc:  # noqa: BLE001 - every failure to open goes back to the parent, in words
        conn.send(("failed", f"{type(exc).__name__}: {exc}"))
        return
    signalled = install_stop_signals()
    conn.send(("ready", {"reference": child.has_reference, "pid": os.getpid()}))
    parent = os.getppid()
    gap = cfg["push_interval"]  # shortest time between two bundles (a cube that sends every frame
    last_fed = last_sent = 0.0  # alone would otherwise cost a pipeline run per frame)
    try:
        while not signalled():
            # wake when rows arrive or the parent asks something (at least 10 times a second)
            ready = wait([conn, child.wake_r], timeout=0.1)
            while conn.poll(0):
                name, rid, *args = conn.recv()
                if name == "close":
                    conn.send(("reply", rid, True, None, child.tare_in_force))
                    return
                try:  # each reply carries the tare in force after the request (the parent shows it)
                    conn.send(("reply", rid, True, child.handle(name, tuple(args)), child.tare_in_force))
                except (ValueError, OSError) as exc:  # a bad argument, or a file that cannot be written
                    conn.send(("reply", rid, False, _portable(exc), child.tare_in_force))
            if child.wake_r in ready:
                time.sleep(max(0.0, last_fed + gap - time.monotonic()))
                child.drain_wakes()
            last_fed = time.monotonic()
            b = child.bundle()
            now = time.monotonic()
            fresh = len(b) or b.arrived_time is not None
            if fresh or now - last_sent >= 0.1:  # samples, or at least the device figures 10 times a second
                conn.send(("bundle", b))
                last_sent = now
            if os.getppid() != parent:
                break
    except (EOFError, OSError):
        pass  # the parent is gone
    finally:
        child.close()


def _plain(d):
    """Stats with numpy scalars as Python numbers (picklable anywhere, JSON-able)."""
    if isinstance(d, dict):
        return {k: _plain(v) for k, v in d.items()}
    if isinstance(d, (list, tuple)):
        return [_plain(v) for v in d]
    if isinstance(d, np.generic):
        return d.item()
    return d


def main(argv=None) -> int:
    """The child's entry point: ``argv`` is ``[START_JSON, FD]`` (``{"pdeathsig": bool}``; the parent's
    socket's file descriptor); the configuration is the first message on the socket."""
    argv = sys.argv[1:] if argv is None else argv
    if json.loads(argv[0]).get("pdeathsig"):
        die_with_parent()
    conn = Connection(int(argv[1]))
    try:
        kind, cfg = conn.recv()  # the devices' addresses: the parent may learn them after starting us
    except (EOFError, OSError):
        return 0  # the parent gave up before configuring us
    if kind != "config":
        conn.send(("failed", f"expected the configuration first, got {kind!r}"))
        return 1
    _serve(conn, cfg)
    return 0


if __name__ == "__main__":
    sys.exit(main())

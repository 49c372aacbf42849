"""The devices and the one pipeline in a process of their own; the caller receives bundles.

Reading a serial port frame by frame and a Net F/T packet by packet costs a few thousand
Python wake-ups a second, and the pipeline (calibration of every sample, contacts on six
patches) a few milliseconds per read. In the desktop app all of that would share one
interpreter lock with the drawing: the window would wait for the lock on every paint call
and the devices would wait for the window. So :class:`PipelineProcess` runs the drivers, the
collecting thread, :class:`~pito_core.pipeline.Pipeline` and the recorder in a child process
(``python -m pito_core.pipeline._process_child START_JSON FD``, :mod:`._process_child`: the
child's loop) and sends the caller one
:class:`~pito_core.pipeline.LiveBundle` over a socket pair as soon as new rows arrive (the
collecting thread wakes the child's loop through a pipe; at most one bundle per
``push_interval`` s); a receiving thread (blocked in ``recv`` without the lock) hands each
to the caller's sink as it arrives (:meth:`set_sink`: the app's views take them there), or
merges them until :meth:`take`. :class:`~pito_core.pipeline.PipelineThread` has the same
interface for a pipeline run in the caller's process (a replay).
It is the same pipeline, with the same pairing rule, as ``pito record``, replay and
``pito bench``; sample times are made in the child (``CLOCK_MONOTONIC`` is one clock for
both processes).

Protocol (``multiprocessing.connection.Connection`` on a socket pair, pickled tuples)
    parent → child first: ``("config", cfg)`` (the devices and settings; the child, started by
    :class:`~pito_core.pipeline.PipelineLaunch`, imports while it waits for it).
    child → parent: ``("ready", info)`` or ``("failed", message)`` once; then ``("bundle",
    LiveBundle)`` with its ``stats`` and ``recorded`` filled, and ``("reply", id, ok, value,
    tare_in_force)`` to each request (``value`` is the request's exception, pickled, when ``ok``
    is false: :func:`_portable`; ``tare_in_force``: the pipeline's after the request).
    parent → child: ``(request, id, *args)``, requests ``set_calibration`` (Calibration or
    None), ``set_assembly`` (library name, Assembly or None; wrench covariance), ``tare``
    (duration), ``reset``, ``open_recording`` (path, meta), ``close_recording``,
    ``record_event`` (event) and ``close``.

No orphans
    The child stops when the socket reaches end of file (the parent exited or was killed),
    when its parent process changes, or on SIGTERM, which the kernel sends it when the parent
    dies (``PR_SET_PDEATHSIG``, :mod:`pito_core.devices._lifetime`). A recording it holds is
    closed on the way out (a SIGKILL of the child itself loses at most the last flush interval).
"""

from __future__ import annotations

import contextlib
import os
import pickle
import subprocess
import threading
import time

import numpy as np

from ._bundle import LiveBundle
from ._controls import PipelineControls
from ._launch import PipelineLaunch
from ._outlet import BundleOutlet

__all__ = ["PipelineProcess", "PipelineProcessError"]


class PipelineProcessError(RuntimeError):
    """The pipeline process could not start, refused a request, or ended."""


class PipelineProcess(PipelineControls, BundleOutlet):
    """The cube on ``pito`` and the Net F/T at ``ati``, read and processed in a child process.

    Parameters
    ----------
    pito : str
        Serial port of the cube (as :class:`~pito_core.devices.PitoSerial`).
    ati : str, optional
        Net F/T address ``HOST``, ``HOST:PORT`` (RDT and configuration page on PORT), or None.
    simulated : bool
        The devices are simulated (``stats["simulated"]``, recordings' metadata).
    buffered : bool
        Ask the Net F/T for buffered RDT (several records per packet).
    reference_rate_hz : float
        The Net F/T's RDT output rate, Hz.
    edge : float
        The cube's edge, m (:class:`~pito_core.frames.CubeCore`).
    push_interval : float
        Shortest time between two bundles, s: the child runs the pipeline as soon as rows arrive,
        but not more often than this (a cube that delivers every frame alone would otherwise
        cost one pipeline run per frame).
    startup_timeout : float
        Seconds to wait for the devices to open.
    launch : PipelineLaunch, optional
        A child started earlier, before the devices' addresses were known; default: start one now.

    Raises
    ------
    PipelineProcessError
        The child could not open the devices (its message says why).

    Attributes
    ----------
    calibration, assembly, wrench_cov
        The settings the child's pipeline uses (as last accepted by it; None before).
    tare_in_force : dict or None
        The child's :attr:`Pipeline.tare_in_force`, as its last reply said.

    Notes
    -----
    A consumer sets a sink (:meth:`set_sink`: called with each bundle in the receiving
    thread) or calls :meth:`take` (the bundles since the previous call, merged, or None); the
    settings of :class:`~pito_core.pipeline.Pipeline` are requests (:meth:`set_calibration`,
    :meth:`set_assembly`, :meth:`tare`, :meth:`reset`), and so is recording
    (:meth:`open_recording`, :meth:`close_recording`, :meth:`record_event`).
    """

    #: Not a recording (``PipelineThread.replay`` says whether it replays one).
    replay = False

    def __init__(self, pito: str, ati: str | None = None, *, simulated: bool = False, buffered: bool = False,
                 reference_rate_hz: float = 1000.0, edge: float | None = None, push_interval: float = 0.005,
                 startup_timeout: float = 30.0, launch: PipelineLaunch | None = None):
        if not push_interval > 0:
            raise ValueError(f"push_interval: expected > 0 s, got {push_interval!r}")
        BundleOutlet.__init__(self)
        self.simulated = bool(simulated)
        self._replies: dict = {}
        self._reply_ready = threading.Condition()
        self._next_id = 0
        self._send_lock = threading.Lock()
        self.ended: str | None = None  # why the child ended, once it has
        self.bundles_received = 0
        self._closing = False  # close() was called: the end is expected
        self.calibration = self.assembly = self.wrench_cov = None
        self.tare_in_force: dict | None = None
        cfg = {"pito": pito, "ati": ati, "buffered": bool(buffered), "reference_rate_hz": float(reference_rate_hz),
               "simulated": self.simulated, "edge": None if edge is None else float(edge),
               "push_interval": float(push_interval)}
        launch = PipelineLaunch() if launch is None else launch
        self._proc, self._conn = launch.proc, launch.conn
        self.pid = self._proc.pid
        try:
            self._conn.send(("config", cfg))  # the child has been importing meanwhile
            if not self._conn.poll(startup_timeout):
                raise PipelineProcessError(f"the pipeline process did not start within {startup_timeout} s")
            msg = self._conn.recv()
            if msg[0] != "ready":
                raise PipelineProcessError(f"opening the devices: {msg[1]}")
        except (EOFError, OSError) as exc:
            self._kill()
            raise PipelineProcessError(f"the pipeline process ended while starting ({exc!r})") from None
        except BaseException:
            self._kill()
            raise
        self.info = msg[1]
        self.has_reference = bool(self.info["reference"])
        self._receiver = threading.Thread(target=self._receive, name="PipelineProcess", daemon=True)
        self._receiver.start()

    # ------------------------------------------------------------------ receiving
    def _receive(self) -> None:
        while True:
            try:
                msg = self._conn.recv()  # blocks without the interpreter lock
            except (EOFError, OSError):
                break
            if msg[0] == "bundle":
                b, gone = msg[1], False
                try:  # bundles already waiting go with it, merged (a consumer that fell behind catches up at once)
                    while self._conn.poll(0):
                        msg = self._conn.recv()
                        if msg[0] == "bundle":
                            b = b.merged(msg[1])
                        else:
                            self._reply(msg)
                except (EOFError, OSError):
                    gone = True
                self._arrived(b)
                if gone:
                    break
            elif msg[0] == "reply":
                self._reply(msg)
        closed = self._closing
        self.ended = self.ended or f"the pipeline process (pid {self.pid}) ended"
        with self._reply_ready:
            self._reply_ready.notify_all()
        if not closed:  # the sink sees the devices gone (stats: connected False), and why
            self._arrived(LiveBundle(np.zeros(0), np.zeros((0, 36)), np.zeros((0, 6)), stats=self.stats()))
            self._tell(self.ended)

    def _reply(self, msg: tuple) -> None:
        with self._reply_ready:
            self._replies[msg[1]] = (msg[2], msg[3])
            self.tare_in_force = msg[4]
            self._reply_ready.notify_all()

    def _arrived(self, b: LiveBundle) -> None:
        """A bundle from the child: to the sink (with any kept for :meth:`take` before it), else kept."""
        self.bundles_received += 1  # (the receiving thread only)
        self._deliver(b)

    def take(self) -> LiveBundle | None:
        """The bundles received since the previous call, merged (every sample once, the latest state), or None."""
        b = BundleOutlet.take(self)
        if b is None and self.ended:
            b = LiveBundle(np.zeros(0), np.zeros((0, 36)), np.zeros((0, 6)), stats=self.stats())
        return b

    def stats(self) -> dict:
        """The latest device figures (as ``AcquisitionReader.stats``), plus ``process`` (pid, alive, why ended)."""
        s = self._last_stats()
        s["process"] = {"pid": self.pid, "alive": self.ended is None, "ended": self.ended}
        if self.ended:
            s["connected"] = False
        return s

    def _request(self, name: str, *args, timeout: float = 10.0):
        if self.ended:
            raise PipelineProcessError(f"{name}: {self.ended}")
        with self._reply_ready:
            self._next_id += 1
            rid = self._next_id
        with self._send_lock:
            try:
                self._conn.send((name, rid, *args))
            except OSError as exc:
                raise PipelineProcessError(f"{name}: the pipeline process is gone ({exc})") from None
        deadline = time.monotonic() + timeout
        with self._reply_ready:
            while rid not in self._replies:
                left = deadline - time.monotonic()
                if self.ended or left <= 0:
                    raise PipelineProcessError(f"{name}: no answer from the pipeline process"
                                               + (f" ({self.ended})" if self.ended else f" within {timeout} s"))
                self._reply_ready.wait(left)
            ok, value = self._replies.pop(rid)
        if not ok:  # the child's exception: a bad argument as itself, anything else as this process's error
            if isinstance(value, ValueError):
                raise value
            raise PipelineProcessError(f"{name}: {value}") from value
        return value

    # ------------------------------------------------------------------ settings (PipelineControls), kept here too
    def _call(self, name: str, *args, timeout: float = 10.0):
        return self._request(name, *args, timeout=timeout)

    def set_calibration(self, calibration) -> None:
        super().set_calibration(calibration)
        self.calibration = calibration

    def set_assembly(self, assembly, wrench_cov=None) -> None:
        super().set_assembly(assembly, wrench_cov)
        self.assembly, self.wrench_cov = assembly, wrench_cov

    # ------------------------------------------------------------------ lifetime
    def close(self) -> None:
        """Close the recording (if any) and the devices, and end the child process."""
        self._closing = True
        if self._proc.poll() is None and not self.ended:
            with contextlib.suppress(PipelineProcessError, ValueError):
                self._request("close", timeout=10.0)
        self.ended = self.ended or "closed"
        try:
            self._proc.wait(timeout=5.0)
        except subprocess.TimeoutExpired:
            self._kill()
        with contextlib.suppress(OSError):
            self._conn.close()

    def _kill(self) -> None:
        with contextlib.suppress(OSError):
            self._proc.kill()
        with contextlib.suppress(subprocess.TimeoutExpired):
            self._proc.wait(timeout=5.0)

    def __enter__(self) -> "PipelineProcess":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def borrowed(self) -> "_Borrowed":
        """The same process as a source whose ``close()`` leaves it running (its owner closes it)."""
        return _Borrowed(self)


class _Borrowed:
    """A :class:`PipelineProcess` lent to a consumer: everything but :meth:`close` goes to the process."""

    def __init__(self, process: PipelineProcess):
        self._process = process

    def __getattr__(self, name):
        return getattr(self._process, name)

    def close(self) -> None:
        """Leave the process running; a recording it holds is closed, and its bundles are dropped until
        the next :meth:`set_sink` (a consumer closes its source on a switch)."""
        self._process.set_sink(_drop)
        with contextlib.suppress(PipelineProcessError, ValueError):
            self._process.close_recording()


def _drop(bundle) -> None:
    """The sink of a process nobody reads (a lent process while its borrower replays a recording)."""


# ---------------------------------------------------------------------- the exceptions' crossing
def _portable(exc: Exception) -> Exception:
    """``exc`` as it can cross to the parent: itself when it survives pickling, else its
    built-in base (``ValueError`` or ``OSError``) with the type's name in the message (an
    exception whose constructor takes other arguments than its message does not unpickle).

    The child's side of a failed request's reply (:mod:`._process_child`); the parent's side is
    :meth:`PipelineProcess._request`."""
    try:
        back = pickle.loads(pickle.dumps(exc))
    except Exception:  # noqa: BLE001 - any failure to round-trip: fall back to the built-in base
        back = None
    if type(back) is type(exc) and str(back) == str(exc):
        return exc
    base = ValueError if isinstance(exc, ValueError) else OSError
    return base(f"{type(exc).__name__}: {exc}")

"""Child processes that never outlive their parent (Linux ``PR_SET_PDEATHSIG``).

Used by the acquisition process (:mod:`pito_core.devices._remote`) and the simulated devices
(:mod:`pito_core.sim._process`). ``PR_SET_PDEATHSIG`` follows the *thread* that started the
child, so a child asks for it only when its parent started it from the main thread; both
children also stop on end of file of a pipe from the parent, which covers every other case.
"""

from __future__ import annotations

import contextlib
import ctypes
import signal
import sys
import threading
from typing import Callable

__all__ = ["die_with_parent", "install_stop_signals", "process_alive"]

_PR_SET_PDEATHSIG = 1


def die_with_parent(sig: int = signal.SIGTERM) -> None:
    """Linux: the kernel sends ``sig`` to this process when its parent (thread) dies; no-op elsewhere."""
    if not sys.platform.startswith("linux"):
        return
    with contextlib.suppress(OSError, AttributeError):
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(_PR_SET_PDEATHSIG, int(sig), 0, 0, 0)


def install_stop_signals(signals=(signal.SIGTERM, signal.SIGINT)) -> Callable[[], bool]:
    """Note SIGTERM/SIGINT in a flag; returns ``signalled() -> bool`` for the main loop to poll.

    The handler only sets a flag. It must take no lock: a handler runs on the main thread
    between two bytecodes, possibly while that thread holds the very lock (for example inside
    ``threading.Event.wait``), and a second signal then deadlocks the process for good — a
    child that can never be stopped. Called off the main thread (where handlers cannot be
    installed), it installs nothing and ``signalled()`` stays False.
    """
    flag = [False]

    def handler(*_):
        flag[0] = True

    if threading.current_thread() is threading.main_thread():
        for sig in signals:
            signal.signal(sig, handler)
    return lambda: flag[0]


def process_alive(pid: int) -> bool:
    """Linux: ``pid`` runs (exists and is not a zombie); used to check that no child outlived its parent."""
    try:
        with open(f"/proc/{int(pid)}/stat") as fh:
            return fh.read().rsplit(")", 1)[1].split()[0] != "Z"
    except (OSError, IndexError):
        return False

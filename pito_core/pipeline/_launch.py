"""Start the pipeline's child process before its devices are known, with the standard library only.

:class:`PipelineLaunch` starts ``python -m pito_core.pipeline._process_child START_JSON FD``: the child
imports the drivers and the pipeline at once and waits for its configuration (the devices'
addresses), the first message on the socket; ``PipelineProcess(pito, ati, launch=...)`` sends
it (:mod:`._process`: the protocol). ``pito-app --demo`` launches it on its first line, beside
the simulated devices (whose addresses it needs), so neither child waits for the other's
imports (docs/app.md, "Start-up").
"""

from __future__ import annotations

import contextlib
import json
import socket
import subprocess
import sys
import threading
from multiprocessing.connection import Connection

__all__ = ["PipelineLaunch"]


class PipelineLaunch:
    """The pipeline's child process, started and importing; waiting for its configuration.

    Attributes
    ----------
    proc : subprocess.Popen
    conn : multiprocessing.connection.Connection
        The parent's end of the socket pair (``PipelineProcess`` takes it over).
    pdeathsig : bool
        Started from the main thread: the child asks for SIGTERM when it ends (``PR_SET_PDEATHSIG``).
    """

    def __init__(self):
        self.pdeathsig = threading.current_thread() is threading.main_thread()
        mine, theirs = socket.socketpair()
        try:
            self.proc = subprocess.Popen(
                [sys.executable, "-m", "pito_core.pipeline._process_child", json.dumps({"pdeathsig": self.pdeathsig}),
                 str(theirs.fileno())], pass_fds=(theirs.fileno(),), stdin=subprocess.DEVNULL)
        except BaseException:
            mine.close()
            raise
        finally:
            theirs.close()
        self.conn = Connection(mine.detach())

    def close(self) -> None:
        """End the child if nobody took it over (it stops at the socket's end of file); idempotent."""
        with contextlib.suppress(OSError):
            self.conn.close()
        try:
            self.proc.wait(timeout=5.0)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()

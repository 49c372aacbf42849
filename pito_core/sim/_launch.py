"""Start the simulated devices' child process early, with the standard library only.

:class:`DevicesLaunch` starts ``python -m pito_core.sim._child CONFIG`` (:mod:`._process`: the
announcement, the control channel, no orphans) and returns at once;
``SimulatedDevices(launch=...)`` then reads its announcement. ``pito-app --demo`` launches the
child on its first line, so the child boots while the app imports Qt, VTK and the core
(docs/app.md, "Start-up"); importing this module costs nothing else.
"""

from __future__ import annotations

import contextlib
import json
import subprocess
import sys
import threading

__all__ = ["DevicesLaunch"]


class DevicesLaunch:
    """The simulated devices' child process, started; not yet announced.

    Parameters
    ----------
    seed, speed, period, scenario, assembly, rate_hz
        As :func:`~pito_core.sim.run_devices` (``speed``: simulated seconds per wall second).

    Attributes
    ----------
    proc : subprocess.Popen
        The child (stdin and stdout are pipes: the announcement, and its end-of-file watch).
    cfg : dict
        The configuration it was given.
    """

    def __init__(self, seed: int = 0, speed: float = 1.0, period: float = 1.5, scenario: str = "grasp",
                 assembly: str | None = None, rate_hz: float = 1000.0):
        if not speed > 0 or speed == float("inf"):
            raise ValueError(f"speed: expected a finite speed > 0 (simulated s per wall s), got {speed!r}")
        # PR_SET_PDEATHSIG fires when the *thread* that started the child ends: ask for it only
        # from the main thread (the stdin pipe and the getppid poll cover every other case)
        self.cfg = {"seed": int(seed), "speed": float(speed), "period": float(period), "scenario": scenario,
                    "assembly": assembly, "rate_hz": float(rate_hz),
                    "pdeathsig": threading.current_thread() is threading.main_thread()}
        self.proc = subprocess.Popen([sys.executable, "-m", "pito_core.sim._child", json.dumps(self.cfg)],
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)

    def close(self, timeout: float = 5.0) -> None:
        """End the child if nobody took it over (closing its stdin, then SIGKILL); idempotent."""
        if self.proc.poll() is None:
            with contextlib.suppress(OSError):
                self.proc.stdin.close()
            try:
                self.proc.wait(timeout=timeout)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()

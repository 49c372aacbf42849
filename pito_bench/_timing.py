"""Timing and process helpers: best-of timers, one-core subprocesses, peak memory.

Every benchmark figure is measured in a fresh Python process (``python -m
pito_bench._worker``) whose BLAS/OpenMP pools are limited to ``threads`` threads
(environment variables set before numpy loads), so figures are "on one core" by default
and the peak resident memory of the process is that of the measurement alone.
"""

from __future__ import annotations

import json
import os
import resource
import subprocess
import sys
import time

__all__ = ["best_time", "thread_env", "run_worker", "peak_rss_mb", "WorkerError"]

_THREAD_VARS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "BLIS_NUM_THREADS",
                "VECLIB_MAXIMUM_THREADS", "NUMEXPR_NUM_THREADS")


class WorkerError(RuntimeError):
    """A benchmark subprocess failed (its stderr tail is in the message)."""


def best_time(fn, repeat: int = 3, budget: float | None = None, clock=time.perf_counter) -> tuple[float, object]:
    """Smallest wall time of ``repeat`` calls of ``fn()`` (s), and the last result.

    The minimum is the figure least disturbed by other load on the machine. With
    ``budget`` (s), stops repeating once that much time has been spent (at least once).
    ``clock=time.process_time`` gives the process's CPU time instead (one-thread work on
    a shared machine: the time other jobs take from it is not counted).
    """
    best, out, spent = float("inf"), None, 0.0
    for _ in range(max(1, int(repeat))):
        t0 = clock()
        out = fn()
        dt = clock() - t0
        best, spent = min(best, dt), spent + dt
        if budget is not None and spent >= budget:
            break
    return best, out


def thread_env(threads: int = 1) -> dict:
    """The current environment with every BLAS/OpenMP pool limited to ``threads``."""
    env = dict(os.environ)
    for k in _THREAD_VARS:
        env[k] = str(int(threads))
    return env


def peak_rss_mb() -> float:
    """Peak resident memory of this process so far, MB (10⁶ B)."""
    kb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss  # KiB on Linux
    return kb * 1024 / 1e6


def run_worker(task: str, params: dict, *, threads: int = 1, timeout: float = 3600.0, module: str = "pito_bench._worker") -> dict:
    """Run ``python -m module task params`` in a fresh process; return its JSON answer.

    The child prints one JSON object on its last stdout line. Its peak resident memory
    (``ru_maxrss`` of the child, read by the child itself) is in ``peak_rss_mb``.
    """
    cmd = [sys.executable, "-m", module, task, json.dumps(params)]
    proc = subprocess.run(cmd, env=thread_env(threads), capture_output=True, text=True, timeout=timeout)
    lines = [ln for ln in proc.stdout.splitlines() if ln.strip()]
    if proc.returncode != 0 or not lines:
        tail = "\n".join(proc.stderr.strip().splitlines()[-15:])
        raise WorkerError(f"benchmark task {task!r} failed (exit {proc.returncode}):\n{tail}")
    return json.loads(lines[-1])

"""A study: many recordings, one task each, on Dask (docs/analysis.md, "Studies on Dask").

``client.map(task, recordings)`` and ``as_completed``: each task is a pure function of one
recording that writes its own output atomically (:func:`analyze_to_dir`,
:func:`export_to_dir`), so a rerun skips what is done and a failed recording costs only
itself. A local cluster by default (scheduler, workers and dashboard on 127.0.0.1), or an
existing one by address. Workers run one thread each, so a worker holds one recording at a
time; ``memory_limit`` bounds each worker (Dask pauses, then restarts a worker above it).

``dask[distributed]`` is an optional dependency (extra ``analysis``), imported here only.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

from ._optional import require

__all__ = ["StudyResult", "local_cluster", "run_study", "run_serial", "require_distributed"]


def require_distributed():
    """The ``distributed`` module, or an ImportError naming the extra to install."""
    return require("distributed", "a study on Dask", "dask[distributed]")


@dataclass
class StudyResult:
    """What a study did.

    Attributes
    ----------
    results : list of dict
        One per finished recording (the task's return value), in completion order.
    failed : dict
        Recording → error message, for the recordings whose task raised.
    seconds : float
        Wall time of the study, s (a local cluster's start and stop included).
    compute_seconds : float
        From the first task submitted to the last finished, s.
    workers : int
        Dask workers (0: the single-process path).
    cancelled : bool
    """

    results: list = field(default_factory=list)
    failed: dict = field(default_factory=dict)
    seconds: float = 0.0
    compute_seconds: float = 0.0
    workers: int = 0
    cancelled: bool = False

    @property
    def samples(self) -> int:
        """Cube samples processed (skipped recordings count 0)."""
        return int(sum(r.get("samples") or 0 for r in self.results))

    @property
    def samples_per_s(self) -> float:
        """Samples per second of compute (first submit to last result)."""
        return self.samples / self.compute_seconds if self.compute_seconds > 0 else float("nan")


def _check_names(recordings) -> list[str]:
    paths = [str(r) for r in recordings]
    stems = [Path(p).stem for p in paths]
    dup = sorted({s for s in stems if stems.count(s) > 1})
    if dup:
        raise ValueError(f"recordings: output folders are named by file stem; these occur twice: {', '.join(dup)}")
    if not paths:
        raise ValueError("recordings: expected at least one recording")
    return paths


def run_serial(task, recordings, progress=None, **kwargs) -> StudyResult:
    """The single-process path: ``task(recording, **kwargs)`` one after the other (same results as Dask).

    ``progress(done, total, result_or_None, recording, error_or_None)``; a true return cancels.
    """
    paths = _check_names(recordings)
    out = StudyResult()
    t0 = time.perf_counter()
    for k, p in enumerate(paths):
        try:
            res, err = task(p, **kwargs), None
            out.results.append(res)
        except Exception as exc:  # a failed recording is reported by name; the others go on
            res, err = None, f"{type(exc).__name__}: {exc}"
            out.failed[p] = err
        if progress is not None and progress(k + 1, len(paths), res, p, err):
            out.cancelled = True
            break
    out.seconds = out.compute_seconds = time.perf_counter() - t0
    return out


def local_cluster(n_workers: int, memory_limit="2GiB", dashboard: bool = False):
    """A loopback-only ``LocalCluster``: processes, one thread each; dashboard on 127.0.0.1 (random port) or off."""
    distributed = require_distributed()
    return distributed.LocalCluster(n_workers=int(n_workers), threads_per_worker=1, processes=True,
                                    host="127.0.0.1", dashboard_address="127.0.0.1:0" if dashboard else None,
                                    memory_limit=memory_limit)


def run_study(task, recordings, *, scheduler: str | None = None, n_workers: int = 2, memory_limit="2GiB",
              dashboard: bool = False, progress=None, **kwargs) -> StudyResult:
    """Run ``task(recording, **kwargs)`` for every recording on Dask.

    Parameters
    ----------
    task : callable
        A pure, importable function of one recording (e.g. :func:`analyze_to_dir`).
    recordings : sequence of path
    scheduler : str, optional
        Address of an existing Dask scheduler (``tcp://host:8786``); default a local cluster.
    n_workers : int
        Workers of the local cluster (one thread each).
    memory_limit : str or int
        Per worker of the local cluster (e.g. ``"2GiB"``).
    dashboard : bool
        Serve the local cluster's dashboard on 127.0.0.1 (its address goes to ``progress``'s
        first call as ``recording=None``, ``error=link``).
    progress : callable, optional
        ``progress(done, total, result_or_None, recording, error_or_None)`` after each
        recording; a true return cancels the rest.
    """
    distributed = require_distributed()
    paths = _check_names(recordings)
    if scheduler is None and int(n_workers) < 1:
        raise ValueError(f"n_workers: expected >= 1, got {n_workers!r}")
    out = StudyResult()
    t0 = time.perf_counter()
    cluster = None if scheduler else local_cluster(n_workers, memory_limit, dashboard)
    try:
        with distributed.Client(scheduler or cluster) as client:
            out.workers = len(client.scheduler_info()["workers"])
            if progress is not None and dashboard and cluster is not None:
                progress(0, len(paths), None, None, client.dashboard_link)
            t_submit = time.perf_counter()
            futures = client.map(task, paths, pure=False, **kwargs)
            names = {f.key: p for f, p in zip(futures, paths)}
            for k, fut in enumerate(distributed.as_completed(futures), start=1):
                p, res, err = names[fut.key], None, None
                if fut.status == "error":
                    exc = fut.exception()
                    err = f"{type(exc).__name__}: {exc}"
                    out.failed[p] = err
                else:
                    res = fut.result()
                    out.results.append(res)
                if progress is not None and progress(k, len(paths), res, p, err):
                    client.cancel([f for f in futures if not f.done()])
                    out.cancelled = True
                    break
            out.compute_seconds = time.perf_counter() - t_submit
    finally:
        if cluster is not None:
            cluster.close()
    out.seconds = time.perf_counter() - t0
    return out

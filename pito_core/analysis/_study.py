"""A study: many recordings, one task each, on Dask (docs/analysis.md, "Studies on Dask").

``client.map(task, recordings)`` and ``as_completed``: each task is a pure function of one
recording (:func:`analyze_to_dir`, :func:`export_to_dir`), so a rerun skips what is done and
a failed recording costs only itself. A local cluster by default (scheduler, workers and
dashboard on 127.0.0.1), or an existing one by address. Workers run one thread each, so a
worker holds one recording at a time; ``memory_limit`` bounds each worker (Dask pauses, then
restarts a worker above it).

On Dask the workers need not share the client's disk for the results nor its working
directory: the recordings' paths are made absolute on the client (the workers read them
there: a shared or identical path), each task writes into a temporary folder of its worker
and sends the files back, and the client writes them under ``out_root`` (absolute on the
client) atomically, as the in-process path does (a temporary name, then a rename). A worker
lost during the study and the recordings run again because of it are in the result
(:attr:`StudyResult.lost_workers`, :attr:`StudyResult.rerun`).

``dask[distributed]`` is an optional dependency (extra ``analysis``), imported here only.
"""

from __future__ import annotations

import os
import shutil
import tempfile
import time
import uuid
from dataclasses import dataclass, field
from pathlib import Path

from ._optional import require
from ._output import analyze_to_dir, atomic_dir, export_to_dir, output_dir

#: Event topic of the tasks' starts (``Worker.log_event``): a recording started twice was rerun.
TASK_EVENTS = "pito-study-task"

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
    lost_workers : list of str
        Addresses of the workers that left the cluster during the study (killed, crashed,
        restarted above their memory limit); Dask reran their unfinished tasks elsewhere.
    rerun : dict
        Recording → the workers it was started on, for each recording started more than once.
    """

    results: list = field(default_factory=list)
    failed: dict = field(default_factory=dict)
    seconds: float = 0.0
    compute_seconds: float = 0.0
    workers: int = 0
    cancelled: bool = False
    lost_workers: list = field(default_factory=list)
    rerun: dict = field(default_factory=dict)

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


def _targets(task, recording, kwargs) -> list[Path] | None:
    """What ``task`` writes for ``recording`` under ``kwargs["out_root"]`` (None: unknown, never skipped)."""
    root = kwargs.get("out_root")
    if root is None:
        return None
    if task is analyze_to_dir:
        return [output_dir(recording, root)]
    if task is export_to_dir:
        return [Path(root) / f"{Path(recording).stem}.{f}" for f in kwargs.get("formats", ("nwb",))]
    return None


def _on_worker(task, recording, **kwargs) -> tuple[dict, dict, str]:
    """``task`` on a worker, into a temporary folder of its own: ``(result (with its ``worker``), {relative path: bytes},
    the temporary folder)`` (the folder's name is replaced by the client's ``out_root`` in the result)."""
    distributed = require_distributed()
    try:
        worker = distributed.get_worker()
        address = worker.address
        worker.log_event(TASK_EVENTS, {"recording": recording, "worker": address})
    except ValueError:  # not on a worker (a synchronous client in a test)
        address = ""
    with tempfile.TemporaryDirectory(prefix="pito-task-") as d:
        res = task(recording, **({**kwargs, "out_root": d} if "out_root" in kwargs else kwargs))
        files = {p.relative_to(d).as_posix(): p.read_bytes() for p in sorted(Path(d).rglob("*")) if p.is_file()}
    res = dict(res)
    res["worker"] = address
    return res, files, d


def _write_back(files: dict, out_root: Path) -> None:
    """Write a task's files under ``out_root``: each top-level folder atomically (:class:`atomic_dir`), each file by rename."""
    folders: dict = {}
    for rel, data in files.items():
        head, _, rest = rel.partition("/")
        if rest:
            folders.setdefault(head, {})[rest] = data
        else:
            out_root.mkdir(parents=True, exist_ok=True)
            target = out_root / head
            tmp = target.with_name(f".{target.stem}.tmp-{os.getpid()}-{uuid.uuid4().hex[:8]}{target.suffix}")
            try:
                tmp.write_bytes(data)
                os.replace(tmp, target)
            finally:
                tmp.unlink(missing_ok=True)
    for head, content in folders.items():
        target = out_root / head
        if target.exists():  # --overwrite: the new results replace the old
            shutil.rmtree(target)
        with atomic_dir(target) as tmp:
            for rel, data in content.items():
                (tmp / rel).parent.mkdir(parents=True, exist_ok=True)
                (tmp / rel).write_bytes(data)


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
        except ImportError:  # a missing optional dependency fails every recording: say so once
            raise
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
    dask = require("dask", "a study on Dask", "dask[distributed]")

    # Dask spawns its workers with MALLOC_TRIM_THRESHOLD_=65536, which turns off glibc's
    # dynamic mmap threshold: every large numpy array is then mapped and faulted in afresh,
    # and the analysis costs twice the CPU of the same task in process (0.40 against 0.19
    # CPU-s on 30 000 samples, measured 2026-12-06). The workers keep glibc's defaults.
    # Without a dashboard nobody reads the workers' statistical profiles or GIL contention:
    # their sampling threads cost ~8 % of a task's CPU.
    conf = {"distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None}
    if not dashboard:
        conf.update({"distributed.worker.profile.enabled": False, "distributed.admin.system-monitor.gil.enabled": False})
    with dask.config.set(conf):
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
    given = _check_names(recordings)
    if scheduler is None and int(n_workers) < 1:
        raise ValueError(f"n_workers: expected >= 1, got {n_workers!r}")
    paths = [os.path.abspath(p) for p in given]  # resolved here: the workers' working directory is theirs
    out_root = Path(os.path.abspath(kwargs.pop("out_root"))) if kwargs.get("out_root") is not None else None
    overwrite = bool(kwargs.get("overwrite", False))
    out = StudyResult()
    t0 = time.perf_counter()
    cluster = None if scheduler else local_cluster(n_workers, memory_limit, dashboard)
    try:
        with distributed.Client(scheduler or cluster) as client:
            seen = set(client.scheduler_info()["workers"])
            out.workers = len(seen)
            if progress is not None and dashboard and cluster is not None:
                progress(0, len(paths), None, None, client.dashboard_link)
            t_submit, t_wall = time.perf_counter(), time.time()
            todo, k = [], 0
            for g, p in zip(given, paths):
                targets = _targets(task, p, {**kwargs, "out_root": out_root})
                if targets and not overwrite and all(t.exists() for t in targets):
                    k += 1
                    res = {"recording": g, "status": "skipped", "out": str(out_root), "samples": 0, "trials": None,
                           "seconds": 0.0, "simulated": None}
                    out.results.append(res)
                    if progress is not None and progress(k, len(paths), res, g, None):
                        out.cancelled = True
                        return out
                else:
                    todo.append((g, p))
            extra = {} if out_root is None else {"out_root": str(out_root)}
            futures = client.map(_on_worker, [task] * len(todo), [p for _, p in todo], pure=False, **kwargs, **extra)
            names = {f.key: g for f, (g, _) in zip(futures, todo)}
            for k, fut in enumerate(distributed.as_completed(futures), start=k + 1):
                g, res, err = names[fut.key], None, None
                seen |= set(client.scheduler_info()["workers"])
                if fut.status == "error":
                    exc = fut.exception()
                    err = f"{type(exc).__name__}: {exc}"
                    out.failed[g] = err
                else:
                    res, files, tmp = fut.result()
                    res["recording"] = g
                    if out_root is not None:
                        _write_back(files, out_root)
                        res["out"] = str(res.get("out", "")).replace(tmp, str(out_root))
                    out.results.append(res)
                if progress is not None and progress(k, len(paths), res, g, err):
                    client.cancel([f for f in futures if not f.done()])
                    out.cancelled = True
                    break
            out.compute_seconds = time.perf_counter() - t_submit
            out.lost_workers = sorted(seen - set(client.scheduler_info()["workers"]))
            out.rerun = _reruns(client, set(paths), dict(zip(paths, given)), names, t_wall)
    finally:
        if cluster is not None:
            cluster.close()
        out.seconds = time.perf_counter() - t0
    return out


def _reruns(client, paths: set, names: dict, keys: dict, since: float) -> dict:
    """Recording (as given) → the workers it was started on, for those started more than once in this study.

    From the tasks' start events (:data:`TASK_EVENTS`) and the scheduler's ``remove-worker`` events
    (a task processing on a worker that left is run again elsewhere, even if it had not logged its start).
    """
    started: dict = {}
    for _, msg in client.get_events(TASK_EVENTS):
        if isinstance(msg, dict) and msg.get("recording") in paths:
            started.setdefault(names[msg["recording"]], []).append(msg.get("worker"))
    for t, msg in client.get_events("all"):
        if t < since or not isinstance(msg, dict) or msg.get("action") != "remove-worker":
            continue
        for key in msg.get("processing-tasks") or ():
            rec = keys.get(key)
            if rec is not None and msg.get("worker") not in started.setdefault(rec, []):
                started[rec].insert(0, msg.get("worker"))
    return {rec: w for rec, w in started.items() if len(w) > 1}

"""One recording → one output folder, written atomically (the unit of work of a study).

``OUT/<stem>/`` holds ``phases.csv``, ``patches.csv``, ``trial_NN.png``, ``summary.json``
(and ``<stem>.nwb`` with ``--nwb``). Everything is written into a hidden temporary folder
beside it, then renamed in one step: a folder that exists is complete, so a rerun skips it
(the target-file habit of make and Snakemake); a killed run leaves only a temporary folder,
removed by the next run of the same recording.
"""

from __future__ import annotations

import json
import os
import resource
import shutil
import socket
import time
import uuid
from pathlib import Path

from ..calibration import load_calibration
from ..interop import append_grasp_phases, export_data, write_mcap, write_nwb
from ._analyze import GraspAnalysis, analyze_data, analyze_recording
from ._figures import save_overview_figure, save_trial_figures
from ._metrics import PATCH_COLUMNS, PHASE_COLUMNS
from ._segment import AnalysisSettings

__all__ = ["write_analysis", "analyze_to_dir", "export_to_dir", "output_dir", "atomic_dir", "cpu_seconds", "peak_rss_mib"]


def output_dir(recording, out_root) -> Path:
    """The folder of ``recording``'s results under ``out_root``: ``out_root/<file stem>``."""
    return Path(out_root) / Path(recording).stem


class atomic_dir:
    """``with atomic_dir(target) as tmp:`` write into ``tmp``; on success it becomes ``target``.

    The temporary folder ``.<name>.tmp-<host>-<pid>-<random>`` is removed on error. Leftovers
    of killed runs are removed on entry, but only those of this host whose process is gone (a
    concurrent run's folder is left alone). If ``target`` appears meanwhile (the same
    recording finished by another task, e.g. one Dask ran twice), the first one stays and
    ``finished_by_other`` is set.
    """

    def __init__(self, target):
        self.target = Path(target)
        self.tmp = self.target.parent / f".{self.target.name}.tmp-{_HOST}-{os.getpid()}-{uuid.uuid4().hex[:8]}"
        self.finished_by_other = False

    def __enter__(self) -> Path:
        self.target.parent.mkdir(parents=True, exist_ok=True)
        for old in self.target.parent.glob(f".{self.target.name}.tmp-{_HOST}-*"):
            if not _alive(old.name.split(f".tmp-{_HOST}-", 1)[1].split("-")[0]):
                shutil.rmtree(old, ignore_errors=True)
        self.tmp.mkdir()
        return self.tmp

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is not None:
            shutil.rmtree(self.tmp, ignore_errors=True)
            return
        try:
            os.replace(self.tmp, self.target)
        except OSError:
            if not self.target.is_dir():
                raise
            shutil.rmtree(self.tmp, ignore_errors=True)
            self.finished_by_other = True


_HOST = socket.gethostname().replace("-", "_")


def _alive(pid: str) -> bool:
    """A process with this id exists on this host."""
    try:
        os.kill(int(pid), 0)
    except (ValueError, ProcessLookupError):
        return False
    except PermissionError:
        return True
    return True


def figure_choice(figures) -> str:
    """``figures`` as one of :data:`~pito_core.analysis.FIGURE_CHOICES` (True: ``"trials"``, False/None: ``"none"``)."""
    from . import FIGURE_CHOICES

    if figures is True:
        return "trials"
    if figures is False or figures is None:
        return "none"
    if figures not in FIGURE_CHOICES:
        raise ValueError(f"figures: expected one of {', '.join(FIGURE_CHOICES)}, got {figures!r}")
    return figures


def write_analysis(analysis: GraspAnalysis, directory, *, figures="trials") -> list[Path]:
    """Write the tables (CSV), the figures (PNG) and ``summary.json`` into ``directory``.

    ``figures``: ``"none"``, ``"overview"`` (``overview.png``, one per recording) or ``"trials"``
    (the overview and ``trial_NN.png`` per trial); True means ``"trials"``, False ``"none"``.
    """
    figures = figure_choice(figures)
    d = Path(directory)
    out = [d / "phases.csv", d / "patches.csv"]
    analysis.phases.to_csv(out[0], index=False)
    analysis.patches.to_csv(out[1], index=False)
    if figures != "none":
        out.append(save_overview_figure(analysis, d))
    if figures == "trials":
        out += save_trial_figures(analysis, d)
    summary = {k: v for k, v in analysis.meta.items()}
    summary["settings"] = {k: getattr(analysis.settings, k) for k in analysis.settings.__dataclass_fields__}
    summary["columns"] = {"phases.csv": PHASE_COLUMNS, "patches.csv": PATCH_COLUMNS}
    (d / "summary.json").write_text(json.dumps(summary, indent=1, default=str))
    out.append(d / "summary.json")
    return out


def _load_calibration(calibration):
    """A Calibration from a path (None and Calibration objects pass through)."""
    if calibration is None or not isinstance(calibration, (str, os.PathLike)):
        return calibration
    return load_calibration(calibration)


def analyze_to_dir(recording, out_root, *, calibration=None, assembly=None, settings: AnalysisSettings | None = None,
                   nwb: bool = False, figures="overview", overwrite: bool = False, recover: bool = False) -> dict:
    """Analyse ``recording`` into ``output_dir(recording, out_root)`` atomically; skip it if done.

    ``figures`` as :func:`write_analysis` (default one overview figure per recording).
    ``recover``: read an incomplete (killed) recording's intact part.

    A pure function of its arguments (a Dask task): ``calibration`` is a file path (or a
    Calibration, or None for the recording's own). Returns ``{"recording", "status"
    ("done" or "skipped"), "out", "samples", "trials", "seconds" (wall), "cpu_seconds", "simulated",
    "max_rss_MiB" (peak of the process that ran it)}``.
    """
    target = output_dir(recording, out_root)
    if target.exists() and not overwrite:
        return {"recording": str(recording), "status": "skipped", "out": str(target), "samples": 0, "trials": None,
                "seconds": 0.0, "simulated": None}
    figure_choice(figures)  # a wrong choice fails before the recording is read
    t0, c0 = time.perf_counter(), cpu_seconds()
    cal = _load_calibration(calibration)
    source = str(calibration) if isinstance(calibration, (str, os.PathLike)) else None
    if nwb:  # one pipeline run for the analysis and the NWB export
        data = export_data(recording, cal, assembly, calibration_source=source, recover=recover)
        analysis = analyze_data(data, settings, source=recording)
    else:
        analysis = analyze_recording(recording, cal, assembly, settings, calibration_source=source, recover=recover)
    if overwrite and target.exists():
        shutil.rmtree(target)
    out = atomic_dir(target)
    with out as tmp:
        write_analysis(analysis, tmp, figures=figures)
        if nwb:
            _write_nwb(data, analysis, tmp / f"{target.name}.nwb")
    return {"recording": str(recording), "status": "done (by another task)" if out.finished_by_other else "done", "out": str(target), "samples": analysis.meta["n_samples"],
            "trials": len(analysis.trials), "seconds": time.perf_counter() - t0, "simulated": analysis.simulated,
            "cpu_seconds": cpu_seconds() - c0, "max_rss_MiB": peak_rss_mib()}


def cpu_seconds() -> float:
    """CPU time (user + system) of this process so far, s."""
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def peak_rss_mib() -> float:
    """Peak resident memory of this process so far, MiB (``getrusage``; a Dask worker's own peak)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def _write_nwb(data, analysis, path) -> None:
    """The NWB export of ``data`` (:func:`~pito_core.interop.export_data`) plus its ``grasp_phases`` intervals table."""
    write_nwb(data, path)
    append_grasp_phases(path, analysis.phases, PHASE_COLUMNS)


def export_to_dir(recording, out_root, formats=("nwb",), *, calibration=None, assembly=None, contacts: bool = True,
                  overwrite: bool = False) -> dict:
    """``pito export`` of one recording into ``out_root/<stem>.<suffix>`` (atomic per file; skip existing).

    ``formats``: some of ``nwb``, ``mcap``. Returns ``{"recording", "status", "out", "samples", "seconds"}``.
    """
    writers = {"nwb": write_nwb, "mcap": write_mcap}
    bad = set(formats) - set(writers)
    if bad or not formats:
        raise ValueError(f"formats: expected some of {sorted(writers)}, got {sorted(formats)}")
    stem = Path(recording).stem
    targets = {f: Path(out_root) / f"{stem}.{f}" for f in formats}
    todo = [f for f, p in targets.items() if overwrite or not p.exists()]
    if not todo:
        return {"recording": str(recording), "status": "skipped", "out": str(out_root), "samples": 0, "seconds": 0.0}
    t0, c0 = time.perf_counter(), cpu_seconds()
    cal = _load_calibration(calibration)
    source = str(calibration) if isinstance(calibration, (str, os.PathLike)) else None
    data = export_data(recording, cal, assembly, calibration_source=source, contacts=contacts)
    Path(out_root).mkdir(parents=True, exist_ok=True)
    for f in todo:
        tmp = targets[f].with_name(f".{stem}.tmp-{os.getpid()}-{uuid.uuid4().hex[:8]}.{f}")  # keeps the suffix
        try:
            writers[f](data, tmp)
            os.replace(tmp, targets[f])
        finally:
            tmp.unlink(missing_ok=True)
    return {"recording": str(recording), "status": "done", "out": str(out_root), "samples": data.n,
            "seconds": time.perf_counter() - t0, "cpu_seconds": cpu_seconds() - c0, "max_rss_MiB": peak_rss_mib()}

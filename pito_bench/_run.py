"""``run_bench``: run the sections of ``pito bench`` and collect one JSON-able result."""

from __future__ import annotations

import datetime as _dt
import importlib.util
import json
import math
import os
import platform
import shutil
import subprocess
import sys
import tempfile

import numpy
import scipy

from pito_core import __version__

from ._analysis import run_analysis
from ._calibration import coverage_cubes, random_cube_ratios, run_calibration
from ._model_choice import model_choice_ratios
from ._contact import run_contact
from ._pipeline import run_pipeline
from ._report import targets
from ._soak import run_soak
from ._timing import thread_env

__all__ = ["SECTIONS", "FULL_SIZES", "QUICK_SIZES", "run_bench", "live_available", "json_safe"]

#: Sections in run order; ``live`` needs the app extras (PySide6, pyvista).
SECTIONS = ("calibration", "contact", "pipeline", "analysis", "live")
#: Sections run only when named (long): ``soak`` = 10 min recording by pito-app --demo (1 min with --quick).
EXTRA_SECTIONS = ("soak",)
#: Calibration sizes k (samples per session) of a full and of a quick run.
FULL_SIZES = (1_000, 10_000, 100_000, 1_000_000, 10_000_000)
QUICK_SIZES = (1_000, 10_000, 100_000)


def json_safe(obj):
    """``obj`` with NaN and ±inf floats replaced by None (strict JSON has no NaN)."""
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: json_safe(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [json_safe(v) for v in obj]
    return obj


def live_available() -> bool:
    """True if the app extras (PySide6, pyvista, the ``app`` package) are importable."""
    try:
        return all(importlib.util.find_spec(m) is not None for m in ("PySide6", "pyvista", "app"))
    except (ImportError, ValueError):
        return False


def _meta(quick: bool, threads: int) -> dict:
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as f:
            cpu = next((ln.split(":", 1)[1].strip() for ln in f if ln.startswith("model name")), cpu)
    except OSError:  # pragma: no cover
        pass
    try:
        load = [round(x, 2) for x in os.getloadavg()]
    except OSError:  # pragma: no cover
        load = None
    return {"date": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"), "pito": __version__,
            "python": platform.python_version(), "numpy": numpy.__version__, "scipy": scipy.__version__,
            "cpu": cpu, "cpus": os.cpu_count(), "loadavg": load, "quick": quick, "threads": threads,
            "note": "every time is compared with a baseline measured in the same run (ratios); data are simulated"}


def _run_live(quick: bool, threads: int, progress) -> dict:
    if not live_available():
        return {"status": "skipped: app extras not installed"}
    progress("live: the whole demo window on Xvfb, grabbed from outside (python -m pito_bench._live_window)")
    cmd = [sys.executable, "-m", "pito_bench._live_window", "--json"] + (["--quick"] if quick else [])
    proc = subprocess.run(cmd, env=thread_env(threads), capture_output=True, text=True, timeout=900)
    lines = [ln for ln in proc.stdout.splitlines() if ln.strip()]
    if proc.returncode != 0 or not lines:
        tail = " | ".join(proc.stderr.strip().splitlines()[-5:])
        return {"status": f"failed: exit {proc.returncode}: {tail}"}
    return json.loads(lines[-1])


def run_bench(*, quick: bool = False, sections=SECTIONS, sizes=None, threads: int = 1, workdir=None,
              contact_sizes=None, progress=None) -> dict:
    """Run the benchmark sections; every measurement in a fresh subprocess.

    Parameters
    ----------
    quick : bool
        Small sizes (a run of well under a minute on a quiet 2-core machine).
    sections : sequence of str
        Any of :data:`SECTIONS`.
    sizes : sequence of int, optional
        Calibration sizes k (samples); default :data:`FULL_SIZES` or :data:`QUICK_SIZES`.
    threads : int
        BLAS/OpenMP threads of the measuring processes (1: "on one core").
    workdir : str, optional
        Where the simulated session files go (default: a temporary directory, removed).
    contact_sizes : dict, optional
        ``n_speed``, ``n_acc``, ``n_scipy`` overrides for the contact section.
    progress : callable, optional
        ``progress(str)`` for status lines (default: silent).

    Returns
    -------
    dict
        ``meta``, one key per section run, and ``targets``; JSON-ready (NaN → None).
    """
    progress = progress or (lambda s: None)
    unknown = set(sections) - set(SECTIONS) - set(EXTRA_SECTIONS)
    if unknown:
        raise ValueError(f"sections: expected some of {SECTIONS + EXTRA_SECTIONS}, got {sorted(unknown)}")
    result = {"meta": _meta(quick, threads)}
    own_dir = workdir is None
    workdir = tempfile.mkdtemp(prefix="pito-bench-") if own_dir else workdir
    try:
        if "calibration" in sections:
            ks = sizes if sizes is not None else (QUICK_SIZES if quick else FULL_SIZES)
            result["calibration"] = run_calibration(ks, workdir, quick=quick, threads=threads,
                                                    n_test=5_000 if quick else 20_000, progress=progress)
            result["calibration"]["random_cubes"] = random_cube_ratios(quick=quick, threads=threads, progress=progress)
            result["calibration"]["model_choice"] = model_choice_ratios(quick=quick, threads=threads, progress=progress)
            result["calibration"]["coverage_cubes"] = coverage_cubes(quick=quick, threads=threads, progress=progress)
        if "contact" in sections:
            result["contact"] = run_contact(quick=quick, threads=threads, progress=progress, **(contact_sizes or {}))
        if "pipeline" in sections:
            result["pipeline"] = run_pipeline(quick=quick, threads=threads, progress=progress)
        if "analysis" in sections:
            result["analysis"] = run_analysis(quick=quick, threads=threads, progress=progress)
        if "live" in sections:
            result["live"] = _run_live(quick, threads, progress)
        if "soak" in sections:
            minutes = 1.0 if quick else 10.0
            app = live_available() and shutil.which("Xvfb") is not None
            progress(f"soak: recording {minutes:g} min from the simulated devices "
                     + ("(pito-app --demo --record, window on Xvfb)" if app else
                        "(headless pito record --pito sim --ati sim: the app extras or Xvfb are missing)"))
            result["soak"] = run_soak(minutes, app=app, workdir=workdir, progress=progress)
    finally:
        if own_dir:
            shutil.rmtree(workdir, ignore_errors=True)
    result["targets"] = targets(result)
    return json_safe(result)

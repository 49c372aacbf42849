"""Re-run both papers' experiments on the simulator: figures, their data and a summary.

``run_reproduction(out_dir, quick=False)`` simulates the calibration, squeeze, free-grasp
and touch protocols (``pito_core.sim``), fits and evaluates every method with the
calibration core, and writes PNG figures (units on every axis, marked SIMULATED), one CSV
per figure and ``summary.md`` with the papers' qualitative findings checked.
"""

from __future__ import annotations

import os
import time

from ._experiments import GRASP_METHODS, METHOD_MOUNTS, METHOD_ORDER, ReproductionConfig, Results, run_experiments
from ._figures import FIGURES, write_figures
from ._summary import Finding, findings, write_summary

__all__ = [
    "FIGURES",
    "Finding",
    "GRASP_METHODS",
    "METHOD_MOUNTS",
    "METHOD_ORDER",
    "ReproductionConfig",
    "Results",
    "findings",
    "run_experiments",
    "run_reproduction",
    "write_figures",
    "write_summary",
]


def run_reproduction(out_dir, quick: bool = False, *, seed: int = 0, cube_seed: int = 0, progress=print):
    """Run the experiments and write figures, CSV files and ``summary.md`` into ``out_dir``.

    Parameters
    ----------
    out_dir : path-like
        Output folder (created if missing).
    quick : bool
        Small sample counts (CI smoke test).
    seed, cube_seed : int
        Seeds of the runs and of the simulated cube.
    progress : callable, optional
        Called with one line per step; None for silence.

    Returns
    -------
    (Results, list of Finding, str)
        The results, the checked findings and the summary's path.
    """
    t0 = time.perf_counter()
    out_dir = os.fspath(out_dir)
    if os.path.exists(out_dir) and not os.path.isdir(out_dir):
        raise ValueError(f"out: expected a folder, got the file {out_dir!r}")
    os.makedirs(out_dir, exist_ok=True)
    cfg = ReproductionConfig.quick(seed, cube_seed) if quick else ReproductionConfig(seed=seed, cube_seed=cube_seed)
    res = run_experiments(cfg, progress=progress)
    files = write_figures(res, out_dir)
    if progress is not None:
        progress(f"[{time.perf_counter() - t0:6.1f} s] wrote {len(files)} figure and data files")
    path = write_summary(res, out_dir, files, time.perf_counter() - t0, quick)
    if progress is not None:
        progress(f"[{time.perf_counter() - t0:6.1f} s] wrote {path}")
    return res, findings(res), path

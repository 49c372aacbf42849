"""Benchmarks of what pito exists for: calibration fits, contact solves, the live pipeline.

``pito bench`` runs them (``run_bench``). Every figure is measured in the same run as
its baseline and reported as a ratio, since machines are noisy; each measurement runs in
a fresh subprocess limited to one BLAS thread (one core), which also isolates its peak
memory. Calibration data are simulated (``pito_core.sim``).
"""

from ._pipeline import default_pipeline, run_live, tick_cost
from ._run import SECTIONS, run_bench

__all__ = ["SECTIONS", "default_pipeline", "run_bench", "run_live", "tick_cost"]

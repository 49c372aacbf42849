"""Benchmarks of what pito exists for: calibration fits, contact solves, the live pipeline.

``pito bench`` runs them (``run_bench``). Every figure is measured in the same run as
its baseline and reported as a ratio, since machines are noisy; each measurement runs in
a fresh subprocess limited to one BLAS thread (one core), which also isolates its peak
memory. Calibration data are simulated (``pito_core.sim``).
"""

from importlib import import_module
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from ._pipeline import default_pipeline, run_live, tick_cost
    from ._run import SECTIONS, run_bench

__all__ = ["SECTIONS", "default_pipeline", "run_bench", "run_live", "tick_cost"]

#: name → module, loaded on first use (PEP 562, as pito_core/_lazy.py): a process that imports one module
#: of the bench (the app's process of the start-up bench: _live_window, _stamp) loads no other (_run: scipy.signal)
_WHERE = {"default_pipeline": "._pipeline", "run_live": "._pipeline", "tick_cost": "._pipeline",
          "SECTIONS": "._run", "run_bench": "._run"}


def __getattr__(name: str):
    try:
        module = _WHERE[name]
    except KeyError:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}") from None
    value = globals()[name] = getattr(import_module(module, __name__), name)
    return value


def __dir__():
    return sorted(set(globals()) | set(_WHERE))

"""Entry point of the measuring subprocesses: ``python -m pito_bench._worker TASK JSON``.

Prints one JSON object (the task's result plus ``peak_rss_mb``) on its last line.
"""

from __future__ import annotations

import importlib
import json
import sys

from ._timing import peak_rss_mb


#: task name -> (module, function)
TASKS = {
    "cal_generate": ("_calibration", "task_generate"),
    "cal_memory": ("_calibration", "task_memory"),
    "cal_random": ("_calibration", "task_random_cubes"),
    "cal_model_choice": ("_model_choice", "task_model_choice"),
    "cal_independent": ("_model_choice", "task_independent_cubes"),
    "cal_coverage_cubes": ("_calibration", "task_coverage_cubes"),
    "cal_stream": ("_calibration", "task_stream"),
    "contact": ("_contact", "task_contact"),
    "contact_single": ("_single_contact", "task_single_contact"),
    "pipeline": ("_pipeline", "task_pipeline"),
    "analysis": ("_analysis", "task_analysis"),
    "analysis_study": ("_analysis", "task_analysis_study"),
}


def _task(name):
    module, func = TASKS[name]
    return getattr(importlib.import_module(f"{__package__}.{module}"), func)


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    task, params = argv[0], json.loads(argv[1]) if len(argv) > 1 else {}
    out = _task(task)(**params)
    out["peak_rss_mb"] = peak_rss_mb()
    print(json.dumps(out, allow_nan=True))
    return 0


if __name__ == "__main__":
    sys.exit(main())

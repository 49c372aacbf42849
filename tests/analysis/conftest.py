"""Fixtures: SIMULATED lift-hold-replace recordings (pito_core.sim.LiftTask) with an ideal calibration embedded."""

import numpy as np
import pytest

from pito_core.calibration import Calibration
from pito_core.interop import assembly_record, calibration_record
from pito_core.sim import LiftTask, VirtualCube, write_lift_recording


def ideal_calibration() -> Calibration:
    cube = VirtualCube()
    return Calibration("ideal", cube.ideal_calibration(), range(1, 7), "face", cube.offset, cube.core, np.eye(4),
                       meta={"simulated": True, "date": "2026-11-24T00:00:00+00:00"})


def make_recordings(directory, n, n_trials=2):
    """``n`` recordings ``rec000.pitorec …`` of ``n_trials`` trials each; returns ``[(path, task, truth)]``."""
    cal = ideal_calibration()
    meta = {"calibration": calibration_record(cal, "ideal"), "assembly": assembly_record("cube")}
    out = []
    for k in range(n):
        task = LiftTask(n_trials, seed=k)
        path = directory / f"rec{k:03d}.pitorec"
        out.append((path, task, write_lift_recording(path, task, seed=k, meta=meta)))
    return out


@pytest.fixture(scope="session")
def lift_recording(tmp_path_factory):
    """``(path, task, truth)`` of a 3-trial lift recording."""
    d = tmp_path_factory.mktemp("lift")
    cal = ideal_calibration()
    meta = {"calibration": calibration_record(cal, "ideal"), "assembly": assembly_record("cube")}
    task = LiftTask(3, seed=11)
    path = d / "lift.pitorec"
    return path, task, write_lift_recording(path, task, seed=3, meta=meta)

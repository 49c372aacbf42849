"""Fixtures: an ideal calibration of the simulated cube and short SIMULATED recordings (pito record --pito sim)."""

import subprocess
import sys

import numpy as np
import pytest

from pito_core.calibration import Calibration
from pito_core.sim import VirtualCube

ASSEMBLY = "pito_mixed"


def ideal_calibration(scale: float = 1.0) -> Calibration:
    cube = VirtualCube()
    return Calibration("ideal", scale * cube.ideal_calibration(), range(1, 7), "face", cube.offset, cube.core, np.eye(4),
                       meta={"simulated": True, "date": "2026-11-23T00:00:00+00:00", "scale": scale})


def pito(*args, timeout=180):
    r = subprocess.run([sys.executable, "-c", "import sys; from pito_core.cli import main; sys.exit(main())", *map(str, args)], capture_output=True, text=True,
                       timeout=timeout)
    assert r.returncode == 0, r.stderr
    return r


@pytest.fixture(scope="session")
def interop_files(tmp_path_factory):
    """``(dir, calibration file, recording with embedded calibration + assembly, recording without)``."""
    d = tmp_path_factory.mktemp("interop")
    cal = d / "ideal.h5"
    ideal_calibration().save(cal)
    rec = d / "grasp.pitorec"
    pito("record", "--pito", "sim", "--ati", "sim", "--sim-speed", 4, "--duration", 1.2, "--seed", 5, "--progress", 0,
         "--tare", 0.4, "--calibration", cal, "--object", ASSEMBLY, "-o", rec)
    raw = d / "raw.pitorec"
    pito("record", "--pito", "sim", "--ati", "sim", "--sim-speed", 4, "--duration", 0.6, "--seed", 6, "--progress", 0,
         "-o", raw)
    return d, cal, rec, raw

"""The lab's day, shared: one calibration by `pito calibrate` and one recording by `pito record` for every stage."""

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from pito_core.io import read_recording

ROOT = Path(__file__).parents[2]
SIM_SPEED, WALL_S = 4, 15  # one minute of device time


def pito(*args, cwd=None, timeout=240, check=True):
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    r = subprocess.run([sys.executable, "-c", "import sys; from pito_core.cli import main; sys.exit(main())",
                        *map(str, args)], capture_output=True, text=True, timeout=timeout, cwd=cwd, env=env)
    if check:
        assert r.returncode == 0, f"pito {' '.join(map(str, args[:2]))}: rc={r.returncode}\n{r.stdout[-2000:]}\n{r.stderr[-3000:]}"
    return r


@pytest.fixture(scope="session")
def day(tmp_path_factory):
    """The calibration, the one-minute recording and its counts, shared by every stage."""
    d = tmp_path_factory.mktemp("labday")
    pito("simulate", "--protocol", "calibration", "--flange", "face", "--connected-face", 6, "-k", 1500,
         "-o", d / "ses.h5")
    pito("calibrate", d / "ses.h5", "--method", "unloaded_frame", "-o", d / "cube.pitocal")
    r = pito("record", "--pito", "sim", "--ati", "sim", "--sim-speed", SIM_SPEED, "--duration", WALL_S, "--seed", 1,
             "--tare", 2, "--progress", 0, "--calibration", d / "cube.pitocal", "-o", d / "rec.pitorec")
    rec = read_recording(d / "rec.pitorec")
    said = re.search(r"(\d+) cube samples, (\d+) reference samples", r.stdout)
    # hand-off 1: devices → file (the recorder exits 1 if a frame the drivers received is not in the file)
    assert said and (int(said[1]), int(said[2])) == (rec.pito.size, rec.netft.size)
    return {"dir": d, "cal": d / "cube.pitocal", "rec": d / "rec.pitorec", "n": rec.pito.size, "m": rec.netft.size}

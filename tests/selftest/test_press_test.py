"""The press test names a flipped or swapped axis of a calibration (pure numpy)."""

import numpy as np
import pytest

from pito_core.calibration import Calibration
from pito_core.frames import CubeCore
from pito_core.selftest import PRESS_PROTOCOL, check_press_test
from pito_core.sim import random_sensor


def _setup(seed=3):
    sensor = random_sensor(seed, condition=(1.0, 3.0), noise=(0.5, 1.0), offset=1e5)
    K = sensor.sensitivity
    cal = Calibration("total", np.linalg.inv(K), range(1, 7), "face", sensor.offset, CubeCore(), np.eye(4))
    rng = np.random.default_rng(seed)

    def counts(face_wrench_rows):
        F = np.asarray(face_wrench_rows, dtype=float).reshape(-1, 36)
        return sensor.offset + F @ K.T + rng.normal(size=F.shape) * 2.0

    rest = counts(np.zeros((50, 6, 6)))
    steps = []
    for st in PRESS_PROTOCOL:
        W = np.zeros((80, 6, 6))
        amp = 5.0 if st.action == "press" else 0.08  # N, N·m
        W[:, st.face - 1, :] = np.asarray(st.direction, float) * amp * np.linspace(0.2, 1, 80)[:, None]
        W[:, st.face - 1, :] += rng.normal(size=(80, 6)) * [0.2, 0.2, 0.2, 0.003, 0.003, 0.003]  # sloppy operator
        steps.append(counts(W))
    return cal, rest, steps


def test_a_correct_calibration_passes():
    cal, rest, steps = _setup()
    r = check_press_test(cal, rest, steps)
    assert r.passed, r.summary()
    assert len(r.checks) == 12 and "passed" in r.summary()


@pytest.mark.parametrize("face,axis", [(2, 2), (5, 5), (6, 2)])
def test_a_flipped_axis_is_named(face, axis):
    cal, rest, steps = _setup()
    row = 6 * (face - 1) + axis
    M = cal.matrix.copy()
    M[row] *= -1
    bad = Calibration("total", M, range(1, 7), "face", cal.offset, CubeCore(), np.eye(4))
    r = check_press_test(bad, rest, steps)
    name = ("fx", "fy", "fz", "tx", "ty", "tz")[axis]
    assert not r.passed
    assert r.findings == [f for f in r.findings if f.startswith(f"face {face}: {name} is flipped")]
    assert len(r.findings) == 1


def test_swapped_axes_are_named():
    cal, rest, steps = _setup()
    M = cal.matrix.copy()
    M[[12 + 0, 12 + 2]] = M[[12 + 2, 12 + 0]]  # face 3: fx and fz rows swapped
    bad = Calibration("total", M, range(1, 7), "face", cal.offset, CubeCore(), np.eye(4))
    r = check_press_test(bad, rest, steps)
    assert len(r.findings) == 1 and "face 3 (press): axes swapped" in r.findings[0] and "fx" in r.findings[0]


def test_no_press_is_too_weak_not_a_pass():
    cal, rest, steps = _setup()
    steps[0] = rest.copy()
    r = check_press_test(cal, rest, steps)
    assert not r.passed and "too weak" in r.findings[0]
    with pytest.raises(ValueError, match="step_counts"):
        check_press_test(cal, rest, steps[:3])

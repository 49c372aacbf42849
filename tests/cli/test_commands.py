"""Every subcommand of ``pito``: ``--help``, a bad argument (exit 2, one error line), a happy path.

Happy paths run on small simulated data (``pito simulate`` writes files marked simulated).
"""

from __future__ import annotations

import numpy as np
import pytest

from pito_core.cli import build_parser, main
from pito_core.defaults import LOADED_FORCE_N
from pito_core.io import RecordingWriter, read_recording_csv


def _small_recording(path, n, seed):
    """A recording of n random (simulated) cube and reference samples, 1 kHz."""
    rng = np.random.default_rng(seed)
    with RecordingWriter(path, {"simulated": True}, flush_interval=1.0, fsync=False) as w:
        w.append_pito(np.arange(n), np.arange(n) * 1000, np.arange(n) * 1e-3, rng.integers(-9, 9, (n, 36)))
        w.append_netft(np.arange(n), np.arange(n), np.zeros(n), np.arange(n) * 1e-3, rng.normal(size=(n, 6)))
    return path


def _subcommands():
    parser = build_parser()
    for action in parser._subparsers._group_actions:  # argparse keeps subparsers here
        return sorted(action.choices)
    return []


SUBCOMMANDS = _subcommands()


def test_every_known_command_is_registered():
    # bench comes from the pito_bench entry point; the rest from pito_core.cli
    for name in ("calibrate", "evaluate", "simulate", "reproduce", "devices", "record", "replay", "bench"):
        assert name in SUBCOMMANDS


@pytest.mark.parametrize("cmd", SUBCOMMANDS)
def test_help(cmd, capsys):
    with pytest.raises(SystemExit) as exc:
        main([cmd, "--help"])
    assert exc.value.code == 0
    out = capsys.readouterr().out
    assert out.startswith(f"usage: pito {cmd}")


@pytest.mark.parametrize("cmd", SUBCOMMANDS)
def test_bad_argument_exits_2_with_one_error_line(cmd, capsys):
    with pytest.raises(SystemExit) as exc:
        main([cmd, "--no-such-option"])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    errors = [line for line in err.splitlines() if "error:" in line]
    # argparse names the first problem: the unknown option, or a required argument missing
    assert len(errors) == 1 and ("--no-such-option" in errors[0] or "required" in errors[0])
    assert "Traceback" not in err


def test_evaluate_help_shows_the_defaults_module_value(capsys):
    with pytest.raises(SystemExit):
        main(["evaluate", "--help"])
    assert f"(default {LOADED_FORCE_N})" in capsys.readouterr().out


@pytest.fixture(scope="module")
def simulated(tmp_path_factory):
    d = tmp_path_factory.mktemp("cli")
    s = d / "s.pitosession"
    assert main(["simulate", "--protocol", "calibration", "--flange", "frame_hole", "--connected-face", "3",
                 "-k", "60", "--seed", "1", "-o", str(s)]) == 0
    return d, s


def test_simulate_calibrate_evaluate_happy_path(simulated, capsys):
    d, s = simulated
    cal = d / "c.pitocal"
    assert main(["calibrate", "--method", "face_to_face", "-o", str(cal), str(s)]) == 0
    assert cal.exists()
    capsys.readouterr()
    assert main(["evaluate", str(cal), str(s)]) == 0
    out = capsys.readouterr().out
    assert "N" in out


def test_user_error_is_one_line_exit_1(simulated, capsys, tmp_path):
    _, s = simulated
    assert main(["evaluate", str(tmp_path / "missing.pitocal"), str(s)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("pito: error:")


def test_devices_happy_path(capsys):
    assert main(["devices"]) == 0


def test_replay_info_happy_path(tmp_path, capsys):
    path = _small_recording(tmp_path / "r.pitorec", 50, seed=0)
    assert main(["replay", "--info", str(path)]) == 0
    assert capsys.readouterr().out.strip()


def test_replay_and_export_write_the_same_csv_and_mat(tmp_path, capsys):
    path = _small_recording(tmp_path / "r.pitorec", 30, seed=1)
    assert main(["replay", "--csv", str(tmp_path / "a"), "--mat", str(tmp_path / "a.mat"), str(path)]) == 0
    assert main(["export", "--csv", str(tmp_path / "b"), "--mat", str(tmp_path / "b.mat"), str(path)]) == 0
    a, b = read_recording_csv(tmp_path / "a_pito.csv"), read_recording_csv(tmp_path / "b_pito.csv")
    assert a.keys() == b.keys() and all(np.array_equal(a[k], b[k]) for k in a)
    assert (tmp_path / "a.mat").exists() and (tmp_path / "b.mat").exists()


def test_calibrate_and_evaluate_name_a_reference_noisier_than_the_tare_allows(tmp_path, capsys):
    """A session whose reference is noisier at rest than the tare's stillness limits (2 % of full scale on
    a random sensor, not the cube's simulator): ``pito calibrate`` fits it and warns in one line, as it
    reports errors; ``pito evaluate`` says the ± may be short."""
    from pito_core.sim import random_sensor, random_sensor_session

    sensor = random_sensor(2, condition=(1.0, 30.0))
    train, _ = random_sensor_session(sensor, "face", 6, 400, n_tare=500, seed=3, reference_noise=0.02)
    test, _ = random_sensor_session(sensor, "face", 6, 100, n_tare=200, seed=4)
    train.save(tmp_path / "train.pitosession")
    test.save(tmp_path / "test.pitosession")
    cal = tmp_path / "c.pitocal"
    assert main(["calibrate", "--method", "total", "--model", "linear", "-o", str(cal),
                 str(tmp_path / "train.pitosession")]) == 0
    warned = [line for line in capsys.readouterr().err.splitlines() if "warning" in line]
    assert len(warned) == 1 and warned[0].startswith("pito: warning: sessions[0].reference: its noise at rest is "), warned
    assert main(["evaluate", str(cal), str(tmp_path / "test.pitosession")]) == 0
    warned = [line for line in capsys.readouterr().out.splitlines() if line.startswith("WARNING:")]
    assert len(warned) == 1 and "is above the limits the intervals were checked within" in warned[0], warned

"""`pito devices`, `pito record`, `pito replay` on the simulated devices; a recorder killed with SIGKILL."""

import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from pito_core.cli import build_parser, main
from pito_core.io import FileFormatError, Recording

RUN_CLI = "import sys; from pito_core.cli import main; sys.exit(main())"


def test_devices_lists_ports_and_sim(capsys):
    assert main(["devices"]) == 0
    assert "sim" in capsys.readouterr().out
    assert main(["devices", "--json"]) == 0
    assert '"device": "sim"' in capsys.readouterr().out


def test_help_explains_units_and_defaults():
    parser = build_parser()
    sub = next(a for a in parser._actions if a.__class__.__name__ == "_SubParsersAction")
    record, replay = sub.choices["record"].format_help(), sub.choices["replay"].format_help()
    assert "N·m" in record and "default" in record and "sim" in record and "--flush-interval" in record
    assert "N·m" in replay and "--recover" in replay and "real speed" in replay
    assert "sim" in sub.choices["devices"].format_help()


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    path = tmp_path_factory.mktemp("rec") / "demo.rec"
    code = main(["record", "--pito", "sim", "--ati", "sim", "-o", str(path), "--duration", "1.5", "--tare", "0.8",
                 "--progress", "0.5"])
    assert code == 0
    return path


def test_record_on_simulated_devices(recorded):
    r = Recording(recorded)
    assert r.complete and r.simulated and r.meta["source"]
    assert r.pito.size > 500 and r.netft.size > 500
    assert np.all(np.diff(r.pito["seq"].astype(np.int64)) == 1)
    assert np.all(np.diff(r.netft["rdt_seq"].astype(np.int64)) == 1)
    assert [e["type"] for e in r.events] == ["tare"]
    assert r.meta["ati_scaling"]["force_unit"] == "N"


def test_replay_and_export(recorded, tmp_path, capsys):
    assert main(["replay", str(recorded), "--speed", "inf"]) == 0
    out = capsys.readouterr()
    assert "replay done" in out.out and "simulated" in out.out and "cube" in out.err
    assert main(["replay", str(recorded), "--info"]) == 0
    prefix = tmp_path / "exp"
    assert main(["replay", str(recorded), "--csv", str(prefix), "--mat", str(tmp_path / "x.mat")]) == 0
    assert (tmp_path / "exp_pito.csv").exists() and (tmp_path / "exp_ati.csv").exists()
    assert (tmp_path / "x.mat").exists()
    assert main(["replay", str(recorded), "--speed", "0"]) == 1


def test_record_cube_only_and_errors(tmp_path, capsys):
    path = tmp_path / "cube.rec"
    assert main(["record", "--pito", "sim", "-o", str(path), "--duration", "0.5", "--progress", "0"]) == 0
    r = Recording(path)
    assert r.pito.size > 0 and r.netft.size == 0
    assert main(["record", "--pito", "/nonexistent/tty", "-o", str(tmp_path / "n.rec"), "--duration", "1"]) != 0
    assert main(["record", "--pito", "sim", "-o", str(tmp_path / "d.rec"), "--duration", "-1"]) == 1
    assert "--duration" in capsys.readouterr().err


def _spawn_recorder(path):
    return subprocess.Popen([sys.executable, "-c", RUN_CLI, "record", "--pito", "sim", "--ati", "sim", "-o",
                             str(path), "--flush-interval", "0.2", "--progress", "0"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)


def _wait_rows(path, n, proc, timeout=120.0):
    deadline = time.monotonic() + timeout
    seen = 0
    while time.monotonic() < deadline and proc.poll() is None:
        try:
            seen = Recording(path, recover=True).pito.size
        except (FileNotFoundError, FileFormatError):
            seen = 0
        if seen >= n:
            return seen
        time.sleep(0.1)
    raise AssertionError(f"recorder wrote {seen} rows (exit {proc.poll()}): {proc.stderr.read().decode()[-500:]}")


def test_recorder_killed_with_sigkill_leaves_a_readable_file(tmp_path):
    path = tmp_path / "killed.rec"
    proc = _spawn_recorder(path)
    try:
        seen = _wait_rows(path, 1500, proc)
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == -signal.SIGKILL
    with pytest.raises(FileFormatError, match="incomplete"):
        Recording(path)
    r = Recording(path, recover=True)
    assert not r.complete and r.pito.size >= seen
    assert np.all(np.diff(r.pito["seq"].astype(np.int64)) == 1)
    assert r.netft.size > 0 and r.simulated
    assert main(["replay", str(path), "--speed", "inf", "--recover"]) == 0


def test_recorder_sigterm_closes_the_file(tmp_path):
    path = tmp_path / "term.rec"
    proc = _spawn_recorder(path)
    try:
        _wait_rows(path, 500, proc)
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(timeout=30) == 0
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert Recording(path).complete

"""``pito analyze`` and ``pito export REC... --out DIR``; the core without pandas and Dask."""

import subprocess
import sys

import pandas as pd
import pytest

from pito_core.analysis import PATCH_COLUMNS, PHASE_COLUMNS
from pito_core.cli import main

from .conftest import make_recordings


def test_help_explains_every_column(capsys):
    with pytest.raises(SystemExit):
        main(["analyze", "--help"])
    text = capsys.readouterr().out
    for col in list(PHASE_COLUMNS) + list(PATCH_COLUMNS):
        assert f"  {col} " in text
    assert "--scheduler" in text and "127.0.0.1" in text


def test_analyze_one_recording_in_process_with_nwb(tmp_path, capsys):
    pytest.importorskip("pynwb")
    (rec, task, _), = make_recordings(tmp_path, 1, n_trials=2)
    assert main(["analyze", str(rec), "--out", str(tmp_path / "out"), "--nwb", "--figures", "trials"]) == 0
    out = capsys.readouterr().out
    assert "done" in out and "in process" in out and "(simulated)" in out
    d = tmp_path / "out" / rec.stem
    phases = pd.read_csv(d / "phases.csv")
    assert list(phases.columns[:3]) == ["trial", "phase", "start_s"] and phases["simulated"].all()
    assert sorted(p.name for p in d.glob("*.png")) == ["overview.png", "trial_01.png", "trial_02.png"]
    from pynwb import NWBHDF5IO

    with NWBHDF5IO(str(d / f"{rec.stem}.nwb"), "r") as io:
        nwb = io.read()
        table = nwb.intervals["grasp_phases"].to_dataframe()
        assert "pito_raw_counts" in nwb.acquisition
    assert len(table) == len(phases) == 10
    assert list(table["phase"]) == list(phases["phase"])
    pd.testing.assert_series_equal(table["grip_force_N"].reset_index(drop=True), phases["grip_force_N"],
                                   check_names=False)
    assert main(["analyze", str(rec), "--out", str(tmp_path / "out")]) == 0  # a rerun skips it
    assert "skipped" in capsys.readouterr().out


def test_export_many_in_process_and_a_bad_one_by_name(tmp_path, capsys):
    pytest.importorskip("pynwb")
    recs = [p for p, _, _ in make_recordings(tmp_path, 2, n_trials=1)]
    bad = tmp_path / "bad.pitorec"
    bad.write_bytes(b"junk")
    code = main(["export", *map(str, recs + [bad]), "--out", str(tmp_path / "x"), "--formats", "nwb,mcap",
                 "--workers", "0", "--no-contacts"])
    assert code == 1
    cap = capsys.readouterr()
    assert f"FAILED {bad}" in cap.err
    assert sorted(p.name for p in (tmp_path / "x").iterdir()) == ["rec000.mcap", "rec000.nwb", "rec001.mcap", "rec001.nwb"]
    assert main(["export", *map(str, recs), "--nwb", str(tmp_path / "a.nwb")]) == 1
    assert "need --out DIR" in capsys.readouterr().err


BLOCK = r"""
import sys
class Block:
    def find_spec(self, name, path=None, target=None):
        if name.split('.')[0] in ('pandas', 'dask', 'distributed'):
            raise ImportError('blocked: ' + name)
sys.meta_path.insert(0, Block())
import numpy as np
import pito_core.analysis as A
from pito_core.cli import build_parser
build_parser()
A.grasp_decomposition(np.zeros((1, 6, 3)), np.zeros((1, 6, 3)), np.ones((1, 6), bool))
for call in (lambda: A.require_pandas(), lambda: A.run_study(A.analyze_to_dir, ['a.pitorec'])):
    try:
        call()
    except ImportError as e:
        print(e)
"""


def test_core_imports_without_pandas_and_dask():
    r = subprocess.run([sys.executable, "-c", BLOCK], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    lines = r.stdout.splitlines()
    assert "pip install 'pito[analysis]'" in lines[0] and "dask[distributed]" in lines[1]


def test_analyze_many_on_a_local_cluster_with_its_dashboard_on_loopback(tmp_path, capsys):
    pytest.importorskip("distributed")
    pytest.importorskip("bokeh")
    recs = [p for p, _, _ in make_recordings(tmp_path, 2, n_trials=1)]
    assert main(["analyze", *map(str, recs), "--out", str(tmp_path / "out"), "--workers", "1", "--dashboard",
                 "--no-figures"]) == 0
    out = capsys.readouterr().out
    assert "Dask dashboard: http://127.0.0.1:" in out and "on Dask (1 worker)" in out
    assert out.count("] done ") == 2 and not list((tmp_path / "out" / "rec000").glob("*.png"))

"""A missing optional dependency: one line naming the extra to install, exit status 2, no traceback.

Each case runs `pito` in a subprocess where the import of the dependency fails
(``sys.modules[name] = None``, as if it were not installed), on the lab's real files.
"""

import os
import subprocess
import sys

import pytest

from .conftest import ROOT


def pito_without(modules, *args, cwd=None):
    prelude = "import sys; " + "".join(f"sys.modules[{m!r}] = None; " for m in modules)
    return subprocess.run([sys.executable, "-c", prelude + "from pito_core.cli import main; sys.exit(main())",
                           *map(str, args)], capture_output=True, text=True, timeout=180, cwd=cwd,
                          env=dict(os.environ, PYTHONPATH=str(ROOT)))


def one_line(r, extra: str) -> None:
    assert r.returncode == 2, r.stdout + r.stderr
    lines = r.stderr.strip().splitlines()
    assert "Traceback" not in r.stderr and len([ln for ln in lines if ln.startswith("pito: error:")]) == 1, r.stderr
    assert f"pip install 'pito[{extra}]'" in lines[-1]


def test_analyze_of_two_recordings_without_dask(day, tmp_path):
    one_line(pito_without(["dask", "distributed"], "analyze", day["rec"], day["rec"].with_name("other.pitorec"),
                          "--out", tmp_path / "o"), "analysis")


@pytest.mark.slow
def test_analyze_without_pandas(day, tmp_path):
    one_line(pito_without(["pandas"], "analyze", day["rec"], "--out", tmp_path / "o", "--no-figures"), "analysis")


@pytest.mark.parametrize("modules, option", [(["pynwb", "hdmf"], "--nwb"), (["mcap", "mcap_ros2"], "--mcap")])
def test_export_without_the_interop_extra(day, tmp_path, modules, option):
    one_line(pito_without(modules, "export", day["rec"], option, tmp_path / "out", "--no-contacts"), "interop")


@pytest.mark.slow
def test_stream_without_pylsl(day):
    one_line(pito_without(["pylsl"], "stream", "--pito", "sim", "--calibration", day["cal"], "--duration", 1),
             "interop")

"""``pito simulate`` and a ``pito reproduce --quick`` run."""

import re

import numpy as np
import pytest

from pito_core.calibration import CalibrationSession
from pito_core.cli import build_parser, main


def test_help_lists_commands(capsys):
    with pytest.raises(SystemExit):
        main(["--help"])
    out = capsys.readouterr().out
    assert "simulate" in out and "reproduce" in out


@pytest.mark.parametrize("cmd", ["simulate", "reproduce"])
def test_subcommand_help_explains_units(cmd, capsys):
    with pytest.raises(SystemExit):
        main([cmd, "--help"])
    out = capsys.readouterr().out
    assert "N·m" in out and "default" in out


@pytest.mark.parametrize(
    "argv, flange, n_faces",
    [
        (["--protocol", "calibration", "--flange", "frame", "--connected-face", "3", "-k", "100"], "frame", 5),
        (["--protocol", "squeeze", "-k", "100"], "face", 5),
        (["--protocol", "touches", "--face", "2", "-k", "100"], "face", 1),
        (["--protocol", "grasp", "-k", "3000"], "face", None),
    ],
)
def test_simulate_writes_a_session(tmp_path, capsys, argv, flange, n_faces):
    path = tmp_path / "out.h5"
    assert main(["simulate", *argv, "--seed", "1", "-o", str(path)]) == 0
    assert "SIMULATED" in capsys.readouterr().out
    s = CalibrationSession.load(path)
    assert s.flange == flange and s.meta["simulated"] is True
    assert np.asarray(s.counts).shape[1] == 36 and len(s) > 0
    if n_faces is not None:
        assert int(np.asarray(s.loaded).any(axis=0).sum()) == n_faces


def test_simulate_bad_input_is_one_line(tmp_path, capsys):
    code = main(["simulate", "--faces", "1,x", "-o", str(tmp_path / "x.h5")])
    assert code == 1
    assert "--faces" in capsys.readouterr().err


def test_parser_builds():
    assert build_parser().prog == "pito"


# ------------------------------------------------------------------ reproduce --quick
EXPECTED = [
    "summary.md",
    "identification.png",
    "identification_single.csv",
    "identification_squeeze.csv",
    "identification_loaded_frame.png",
    "identification_loaded_frame_single.csv",
    "identification_loaded_frame_squeeze.csv",
    "squeeze_connected_face.png",
    "squeeze_connected_face.csv",
    "comparison_forces.png",
    "comparison_torques.png",
    "comparison.csv",
    "rmse_methods.png",
    "rmse_methods.csv",
    "rmse_connected_face.png",
    "rmse_connected_face.csv",
    "table1_icn.png",
    "table1_inverse_condition_numbers.csv",
    "equilibrium.png",
    "equilibrium.csv",
    "model_choice.png",
    "model_choice.csv",
]


@pytest.fixture(scope="module")
def quick_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("reproduce")
    code = main(["reproduce", "--out", str(out), "--quick"])
    return out, code


@pytest.mark.slow
def test_quick_reproduction_writes_everything(quick_run):
    out, code = quick_run
    assert code == 0  # 3: a finding does not hold (test_quick_reproduction_summary_findings says which)
    for name in EXPECTED:
        assert (out / name).exists(), name
        assert (out / name).stat().st_size > 100, name
    assert (out / "contact_points.png").exists() and (out / "contact_points.csv").exists()
    rows = (out / "contact_points.csv").read_text().splitlines()
    # 8 points + centre, for the cube and for the reference sensor
    assert rows[0].startswith("sensor,point,target_x_m,target_y_m") and len(rows) == 1 + 2 * 9
    assert {r.split(",")[0] for r in rows[1:]} == {"cube", "reference"}
    sq = (out / "squeeze_connected_face.csv").read_text().splitlines()
    assert len(sq) == 1 + 6 * 3  # 6 connected faces × (loaded, unloaded, unloaded + frame_hole)
    header = (out / "rmse_methods.csv").read_text().splitlines()[0]
    assert "rmse_force_N" in header and "rmse_torque_Nm" in header
    # Table I is of the papers' linear fits: the unloaded frame on its face flange alone has rank 30 (≈ 0),
    # even where the default chose the polynomial model (its affine part is not of rank 30)
    t1 = np.genfromtxt(out / "table1_inverse_condition_numbers.csv", delimiter=",", names=True)
    assert np.all(t1["unloaded_frame_icn"] < 1e-10), t1["unloaded_frame_icn"]
    assert np.all((t1["loaded_frame_icn"] > 1e-4) & (t1["unloaded_frame_with_frame_hole_icn"] > 1e-4))


def test_failing_finding_is_reported_not_dropped(quick_run):
    """A finding that does not hold is printed as NO with its numbers (exit status 3)."""
    out, code = quick_run
    text = (out / "summary.md").read_text()
    rows = [line for line in text.splitlines() if line.startswith("| ") and ("**yes**" in line or "**NO**" in line)]
    assert len(rows) >= 9
    assert (code == 0) == all("**yes**" in r for r in rows)


@pytest.mark.slow
def test_quick_reproduction_summary_findings(quick_run):
    out, _ = quick_run
    text = (out / "summary.md").read_text()
    assert "SIMULATED" in text
    for name in ("identification.png", "table1_icn.png", "equilibrium.png"):
        assert f"]({name})" in text

    def holds(phrase):
        row = next(line for line in text.splitlines() if line.startswith("| ") and phrase in line)
        return "**yes**" in row

    assert holds("beat face_to_face")
    assert holds("unloaded frame beats loaded frame on RMSE")
    assert holds("loaded faces are identified")
    assert holds("inverse condition numbers")
    assert holds("free grasp (Fig. 20): with the net load measured")
    assert holds("free grasp under a face-flange calibration without a net-load measurement")
    assert holds("squeeze loads for every connected face")
    assert holds("8-point test")
    # the 8-point test's numbers: the error to the targets is the placement's (~mm), not the cube's
    row = next(line for line in text.splitlines() if "8-point test" in line and line.startswith("| "))
    cube, ref = (float(x) for x in re.findall(r"RMS to targets: cube ([0-9.]+) mm, reference ([0-9.]+) mm", row)[0])
    assert 0.5 < cube < 5 and 0.5 < ref < 5
    # every calibration of the free grasp says how its net force was obtained
    assert "| unloaded_frame+frame_hole | measured |" in text
    assert "| unloaded_frame | not measured" in text
    # the numbers behind "unloaded < loaded" are in the row, in N
    row = next(line for line in text.splitlines() if "unloaded frame beats loaded frame on RMSE" in line)
    a, b = (float(x) for x in re.findall(r"forces ([0-9.]+) N vs ([0-9.]+) N", row)[0])
    assert a < b

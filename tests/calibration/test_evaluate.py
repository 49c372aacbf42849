import json
import re

import numpy as np
import pytest
from gen import make_session, true_sensitivity

from pito_core.calibration import (
    calibrate,
    equilibrium,
    identify_loaded_faces,
    inverse_condition_table,
)
from pito_core.cli import main
from pito_core.frames import CubeCore, invert_pose, transform_wrench


def test_equilibrium_of_a_static_pinch_with_weight():
    """Two fingers on faces 1 and 3 hold a 0.3 kg object against gravity (−z in the core frame)."""
    core = CubeCore(0.05)
    m, g = 0.3, 9.81
    cog = np.array([0.003, 0.0, -0.004])  # off centre, towards face 1
    weight = np.array([0, 0, -m * g])
    # each finger: a 5 N squeeze plus its share of the weight (lever rule about the cog)
    p1, p3 = np.array([0.025, 0.0, -0.004]), np.array([-0.025, 0.0, -0.004])
    a = m * g * (cog[0] - p3[0]) / (p1[0] - p3[0])
    f1 = np.array([-5.0, 0, a])
    f3 = np.array([5.0, 0, m * g - a])
    loads_core = []
    for p, f in ((p1, f1), (p3, f3)):
        loads_core.append(np.r_[f, np.cross(p, f)])
    W = np.zeros((1, 6, 6))
    W[0, 0] = transform_wrench(loads_core[0], core.face_pose(1))
    W[0, 2] = transform_wrench(loads_core[1], core.face_pose(3))
    eq = equilibrium(W, core, mass=m, cog=cog, g=g)
    np.testing.assert_allclose(eq.force_sum[0], -weight, atol=1e-12)
    np.testing.assert_allclose(eq.force_sum_norm, [m * g], rtol=1e-12)
    assert eq.weight == pytest.approx(m * g)
    # contact points at the height of the cog: no moment about it
    np.testing.assert_allclose(eq.torque_cog_norm, [0.0], atol=1e-12)
    # about the core centre there would be one: the cog matters
    eq0 = equilibrium(W, core, mass=m, cog=(0, 0, 0), g=g)
    assert eq0.torque_cog_norm[0] > 1e-3
    with pytest.raises(ValueError, match=r"mass: expected a positive mass in kg"):
        equilibrium(W, core, mass=0)
    with pytest.raises(ValueError, match=r"face_wrenches: expected shape \(N, 6, 6\)"):
        equilibrium(W[0], core, mass=1)


def test_identify_loaded_faces_modes():
    W = np.zeros((3, 6, 6))
    W[0, 1, 2] = 2.0  # force only on face 2
    W[1, 3, 5] = 0.05  # torque only on face 4
    W[2, 4] = np.nan  # no output for face 5
    got = identify_loaded_faces(W, 0.5, 0.01, by="force")
    assert got[0, 1] and not got[1].any() and not got[2].any()
    got = identify_loaded_faces(W, 0.5, 0.01, by="torque")
    assert got[1, 3] and not got[0].any()
    got = identify_loaded_faces(W, 0.5, 0.01)
    assert got.sum() == 2
    with pytest.raises(ValueError, match=r"by: expected 'force', 'torque' or 'either'"):
        identify_loaded_faces(W, by="norm")


def test_inverse_condition_table_rows():
    K = true_sensitivity(21)
    cals = [calibrate(make_session(K, flange="frame_hole", connected_face=c, k=200), "loaded_frame") for c in (5, 6)]
    rows = inverse_condition_table(cals)
    assert [r["connected_faces"] for r in rows] == [[5], [6]]
    assert all(0 < r["inverse_condition_number"] < 1 for r in rows)
    assert all(len(r["face_inverse_condition_numbers"]) == 6 for r in rows)


def test_cli_calibrate_and_evaluate(tmp_path, capsys):
    K = true_sensitivity(22)
    train = tmp_path / "train.h5"
    test = tmp_path / "test.h5"
    make_session(K, flange="face", connected_face=6, k=600, free_only=True).save(train)
    make_session(K, flange="face", connected_face=6, k=300, free_only=True, seed=4, squeeze_pairs=[(1, 3)]).save(test)
    cal = tmp_path / "cube.pitocal"
    assert main(["calibrate", str(train), "--method", "unloaded_frame", "-o", str(cal)]) == 0
    out = capsys.readouterr().out
    assert "fx [N]" in out and "tz [N·m]" in out and "face identification" in out and cal.exists()
    assert main(["evaluate", str(cal), str(test)]) == 0
    out = capsys.readouterr().out
    assert "RMSE, squeeze resultant" in out and "face 5" in out
    # the wizard's words: the figure by loaded face (issue 45; report.identification_text)
    assert "single-face loads by loaded face: 1: " in out and "5: " in out.split("by loaded face")[1]
    assert main(["evaluate", str(cal), str(test), "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["method"] == "unloaded_frame" and d["n_squeeze"] == 300 and len(d["rmse_single"]) == 6
    assert d["identification"]["single"]["either"] > 0.99
    # user errors: one line, exit status 1, no traceback
    assert main(["evaluate", str(tmp_path / "missing.pitocal"), str(test)]) == 1
    assert "pito: error:" in capsys.readouterr().err
    assert main(["calibrate", str(train), "--method", "quasi_total", "-o", str(tmp_path / "x")]) == 1
    assert "needs a flange in ('frame',)" in capsys.readouterr().err


def test_cli_csv_sessions(tmp_path, capsys):
    K = true_sensitivity(23)
    s = make_session(K, flange="frame_hole", connected_face=2, k=300)
    s.to_csv(tmp_path / "s.csv")
    assert main(["calibrate", str(tmp_path / "s.csv"), "--method", "face_to_face", "-o", str(tmp_path / "c")]) == 1
    assert "CSV sessions need --flange and --connected-face" in capsys.readouterr().err
    assert main(["calibrate", str(tmp_path / "s.csv"), "--method", "face_to_face", "--flange", "frame_hole",
                 "--connected-face", "2", "-o", str(tmp_path / "c")]) == 0


def test_cli_evaluate_headlines_the_papers_rule_and_shows_uncertainty(tmp_path, capsys):
    """Identification headline: single-face loads by force, squeeze by torque (in words);
    ± (95 %) per face and axis from the calibration's covariance; net load in words."""
    K = true_sensitivity(22)
    train, test, cal = tmp_path / "train.h5", tmp_path / "test.h5", tmp_path / "cube.pitocal"
    make_session(K, flange="face", connected_face=6, k=600, free_only=True).save(train)
    make_session(K, flange="face", connected_face=6, k=300, free_only=True, seed=4, squeeze_pairs=[(1, 3)]).save(test)
    assert main(["calibrate", str(train), "--method", "unloaded_frame", "--holdout", "0", "-o", str(cal)]) == 0
    out = capsys.readouterr().out
    assert "net force/torque of a free grasp: not measured" in out
    assert main(["evaluate", str(cal), str(test)]) == 0
    out = capsys.readouterr().out
    assert re.search(r"single-face loads: [0-9.]+ % of \d+ samples identified by force", out)
    assert re.search(r"squeeze loads: [0-9.]+ % of \d+ samples identified by torque", out)
    assert "± (95 %)" in out and "net force/torque of a free grasp: not measured" in out
    assert main(["evaluate", str(cal), str(test), "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    head = {h["kind"]: h for h in d["identification_headline"]}
    assert head["single"]["rule"] == "force" and head["squeeze"]["rule"] == "torque"
    assert head["single"]["accuracy"] == d["identification"]["single"]["force"]
    assert head["squeeze"]["accuracy"] == d["identification"]["squeeze"]["torque"]
    u = np.array(d["uncertainty95"], dtype=float)
    assert u.shape == (6, 6)
    free = u[:5]  # the five free faces are fitted: finite, positive intervals in N and N·m
    assert np.all(np.isfinite(free)) and np.all(free > 0)
    assert np.all(free[:, :3] < 5.0) and np.all(free[:, 3:] < 0.1)


def test_identification_counts_a_load_only_where_the_reference_shows_one():
    """A calibration of a linear cube identifies every single-face load (SIMULATED, issue 45): a
    sample labelled loaded while the load passes near zero (ramps) is no miss, since the
    reference shows no load on the face either; squeeze samples keep their labels."""
    from pito_core.calibration import evaluate
    from pito_core.sim import SimParams, VirtualCube, simulate_calibration

    cube = VirtualCube(params=SimParams(element_nonlinearity=0.0, frame_nonlinearity=0.0, frame_hysteresis=0.0))
    face = simulate_calibration("face", 6, k=600, seed=1, model=cube, faces=(1, 2, 3, 4, 5))
    hole = simulate_calibration("frame_hole", 6, k=600, seed=2, model=cube, faces=(6,), t0=100.0)
    cal = calibrate([face, hole], "unloaded_frame", model="linear")
    new = simulate_calibration("face", 6, k=1000, seed=3, model=cube, faces=(1, 2, 3, 4, 5), t0=200.0)
    loaded, ref = np.asarray(new.loaded[:]), np.asarray(new.reference[:])
    light = loaded.any(axis=1) & (np.linalg.norm(ref[:, :3], axis=1) < 0.5)
    assert light.sum() > 50  # labelled loaded, the reference shows < 0.5 N: counted as misses before
    ev = evaluate(cal, new)
    assert ev.identification["single"]["force"] == 1.0
    np.testing.assert_array_equal(ev.identification["by_loaded_face"]["force"][:5], 1.0)
    assert np.isnan(ev.identification["by_loaded_face"]["force"][5]) and ev.identification["by_loaded_face_n"][5] == 0
    assert sum(ev.identification["by_loaded_face_n"]) == ev.identification["single"]["n"]

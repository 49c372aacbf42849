"""pito bench: correctness only (STYLE.md item 12: benchmarks are not tests, no timing asserted)."""

from __future__ import annotations

import json
import os
import math

import numpy as np
import pytest

from pito_bench import _data, _report, _run
from pito_bench._calibration import plain_fit, rmse_summary
from pito_bench._contact import SURFACES, make_surface, pareto, sample_contacts, scipy_solve
from pito_bench._pipeline import _naive_decode, default_pipeline, live_scenario


@pytest.fixture(scope="module")
def quick_result(tmp_path_factory):
    """A quick run on tiny sizes (calibration and contact sections, in subprocesses)."""
    return _run.run_bench(
        quick=True, sections=("calibration", "contact"), sizes=[1000, 2000],
        workdir=str(tmp_path_factory.mktemp("bench")),
        contact_sizes={"n_speed": 2000, "n_acc": 400, "n_scipy": 3, "n_single": 300, "n_two": 100},
        calibration_studies=("random_cubes",),  # the model-choice and coverage studies: `pito bench`, not tests
    )


@pytest.mark.slow
def test_quick_run_json_has_calibration_and_contact_ratios(quick_result):
    doc = json.loads(json.dumps(quick_result, allow_nan=False))  # strict JSON (no NaN), round trip
    cal, con = doc["calibration"], doc["contact"]
    assert "simulated" in cal["data"]
    methods = {r["method"] for r in cal["memory"]}
    assert methods == {"face_to_face", "quasi_total", "total", "loaded_frame", "unloaded_frame"}
    for r in cal["memory"]:
        assert r["k"] in (1000, 2000)
        for key in ("rmse_force_N", "rmse_torque_Nm", "rmse_ratio_lstsq", "rmse_ratio_pinv", "time_ratio_lstsq"):
            assert math.isfinite(r[key]) and r[key] > 0, key
        c = r["coverage95"]  # the default's intervals, loaded and at rest (true wrench 0)
        assert 0 <= c["min"] <= c["max"] <= 1 and 0 <= c["rest_min"] <= c["rest_max"] <= 1, c
    rc = cal["random_cubes"]["rows"]  # default fit vs the papers' plain affine least squares (issue 10, item 7)
    assert {r["method"] for r in rc} == methods
    for r in rc:
        assert r["n_cases"] > 0 and r["force_ratio_worst"] <= 1.02 and r["torque_ratio_worst"] <= 1.02, r
    assert {r["k"] for r in cal["streamed"]} == {1000, 2000}
    for r in cal["streamed"]:
        assert r["fit_peak_rss_MB"] > 0 and math.isfinite(r["rmse_force_N"])
    kinds = {a["surface"] for a in con["accuracy"]}
    assert kinds == set(SURFACES)
    assert {a["scenario"] for a in con["accuracy"]} == {"soft", "near_tangent", "point"}
    for a in con["accuracy"]:
        assert "crb_ratio" in a and "valid_fraction" in a
    finite = [a["crb_ratio"] for a in con["accuracy"] if math.isfinite(a["crb_ratio"])]
    assert len(finite) >= len(con["accuracy"]) - 2
    assert all(p["solves_per_s"] > 0 for p in con["pareto"])
    assert any(p["pareto"] for p in con["pareto"])
    assert any(t["target"].startswith("contact error") for t in doc["targets"])
    single = con["single"]["rows"]  # the single-contact test beside the CRB ratios, per patch kind
    assert [r["surface"] for r in single] == list(SURFACES)
    assert all(0 <= r["false_alarm"] <= 1 and 0 <= r["indistinguishable"] <= 1 for r in single)
    assert all("flagged_fraction" in a for a in con["accuracy"])


@pytest.mark.slow
def test_report_text_has_units_and_plots(quick_result, tmp_path):
    text = _report.format_report(quick_result)
    for unit in ("(ms)", "(N)", "(N·m)", "(MB)", "solves/s", "error/CRB", "Targets"):
        assert unit in text
    paths = _report.write_plots(quick_result, tmp_path)
    assert len(paths) == 4 and any(p.endswith("contact_single.png") for p in paths)
    assert all(p.endswith(".png") and (tmp_path / p.split("/")[-1]).stat().st_size > 1000 for p in paths)


def test_live_section_skipped_without_app_extras(monkeypatch):
    monkeypatch.setattr(_run, "live_available", lambda: False)
    out = _run.run_bench(sections=("live",))
    assert out["live"] == {"status": "skipped: app extras not installed"}
    assert "skipped: app extras not installed" in _report.format_report(out)


def test_unknown_section_is_refused():
    with pytest.raises(ValueError, match="sections"):
        _run.run_bench(sections=("gpu",))


def test_generated_file_equals_in_memory_session(tmp_path):
    from pito_core.calibration import CalibrationSession

    n = _data.GEN_BLOCK + 500  # two generator blocks
    path = tmp_path / "s.h5"
    _data.write_session_file(path, "face", 6, n, seed=3)
    a = CalibrationSession.load(path)
    b = _data.generate_session("face", 6, n, seed=3)
    assert np.array_equal(a.counts, b.counts) and np.array_equal(a.reference, b.reference)
    assert np.array_equal(a.loaded, b.loaded) and a.meta["simulated"] is True
    assert (a.loaded.sum(axis=1) <= 1).all() and (~a.loaded.any(axis=1)).sum() > 50


def test_generator_follows_the_load_paths():
    from pito_core.frames import FACES, invert_pose, transform_wrench
    from pito_core.sim import face_wrenches_from_applied

    for flange in ("face", "frame", "frame_hole"):
        d = _data.BenchData(flange, 6, 2000, seed=1)
        counts, reference, loaded = d.block(0)
        rng = np.random.default_rng([1, 0])  # replay the block's draws
        face = np.asarray(d.faces)[rng.integers(0, len(d.faces), 2000)]
        face[rng.random(2000) < _data.UNLOADED_FRACTION] = 0
        face[:50] = 0
        W = rng.uniform(-1, 1, (2000, 6)) * _data.LOAD_SCALE
        applied = np.zeros((2000, 6, 6))
        for i in FACES:
            s = face == i
            applied[s, i - 1] = transform_wrench(W[s], invert_pose(d.core.face_pose(i)))
        F, W_total, _ = face_wrenches_from_applied(applied, flange, 6, d.core)
        np.testing.assert_allclose(reference, transform_wrench(W_total, d.T_core_ati), atol=1e-9)
        np.testing.assert_array_equal(counts, d.cube.counts_from_face_wrenches(F, np.zeros(2000), rng=rng))


def test_plain_fit_is_the_dense_least_squares_solution():
    from pito_core.calibration import calibrate, evaluate

    s = _data.generate_session("face", 6, 6000, seed=1)
    test = _data.generate_session("face", 6, 3000, seed=2)
    for method in ("unloaded_frame", "face_to_face"):
        faces = calibrate(s, method).output_faces
        a = plain_fit(s, method, faces, "lstsq")
        b = plain_fit(s, method, faces, "pinv")
        assert a.output_faces == faces and a.matrix.shape == (6 * len(faces), 36)
        np.testing.assert_allclose(a.matrix, b.matrix, rtol=1e-6, atol=1e-9 * np.abs(a.matrix).max())
        r = rmse_summary(evaluate(a, test))
        assert 0 < r["rmse_force_N"] < 2.0 and 0 < r["rmse_torque_Nm"] < 0.05  # loads: ±15 N, ±0.1 N·m


@pytest.mark.parametrize("kind", ["plane", "sphere", "ellipsoid", "mesh"])
@pytest.mark.parametrize("scenario", ["soft", "near_tangent", "point"])
def test_sampled_contacts_push_on_the_surface(kind, scenario):
    from pito_core.contact import solve

    surface = make_surface(kind)
    c, n, f, tau = sample_contacts(surface, 200, scenario, np.random.default_rng(0))
    cosang = -(f * n).sum(1) / np.linalg.norm(f, axis=1)
    assert (cosang > 0).all()
    if scenario == "near_tangent":
        assert (cosang < np.cos(np.deg2rad(79))).all()
    if scenario == "point":
        assert (tau == 0).all()
    w = np.c_[f, np.cross(c, f) + tau[:, None] * n]
    est = solve(surface, w)
    ok = est.valid
    assert ok.mean() > 0.9
    # every estimate explains the wrench exactly (noise free) ...
    m_est = np.cross(est.point[ok], est.force[ok]) + est.torsion[ok, None] * est.normal[ok]
    np.testing.assert_allclose(m_est, w[ok, 3:], atol=1e-9)
    # ... and is the true contact, except on the bumpy mesh with nearly tangent forces,
    # where the line of action can enter the surface twice (two exact solutions)
    if not (kind == "mesh" and scenario == "near_tangent"):
        np.testing.assert_allclose(est.point[ok], c[ok], atol=1e-7)


@pytest.mark.parametrize("kind", ["plane", "sphere", "ellipsoid"])
def test_scipy_baseline_recovers_noise_free_contacts(kind):
    surface = make_surface(kind)
    c, n, f, tau = sample_contacts(surface, 5, "soft", np.random.default_rng(1))
    w = np.c_[f, np.cross(c, f) + tau[:, None] * n]
    cov = np.diag([1e-4] * 3 + [1e-8] * 3)
    np.testing.assert_allclose(scipy_solve(surface, w, cov), c, atol=1e-6)


def test_mesh_has_5000_facets():
    assert len(make_surface("mesh").mesh.faces) == 5000


def test_pareto_marks_dominated_points():
    speed = [{"surface": "plane", "solver": "closed form (soft finger)", "solves_per_s": 10.0},
             {"surface": "plane", "solver": "scipy least_squares (soft finger)", "solves_per_s": 1.0}]
    acc = [{"surface": "plane", "scenario": "soft", "crb_ratio": 1.0, "scipy_crb_ratio": 2.0}]
    pts = {p["solver"]: p["pareto"] for p in pareto(speed, acc)}
    assert pts == {"closed form (soft finger)": True, "scipy least_squares (soft finger)": False}


def test_naive_decoder_and_live_pipeline_on_simulated_frames():
    from pito_core.devices import pack_frames

    counts, truth = live_scenario(50, seed=0)
    data = b"\x00\x01" + pack_frames(np.arange(50), np.arange(50) * 1000, counts)
    assert _naive_decode(data) == 50
    pipe = default_pipeline()  # the one pipeline of pito_core (what the app and pito record run)
    t = np.arange(40, 50) * 1e-3
    bundle = pipe.process({"time": t, "counts": counts[-10:], "tick": np.arange(40, 50) * 1000})
    assert bundle.face_wrenches.shape == (10, 6, 6) and bundle.contacts.valid.all()
    # the six contacts of the latest sample, back in face frames, are near the truth
    T = pipe.core.face_poses()
    for i in range(6):
        p_face = T[i, :3, :3].T @ (bundle.contacts.point[i] - T[i, :3, 3])
        assert np.linalg.norm(p_face - truth["points"][-1, i]) < 2e-3


def test_cli_help_and_bad_sizes(capsys):
    from pito_core.cli import main

    with pytest.raises(SystemExit):
        main(["bench", "--help"])
    assert "solves per second" in capsys.readouterr().out
    assert main(["bench", "--sizes", "12"]) == 1
    assert "--sizes" in capsys.readouterr().err


def test_stamp_latency_counts_each_new_stamp_once_from_its_first_read():
    """Latency = first read showing a stamp − its sample time; the stamp on screen at the start is not
    counted (it may have been there a while), black is no data, a stamp from the future is bad."""
    from pito_bench._live_window import _StampLog
    from pito_bench._stamp import encode

    def bgra(t):
        r, g, b = encode(t)
        return np.array([b, g, r, 255])

    log = _StampLog()
    log.see(np.zeros(4), 99.0)  # nothing shown yet
    for t_read, t_sample in ((100.000, 99.990), (100.001, 99.990), (100.012, 100.000), (100.013, 100.000),
                             (100.030, 100.020), (100.031, 100.045)):
        log.see(bgra(t_sample), t_read)
    assert np.allclose(log.lat, [12.0, 10.0], atol=1e-6)  # ms: the first stamp is not counted, repeats once
    assert log.bad == 1  # 100.045 read at 100.031: after the read (decoded as 4.7 h old)


@pytest.mark.skipif(not os.environ.get("DISPLAY"), reason="needs an X server (the suite runs under xvfb-run)")
def test_shared_memory_grabs_equal_xgetimage_grabs():
    """The live-window benchmark's MIT-SHM grabs show the same pixels as plain XGetImage."""
    from pito_bench._xgrab import Grabber, _x

    shm, plain = Grabber(os.environ["DISPLAY"]), Grabber(os.environ["DISPLAY"], shm=False)
    win = _draw_test_window(plain.dpy)  # known pixels on the screen (an empty root is all black)
    try:
        if not shm.uses_shm:
            pytest.skip("this X server has no MIT-SHM")
        assert len(np.unique(shm.grab(0, 0, 320, 240).reshape(-1, 4), axis=0)) >= 3
        for rect in ((0, 0, 64, 48), (10, 20, 300, 200), (5, 5, 300, 200), (12, 22, 1, 1), (200, 100, 1, 1)):  # two of one size share a segment; a stamp pixel
            a = shm.grab(*rect).copy()
            b = plain.grab(*rect)
            assert a.shape == b.shape == (rect[3], rect[2], 4)
            assert np.array_equal(a, b)
    finally:
        _x.XDestroyWindow(plain.dpy, win)
        shm.close()
        plain.close()


def _draw_test_window(dpy):
    """A 300×200 window at (10, 20) in grey with a red and a blue rectangle (Xlib through ctypes)."""
    import ctypes

    from pito_bench._xgrab import _x

    _x.XCreateSimpleWindow.restype = ctypes.c_ulong
    _x.XCreateSimpleWindow.argtypes = [ctypes.c_void_p, ctypes.c_ulong] + [ctypes.c_int] * 2 + [ctypes.c_uint] * 3 + [ctypes.c_ulong] * 2
    _x.XCreateGC.restype = ctypes.c_void_p
    _x.XCreateGC.argtypes = [ctypes.c_void_p, ctypes.c_ulong, ctypes.c_ulong, ctypes.c_void_p]
    _x.XSetForeground.argtypes = [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_ulong]
    _x.XFillRectangle.argtypes = [ctypes.c_void_p, ctypes.c_ulong, ctypes.c_void_p] + [ctypes.c_int] * 2 + [ctypes.c_uint] * 2
    _x.XMapWindow.argtypes = [ctypes.c_void_p, ctypes.c_ulong]
    _x.XDestroyWindow.argtypes = [ctypes.c_void_p, ctypes.c_ulong]
    _x.XFreeGC.argtypes = [ctypes.c_void_p, ctypes.c_void_p]
    win = _x.XCreateSimpleWindow(dpy, _x.XDefaultRootWindow(dpy), 10, 20, 300, 200, 0, 0, 0x808080)
    _x.XMapWindow(dpy, win)
    _x.XSync(dpy, 0)
    gc = _x.XCreateGC(dpy, win, 0, None)
    for color, rect in ((0xFF0000, (5, 5, 50, 30)), (0x0000FF, (100, 60, 120, 90))):
        _x.XSetForeground(dpy, gc, color)
        _x.XFillRectangle(dpy, win, gc, *rect)
    _x.XFreeGC(dpy, gc)
    _x.XSync(dpy, 0)
    return win


@pytest.mark.parametrize("kind", ["plane", "sphere", "ellipsoid"])
def test_plain_closed_form_baseline_is_the_solvers_model(kind):
    from pito_bench._baseline import plain_contact
    from pito_core.contact import solve

    surface = make_surface(kind)
    c, n, f, tau = sample_contacts(surface, 200, "soft", np.random.default_rng(2))
    w = np.c_[f, np.cross(c, f) + tau[:, None] * n]
    geo = (dict(point=surface.point, normal=surface.normal) if kind == "plane" else
           dict(center=surface.center, semi_axes=surface.semi_axes, rotation=surface.rotation))
    cb, nb, taub, okb = plain_contact(kind, w[:, :3], w[:, 3:], **geo)
    est = solve(surface, w, single_contact=False)
    assert okb.all() and est.valid.all()
    np.testing.assert_allclose(cb, c, atol=1e-12)
    np.testing.assert_allclose(cb, est.point, atol=1e-12)
    np.testing.assert_allclose(nb, est.normal, atol=1e-12)
    np.testing.assert_allclose(taub, est.torsion, atol=1e-12)


def test_analysis_section_times_every_stage_of_a_simulated_recording():
    from pito_bench._analysis import task_analysis

    r = task_analysis(n_trials=1, repeat=1)
    assert r["samples"] == 6000 and r["trials"] == 1
    stages = [row["stage"] for row in r["rows"]]
    assert stages == ["read", "pair", "calibrate", "contacts", "single-contact test", "contacts with the test", "metrics",
                      "figures", "write"]
    assert all(row["samples_per_s"] > 0 for row in r["rows"] if row["stage"] not in ("calibrate", "single-contact test"))
    assert r["rows"][0]["ratio_read"] == 1.0
    assert r["analyze_recording_samples_per_s"] > 0 and r["figures_share"] > 0
    text = "\n".join(_report._analysis_tables({**r, "data": "SIMULATED", "threads": 1}))
    assert "samples/s" in text and "single-contact test" in text


def test_the_coverage_tables_give_each_face_and_axis_over_the_rows():
    """``coverage_faces_table``: per method, face and axis, the mean over the study's rows and its range;
    faces without output left out."""
    from pito_bench._calibration import coverage_cubes_table, coverage_faces_table

    rows = []
    for level, share in ((0.0, 0.94), (0.0033, 0.98)):
        per = np.full((6, 6), share)
        per[5] = np.nan
        rows.append({"cube": "linear 2%", "method": "quasi_total", "reference_noise": level, "model": "linear",
                     "pooled": share, "se": 0.001, "min": share, "max": share, "out_of_93_97": 0, "n_axes": 30,
                     "per_face_axis": per.tolist()})
    rows[0].update(carrying=0.99, free=0.93, rms_z_carrying=0.25, rms_z_free=1.1)  # rows[1]: a file from before
    cc = {"data": "SIMULATED", "draws": 2, "rows": rows}
    _, header, table = coverage_faces_table(cc)
    assert header == ["method", "face", "fx", "fy", "fz", "tx", "ty", "tz"]
    assert [r[1] for r in table] == ["1", "2", "3", "4", "5"] and table[0][2] == "96.0 (94-98)"
    _, header, table = coverage_cubes_table(cc)
    assert header[5] == "±" and table[1][4:6] == ["98.0", "0.10"]
    assert header[-4:] == ["carrying %", "free %", "RMS z carrying", "RMS z free"]
    assert table[0][-4:] == ["99.0", "93.0", "0.25", "1.10"] and table[1][-4:] == ["nan"] * 4


def test_model_choice_table_shows_the_validation_pass():
    """The later-session table gives, per method, the worst after a validation pass and the fits it set back."""
    from pito_bench._model_choice import model_choice_table

    keys = ("single_F", "single_T", "squeeze_F", "squeeze_T")
    row = {"method": "total", "k_per_face": 600, "groups_corrected": 3, "groups": 24, "every_worst": 1.0,
           "validated_worst": 0.987, "reverted": 1, "fits": 4,
           **{f"{k}_worst": 1.03 for k in keys}, **{f"{k}_median": 0.5 for k in keys}}
    title, header, rows = model_choice_table({"data": "SIMULATED", "rows": [row]})
    assert "validation pass" in title and header[-2:] == ["validated worst", "set back"]
    assert rows[0][-2:] == ["0.987", "1/4"]
    older = {k: v for k, v in row.items() if k not in ("validated_worst", "reverted", "fits")}  # a bench.json before it
    assert model_choice_table({"data": "SIMULATED", "rows": [older]})[2][0][-2:] == ["", ""]

"""Calibration model choice on a later session: the default against the papers' linear fit.

Two sets of cubes, both SIMULATED. The bench's own (``_cubes.py``, independent of
``pito_core.sim``: linear, per-gauge saturation, quadratic hub bending, both, coupling up to
10 %): each method fitted on single-face loads, scored on a later session (new offsets) of
single-face loads, squeeze loads (neighbouring faces in pairs) and single-face loads 1.5×
beyond the training's; truth = the cube's face wrenches. Then ``pito_core.sim``'s:

SIMULATED (``pito_core.sim.VirtualCube`` seed 0, with its temperature drift and frame
hysteresis): each method is fitted on one session per connected face and scored on a
LATER session of the same cube (other seed, one hour later: single-face loads, and
squeeze loads of neighbouring faces in pairs), each tared on its own unloaded samples;
truth = the simulated face wrenches. Reports, per method, the worst and median ratio of
the default's held-out RMSE to the linear fit's (forces, torques; single-face, squeeze),
and how many output groups (a face's forces or torques) took the correction.

The ratios read the loaded faces (the papers' figure). Beside them, ``every_worst``: the worst
ratio over every output of the loaded samples, the faces that carry nothing (crosstalk) and a
``face`` flange's connected face (the reaction) included. For ``pito_core.sim``'s cube also
``validated_worst``: the same worst after a validation pass (a fresh session of the same loads
:data:`VALIDATION_T0` after the training's, as the wizard and ``pito calibrate --validation``
record it; ``confirm_model``), and ``reverted``: the fits it set back to the linear fit.
"""

from __future__ import annotations

import numpy as np

from pito_core.calibration import calibrate, confirm_model
from pito_core.sim import VirtualCube, simulate_calibration, simulate_squeeze

from ._cubes import BenchCube, cube_session
from ._timing import run_worker

__all__ = ["task_model_choice", "task_independent_cubes", "model_choice_ratios", "CUBES"]

#: The bench's own cubes: (form, inter-face coupling, nonlinearity at full scale).
CUBES = (("linear", 0.02, 0.0), ("linear", 0.10, 0.0), ("saturation", 0.02, 0.1), ("saturation", 0.10, 0.1),
         ("hub", 0.05, 0.1), ("both", 0.10, 0.1))
#: Seeds the bench draws its cubes' forms with (each seed: all of ``CUBES`` anew).
CUBE_SEEDS = (0, 1, 2, 3, 4)
#: Later-session loads: (kind, squeeze, load scale).
TEST_KINDS = (("single", False, 1.0), ("squeeze", True, 1.0), ("beyond", False, 1.5))
#: When the validation pass is recorded, s after the training session's start (the later sessions: 3600 s).
VALIDATION_T0 = 600.0

#: Flange each method is fitted with (``unloaded_frame``: its free faces only).
FLANGE = {"face_to_face": "frame_hole", "quasi_total": "frame", "total": "face", "loaded_frame": "frame_hole",
          "unloaded_frame": "face"}


def _ratio(W, Wl, truth, mask, cols):
    e, el = (W - truth)[mask][:, cols], (Wl - truth)[mask][:, cols]
    return float(np.sqrt(np.mean(e**2) / np.mean(el**2)))


def _every_output(W, Wl, truth, loaded, has_output) -> float:
    """The worst of the force and torque ratios over every output of the loaded samples."""
    mask = loaded.any(axis=1)[:, None] & has_output[None]
    return max(_ratio(W, Wl, truth, mask, slice(0, 3)), _ratio(W, Wl, truth, mask, slice(3, 6)))


def task_model_choice(k, faces, seed=1, cube_seed=0) -> dict:
    """Held-out RMSE ratios default / linear per method (see the module docstring); ``cube_seed``: the
    ``VirtualCube``'s seed, ``seed`` the training session's (the later sessions': ``seed + 100``, ``+ 200``)."""
    cube = VirtualCube(seed=cube_seed)
    rows = []
    for method, fl in FLANGE.items():
        r = {key: [] for key in ("single_F", "single_T", "squeeze_F", "squeeze_T", "every", "validated")}
        groups, used, reverted = 0, 0, 0
        for face in faces:
            loaded = tuple(f for f in range(1, 7) if f != face) if method == "unloaded_frame" else None
            train = simulate_calibration(fl, face, k=k, seed=seed, model=cube, faces=loaded)
            auto, lin = calibrate(train, method), calibrate(train, method, model="linear")
            ra = auto.model.row_alpha or []
            groups += len(auto.output_faces) * 2
            used += sum(a is not None for a in ra) // 3
            val = simulate_calibration(fl, face, k=max(k // 2, 300), seed=seed + 50, model=cube, faces=loaded,
                                       t0=VALIDATION_T0)
            checked, _ = confirm_model(auto, val, sessions=[train], fit_options={"model": "auto"})
            reverted += checked is not auto
            free = loaded or [f for f in range(1, 7) if not (fl == "frame" and f == face)]
            pairs = [(free[i], free[(i + 1) % len(free)]) for i in range(len(free))]
            later = {"single": simulate_calibration(fl, face, k=max(k // 2, 300), seed=seed + 100, model=cube,
                                                    faces=loaded, t0=3600.0, return_truth=True),
                     "squeeze": simulate_squeeze(fl, face, k=max(k // 4, 200), seed=seed + 200, pairs=pairs,
                                                 model=cube, t0=3600.0, return_truth=True)}
            for kind, (s, truth) in later.items():
                rest = s.counts[~s.loaded.any(axis=1)]
                W, Wl = auto.tare(rest).wrenches(s.counts), lin.tare(rest).wrenches(s.counts)
                mask = s.loaded & auto.has_output[None]
                r[kind + "_F"].append(_ratio(W, Wl, truth.face_wrenches, mask, slice(0, 3)))
                r[kind + "_T"].append(_ratio(W, Wl, truth.face_wrenches, mask, slice(3, 6)))
                r["every"].append(_every_output(W, Wl, truth.face_wrenches, s.loaded, auto.has_output))
                Wc = W if checked is auto else checked.tare(rest).wrenches(s.counts)
                r["validated"].append(max(_ratio(Wc, Wl, truth.face_wrenches, mask, c)
                                          for c in (slice(0, 3), slice(3, 6))))
        row = {"method": method, "flange": fl, "faces": list(faces), "k_per_face": int(k), "cube_seed": int(cube_seed),
               "seed": int(seed), "groups": groups,
               "groups_corrected": used, "reverted": reverted, "fits": len(faces)}
        for key, v in r.items():
            row[key + "_worst"], row[key + "_median"] = float(np.max(v)), float(np.median(v))
        rows.append(row)
    return {"rows": rows}


def task_independent_cubes(k, connected_face=6, seed=1, cube_seed=0) -> dict:
    """Held-out RMSE ratios default / linear per cube, method and test kind (see the module docstring);
    ``cube_seed`` draws the cubes' forms (gains, coupling, hub), ``seed`` the training session."""
    rows = []
    for form, coupling, level in CUBES:
        cube = BenchCube(form, coupling, level, seed=cube_seed)
        for method, fl in FLANGE.items():
            c = connected_face
            faces = [f for f in range(1, 7) if not ((fl == "frame" or method == "unloaded_frame") and f == c)]
            train, _ = cube_session(cube, fl, c, faces, k, seed=seed)
            auto, lin = calibrate(train, method), calibrate(train, method, model="linear")
            ra = auto.model.row_alpha or []
            row = {"cube": f"{form} {coupling:.0%}", "cube_seed": int(cube_seed), "method": method, "k_per_face": int(k),
                   "groups": 2 * len(auto.output_faces), "groups_corrected": sum(a is not None for a in ra) // 3}
            pairs = [(faces[i], faces[(i + 1) % len(faces)]) for i in range(len(faces))]
            for kind, squeeze, scale in TEST_KINDS:
                s, F = cube_session(cube, fl, c, [] if squeeze else faces, max(k // 2, 300), pairs=pairs if squeeze else (),
                                    load_scale=scale, seed=seed + 100, offset_shift=50.0)
                rest = s.counts[~s.loaded.any(axis=1)]
                W, Wl = auto.tare(rest).wrenches(s.counts), lin.tare(rest).wrenches(s.counts)
                mask = s.loaded & auto.has_output[None]
                row[kind + "_F"] = _ratio(W, Wl, F, mask, slice(0, 3))
                row[kind + "_T"] = _ratio(W, Wl, F, mask, slice(3, 6))
                row["every_worst"] = max(row.get("every_worst", 0.0), _every_output(W, Wl, F, s.loaded, auto.has_output))
            rows.append(row)
    return {"rows": rows}


def model_choice_ratios(quick: bool = False, threads: int = 1, progress=print) -> dict:
    """The section ``calibration.model_choice`` of ``pito bench`` (in a subprocess)."""
    faces = [6, 2] if quick else [6, 2, 3, 1]
    ks = [600] if quick else [600, 3000]
    progress(f"calibration: model choice on a later session, {len(faces)} connected faces, k = {ks}")
    rows = []
    for k in ks:
        rows += run_worker("cal_model_choice", {"k": k, "faces": faces}, threads=threads)["rows"]
    k_ind = 1000 if quick else 2000
    cube_seeds = CUBE_SEEDS[:1] if quick else CUBE_SEEDS
    progress(f"calibration: model choice on the bench's own cubes, k = {k_ind} per face, cube seeds {list(cube_seeds)}")
    ind = []
    for cs in cube_seeds:
        ind += run_worker("cal_independent", {"k": k_ind, "cube_seed": cs}, threads=threads)["rows"]
    return {"data": "SIMULATED: pito_core.sim.VirtualCube seed 0, trained on one session, scored on a later one",
            "rows": rows, "independent": {"data": "SIMULATED: pito_bench._cubes (independent of pito_core.sim)",
                                          "rows": ind}}


def model_choice_table(mc) -> tuple[str, list, list]:
    """``(title, header, rows)`` of the section for the text report."""
    def f(x):
        return f"{x:.3f}"

    rows = [[r["method"], f"{r['k_per_face']:,}", f"{r['groups_corrected']}/{r['groups']}",
             f(r["single_F_worst"]), f(r["single_T_worst"]), f(r["squeeze_F_worst"]), f(r["squeeze_T_worst"]),
             f(r["single_F_median"]), f(r["single_T_median"]), f(r["every_worst"]),
             f(r["validated_worst"]) if "validated_worst" in r else "", f"{r['reverted']}/{r['fits']}" if "reverted" in r
             else ""] for r in mc["rows"]]
    title = (f"Calibration model on a later session ({mc['data']}): default / papers' linear fit, held-out RMSE "
             "ratio on the loaded faces; every output: also the faces that carry nothing and the connected face's "
             "reaction; groups = a face's forces or torques that took the correction; validated: the worst loaded-face "
             "ratio after a validation pass of fresh loads (confirm_model), and the fits it set back to linear")
    header = ["method", "k per face", "groups corrected", "single F worst", "single T worst", "squeeze F worst",
              "squeeze T worst", "single F median", "single T median", "every output worst", "validated worst",
              "set back"]
    return title, header, rows


def independent_table(mc) -> tuple[str, list, list] | None:
    """``(title, header, rows)`` of the bench's own cubes, with the worst and median over them."""
    ind = (mc or {}).get("independent")
    if not ind:
        return None
    keys = [f"{k}_{p}" for k, _, _ in TEST_KINDS for p in "FT"] + ["every_worst"]
    rows = [[f"{r['cube']} #{r.get('cube_seed', 0)}", r["method"], f"{r['groups_corrected']}/{r['groups']}"]
            + [f"{r[k]:.3f}" for k in keys] for r in ind["rows"]]
    nl = np.array([[r[k] for k in keys] for r in ind["rows"] if not r["cube"].startswith("linear")])
    li = np.array([[r[k] for k in keys] for r in ind["rows"] if r["cube"].startswith("linear")])
    if nl.size:
        rows.append(["nonlinear cubes", "worst", ""] + [f"{v:.3f}" for v in nl.max(axis=0)])
        rows.append(["nonlinear cubes", "median", ""] + [f"{v:.3f}" for v in np.median(nl, axis=0)])
    if li.size:
        rows.append(["linear cubes", "worst", ""] + [f"{v:.3f}" for v in li.max(axis=0)])
    title = (f"Calibration model on a later session ({ind['data']}): default / papers' linear fit, held-out RMSE "
             "ratio on the loaded faces (single-face, squeeze, single-face at 1.5× the training loads), and the worst "
             "over every output (also the faces that carry nothing and the connected face's reaction); #n = the cube seed")
    return title, ["cube", "method", "groups corrected"] + keys, rows

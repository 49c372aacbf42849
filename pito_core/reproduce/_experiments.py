"""The papers' experiments on the simulator: sessions → calibrations → figures of merit.

Every figure of merit comes from the calibration core (``calibrate``, ``evaluate``,
``equilibrium``); this module only decides which simulated sessions feed which method.
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass, field

import numpy as np

from ..calibration import MountGeometry, calibrate, equilibrium, evaluate
from ..contact import Plane, solve
from ..frames import FACES
from ..sim import (
    SimParams,
    VirtualCube,
    simulate_calibration,
    simulate_free_grasp,
    simulate_squeeze,
    simulate_touches,
)

__all__ = ["ReproductionConfig", "Results", "run_experiments", "METHOD_MOUNTS", "METHOD_ORDER", "GRASP_METHODS"]

#: Order of the methods in tables and figures.
METHOD_ORDER = ("face_to_face", "quasi_total", "total", "loaded_frame", "unloaded_frame")

#: Calibrations shown in the free grasp (paper Fig. 20): every method, plus ``unloaded_frame``
#: fitted on its face-flange session together with a ``frame_hole`` session (the net-load
#: directions measured). Face/frame-flange loads span 30 of 36 directions (every sample has
#: Σ_i F_i = 0 about the flange), so a face-flange fit alone leaves the net force of a free
#: grasp unidentified (plain least squares: ΣF ≈ 0); ``meta["net_load"]`` says which.
GRASP_METHODS = ("face_to_face", "quasi_total", "total", "loaded_frame", "unloaded_frame", "unloaded_frame+frame_hole")

#: Placement scatter of a fingertip/pencil aimed at a marked point, m per in-plane axis
#: (``simulate_touches(placement_scatter=)``), and touches per point in the 8-point test.
TOUCH_SCATTER = 1.5e-3
TOUCH_REPEATS = 3

#: Calibration mounts of each method: (flange, connected faces of its calibration sessions).
#: ``total`` combines two face-flange sessions so that the connected face's rows are fitted
#: from direct loads too (a single face-flange session only tells them through the reaction).
METHOD_MOUNTS = {
    "face_to_face": ("face", (6,)),
    "quasi_total": ("frame", (6,)),
    "total": ("face", (6, 5)),
    "loaded_frame": ("frame_hole", (6,)),
    "unloaded_frame": ("face", (6,)),
}


@dataclass(frozen=True)
class ReproductionConfig:
    """Sizes and seeds of a reproduction run.

    Attributes
    ----------
    k : int
        Samples per loaded face in calibration sessions.
    k_test : int
        Samples per loaded face in held-out single-face sessions.
    k_squeeze : int
        Samples per squeeze pair.
    k_grasp : int
        Samples of the free grasp (1 kHz).
    k_touch : int
        Samples per fingertip touch.
    seed : int
        Seed of the runs; the cube is ``VirtualCube(seed=cube_seed)``.
    cube_seed : int
    connected_face : int
        Connected face of the main experiments (the papers' squeeze pairs avoid face 6).
    """

    k: int = 10_000
    k_test: int = 3_000
    k_squeeze: int = 3_000
    k_grasp: int = 24_000
    k_touch: int = 1_500
    seed: int = 0
    cube_seed: int = 0
    connected_face: int = 6

    @classmethod
    def quick(cls, seed: int = 0, cube_seed: int = 0) -> "ReproductionConfig":
        """Small sizes for CI smoke tests (well under two minutes on two cores)."""
        return cls(k=2_000, k_test=800, k_squeeze=800, k_grasp=12_000, k_touch=600, seed=seed, cube_seed=cube_seed)


@dataclass
class Results:
    """Everything the figures and the summary need (SI units)."""

    config: ReproductionConfig
    params: SimParams
    calibrations: dict = field(default_factory=dict)  # method -> Calibration
    evaluations: dict = field(default_factory=dict)  # method -> Evaluation
    linear_evaluations: dict = field(default_factory=dict)  # method -> Evaluation of the papers' linear fit
    per_connected: dict = field(default_factory=dict)  # (method, c) -> (Calibration, Evaluation)
    squeeze_per_connected: dict = field(default_factory=dict)  # (method, c) -> Evaluation on squeezes
    identification_series: dict = field(default_factory=dict)
    grasp: dict = field(default_factory=dict)
    touches: dict = field(default_factory=dict)
    timings: list = field(default_factory=list)
    notes: list = field(default_factory=list)
    generation_rate: float = float("nan")  # samples / s of the simulator
    grasp_net_load: dict = field(default_factory=dict)  # method -> meta["net_load"] words


class _Steps:
    def __init__(self, progress):
        self.progress = progress
        self.t0 = time.perf_counter()
        self.log = []

    def __call__(self, text):
        dt = time.perf_counter() - self.t0
        self.log.append((round(dt, 2), text))
        if self.progress is not None:
            self.progress(f"[{dt:6.1f} s] {text}")


def _calibrate_quiet(sessions, method):
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        cal = calibrate(sessions, method, allow_rank_deficient=True)
    return cal, [str(x.message) for x in w]


class _Sessions:
    """The simulated sessions of one reproduction, made once each and cached; each starts where the
    previous one ended (the gauges' drift goes on between them)."""

    def __init__(self, cfg: ReproductionConfig, cube: VirtualCube, res: Results):
        self.cfg, self.cube, self.res = cfg, cube, res
        self.cache = {}
        self.clock = 0.0

    def t0(self, n) -> float:
        """Start time (s) of a session of ``n`` samples; moves the clock past it and 5 s more."""
        start = self.clock
        self.clock += n / self.cube.params.rate + 5.0
        return start

    def calibration(self, flange, c, seed_off=0, free_only=False):
        """A calibration session (``cfg.k`` samples per face) on mount ``flange``, connected face ``c``."""
        cfg = self.cfg
        key = ("cal", flange, c, seed_off, free_only)
        if key not in self.cache:
            tt = time.perf_counter()
            faces = tuple(f for f in FACES if f != c) if free_only else None
            s = simulate_calibration(flange, c, k=cfg.k, seed=cfg.seed + seed_off, faces=faces, model=self.cube,
                                     t0=self.t0(6.3 * cfg.k))
            dt = time.perf_counter() - tt
            if dt > 0:
                rate = self.res.generation_rate
                self.res.generation_rate = max(rate if np.isfinite(rate) else 0, len(s) / dt)
            self.cache[key] = s
        return self.cache[key]

    def test(self, flange, c, free_only=False):
        """The held-out sessions on this mount: single-face loads and squeezes."""
        cfg = self.cfg
        key = ("test", flange, c, free_only)
        if key not in self.cache:
            faces = tuple(f for f in FACES if f != c) if free_only else None
            single = simulate_calibration(flange, c, k=cfg.k_test, seed=cfg.seed + 101, faces=faces, model=self.cube,
                                          t0=self.t0(6.3 * cfg.k_test))
            sq = simulate_squeeze(flange, c, k=cfg.k_squeeze, seed=cfg.seed + 202, model=self.cube,
                                  t0=self.t0(8.5 * cfg.k_squeeze))
            self.cache[key] = (single, sq)
        return self.cache[key]

    def squeeze(self, flange, c):
        """Squeeze loads with connected face ``c`` (the per-connected-face resultants)."""
        cfg = self.cfg
        key = ("sq", flange, c)
        if key not in self.cache:
            self.cache[key] = simulate_squeeze(flange, c, k=cfg.k_squeeze, seed=cfg.seed + 404, model=self.cube,
                                               t0=self.t0(8.5 * cfg.k_squeeze))
        return self.cache[key]


def run_experiments(config: ReproductionConfig | None = None, progress=print) -> Results:
    """Run every experiment of both papers on the default simulator.

    Parameters
    ----------
    config : ReproductionConfig, optional
        Sizes and seeds (default full size).
    progress : callable, optional
        Called with one line per step (elapsed time first); None for silence.

    Returns
    -------
    Results
    """
    cfg = ReproductionConfig() if config is None else config
    step = _Steps(progress)
    cube = VirtualCube(seed=cfg.cube_seed)
    res = Results(cfg, cube.params)
    sessions = _Sessions(cfg, cube, res)
    _main_comparison(res, sessions, step)
    _identification_series(res, sessions)
    step("face identification series (unloaded_frame and loaded_frame, single face and squeeze)")
    for c in FACES:
        _per_connected_face(res, sessions, c)
        step(f"connected face {c}: loaded frame, unloaded frame (alone and with a frame_hole session) fitted; "
             "single-face and squeeze loads evaluated")
    _free_grasp(res, sessions)
    step(f"free grasp: {cfg.k_grasp} samples, mass {res.grasp['run'].mass} kg, "
         f"{len(res.grasp['run'].scenario.names)} fingers")
    res.touches = _touch_test(res, cube, cfg, sessions.t0)
    step("contact-point test: " + ("done" if res.touches.get("available") else res.touches.get("reason", "skipped")))
    res.timings = step.log
    return res


def _main_comparison(res: Results, sessions: _Sessions, step) -> None:
    """Every method fitted on its mount with connected face ``cfg.connected_face``, evaluated held out."""
    cfg, c_main = res.config, res.config.connected_face
    step(f"simulating calibration sessions (k = {cfg.k} samples per face, connected face {c_main})")
    for method in METHOD_ORDER:
        flange, faces = METHOD_MOUNTS[method]
        faces = _mount_faces(faces, c_main)
        # unloaded_frame loads only the five free faces (the paper's protocol)
        fitted_on = [sessions.calibration(flange, c, free_only=method == "unloaded_frame") for c in faces]
        cal, warns = _calibrate_quiet(fitted_on, method)
        res.notes += [f"{method}: {w}" for w in warns]
        # held out like its training: unloaded_frame is tested on loads on the five free faces
        single, sq = sessions.test(flange, c_main, free_only=method == "unloaded_frame")
        ev = evaluate(cal, [single, sq])
        res.calibrations[method] = cal
        res.evaluations[method] = ev
        res.linear_evaluations[method] = ev if cal.model.name == "linear" else evaluate(cal.linear_alternative(), [single, sq])
        step(f"{method}: fitted on {len(fitted_on)} session(s) ({flange}; net load {cal.meta.get('net_load')}; "
             f"model {cal.model.name}); force RMSE "
             f"{np.nanmean(ev.rmse_force()):.3f} N, torque RMSE {np.nanmean(ev.rmse_torque()):.4f} N·m, "
             f"squeeze {np.sqrt(np.nanmean(ev.rmse_squeeze[:3] ** 2)):.3f} N")


def _identification_series(res: Results, sessions: _Sessions) -> None:
    """Force and torque norms per face over the held-out sessions (the papers' Fig. 6)."""
    for method, flange in (("unloaded_frame", "face"), ("loaded_frame", "frame_hole")):
        cal = res.calibrations[method]
        single, sq = sessions.test(flange, res.config.connected_face, free_only=method == "unloaded_frame")
        for kind, s in (("single", single), ("squeeze", sq)):
            counts = np.asarray(s.counts, dtype=float)
            free = ~np.asarray(s.loaded).any(axis=1)
            W = cal.wrenches(counts, offset=counts[free].mean(axis=0))
            entry = {
                "time": np.asarray(s.time) - s.time[0],
                "force_norm": np.linalg.norm(W[..., :3], axis=-1),
                "torque_norm": np.linalg.norm(W[..., 3:], axis=-1),
                "loaded": np.asarray(s.loaded),
                "connected_face": s.connected_face,
                "flange": flange,
                "method": method,
            }
            res.identification_series[kind if method == "unloaded_frame" else (method, kind)] = entry


def _per_connected_face(res: Results, sessions: _Sessions, c: int) -> None:
    """The three per-connected-face calibrations with connected face ``c``, on single-face and squeeze loads."""
    cfg, c_main = res.config, res.config.connected_face
    for method, flange in (("loaded_frame", "frame_hole"), ("unloaded_frame", "face"),
                           ("unloaded_frame+frame_hole", "face")):
        if c == c_main and method in res.calibrations:
            res.per_connected[(method, c)] = (res.calibrations[method], res.evaluations[method])
        else:
            if method == "unloaded_frame+frame_hole":
                fitted_on = [sessions.calibration("face", c, free_only=True), sessions.calibration("frame_hole", c)]
            else:
                fitted_on = sessions.calibration(flange, c, free_only=method == "unloaded_frame")
            cal, warns = _calibrate_quiet(fitted_on, method.split("+")[0])
            res.notes += [f"{method} (connected face {c}): {w}" for w in warns]
            faces = tuple(f for f in FACES if f != c) if method.startswith("unloaded_frame") else None
            single = simulate_calibration(flange, c, k=cfg.k_test, seed=cfg.seed + 303, faces=faces,
                                          model=sessions.cube, t0=sessions.t0(6.3 * cfg.k_test))
            res.per_connected[(method, c)] = (cal, evaluate(cal, single))
            if c == c_main:
                res.calibrations[method] = cal
        # squeeze resultant RMSE with this connected face (papers' Figs 11, 12, 16, 19)
        res.squeeze_per_connected[(method, c)] = evaluate(res.per_connected[(method, c)][0], sessions.squeeze(flange, c))


def _free_grasp(res: Results, sessions: _Sessions) -> None:
    """A free grasp seen through each of :data:`GRASP_METHODS`: the equilibrium against the truth."""
    cfg, cube = res.config, sessions.cube
    run = simulate_free_grasp(k=cfg.k_grasp, seed=cfg.seed, model=cube, t0=sessions.t0(cfg.k_grasp))
    grasp_methods = {}
    for method in GRASP_METHODS:
        cal = res.calibrations[method]
        if cal.model.name != "linear" and cal.meta.get("load_directions", {}).get("not_identified"):
            # the polynomial correction is fitted on the measured load directions: a free grasp's
            # net load lies outside them, so the papers' linear fit is the one shown here
            res.notes.append(f"{method}: free grasp with the papers' linear fit (net load not identified; the "
                             f"{cal.model.name} model is not fitted for it)")
            cal = cal.linear_alternative()
        W = cal.wrenches(run.counts)
        grasp_methods[method] = equilibrium(W, cube.core, run.mass, run.cog)
    res.grasp_net_load = {m: res.calibrations[m].meta.get("net_load", "not recorded") for m in GRASP_METHODS}
    eq_true = equilibrium(run.face_wrenches, cube.core, run.mass, run.cog)
    m_ag = run.mass * np.linalg.norm(run.state.accel - run.state.gravity, axis=1)
    res.grasp = {"run": run, "methods": grasp_methods, "truth": eq_true, "m_a_minus_g": m_ag}


def _mount_faces(faces, c_main: int) -> tuple:
    """:data:`METHOD_MOUNTS` is written for connected face 6; move it to ``c_main``."""
    if c_main == 6:
        return tuple(faces)
    second = 5 if c_main != 5 else 4
    return tuple(c_main if f == 6 else second for f in faces)


def _touch_test(res: Results, cube, cfg, t0) -> dict:
    """The 8-point test (multi-touch Fig. 3, PITO Fig. 22b): fingertip touches on face 5's flat
    patch, contact points from the cube's calibrated face wrench and from the reference sensor.

    Touches land :data:`TOUCH_SCATTER` (σ per axis) off their marked targets, as a fingertip or
    pencil aimed at a mark does; errors are measured against the targets (as the papers do),
    and against where the touch actually landed (the sensor's own error).
    """
    face = 5 if cfg.connected_face != 5 else 1
    session, truth = simulate_touches(face, "face", cfg.connected_face, k=cfg.k_touch, seed=cfg.seed, model=cube,
                                      t0=t0(10 * cfg.k_touch * TOUCH_REPEATS), placement_scatter=TOUCH_SCATTER,
                                      repeats=TOUCH_REPEATS)
    out = {"face": face, "points": truth.points, "available": False, "scatter_m": TOUCH_SCATTER,
           "repeats": TOUCH_REPEATS}
    cal = res.calibrations["unloaded_frame"]
    counts = np.asarray(session.counts, dtype=float)
    free = ~np.asarray(session.loaded).any(axis=1)
    W_cube = cal.wrenches(counts, offset=counts[free].mean(axis=0))[:, face - 1]
    # the reference measures the whole load in S_A; with only face 5 touched that is face 5's
    # wrench, moved into face 5's frame
    W_ref = np.asarray(session.reference, dtype=float) @ MountGeometry(session).X_face_ati[face - 1].T
    h = truth.points[0, 2]
    plane = Plane((0.0, 0.0, h), (0.0, 0.0, 1.0))
    fn = -truth.force[:, 2]
    for name, W in (("cube", W_cube), ("reference", W_ref)):
        est = solve(plane, W, force_threshold=1.0)
        est_pts = np.asarray(est.point)
        valid = np.asarray(est.valid) & (fn > 1.5) & (truth.point_index >= 0)
        rows = []
        for p in range(len(truth.points)):
            sel = (truth.point_index == p) & valid
            if not sel.any():
                rows.append((p, np.nan, np.nan, np.nan, np.nan, 0))
                continue
            e = est_pts[sel, :2]
            mean = e.mean(axis=0)
            err_target = np.linalg.norm(e - truth.points[p, :2], axis=1)
            err_placed = np.linalg.norm(e - truth.point[sel, :2], axis=1)
            rows.append((p, mean[0], mean[1], float(np.sqrt(np.mean(err_target**2))),
                         float(np.sqrt(np.mean(err_placed**2))), int(sel.sum())))
        rows = np.array(rows, dtype=float)
        e_t = est_pts[valid, :2] - truth.points[truth.point_index[valid], :2]
        e_p = est_pts[valid, :2] - truth.point[valid, :2]
        out[name] = {"rows": rows, "rms_target": float(np.sqrt(np.mean(np.sum(e_t**2, axis=1)))),
                     "rms_placed": float(np.sqrt(np.mean(np.sum(e_p**2, axis=1)))),
                     "est": est_pts, "valid": valid}
    placed_off = truth.placed[:, :2] - truth.points[np.tile(np.arange(len(truth.points)), TOUCH_REPEATS), :2]
    out.update(available=True, rows=out["cube"]["rows"],
               placement_rms=float(np.sqrt(np.mean(np.sum(placed_off**2, axis=1)))),
               samples={"true": truth.points, "est": out["cube"]["est"], "index": truth.point_index,
                        "valid": out["cube"]["valid"], "ref_est": out["reference"]["est"],
                        "ref_valid": out["reference"]["valid"], "placed": truth.placed})
    return out

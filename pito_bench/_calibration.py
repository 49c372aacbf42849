"""Calibration benchmark: fit time and held-out RMSE against the number of samples.

For every size k and method: ``calibrate`` on an in-memory session and streamed from a
session file (``CalibrationSession.load(path, lazy=True)``), side by side with a plain
NumPy fit of the same data (offsets, targets, then ``numpy.linalg.lstsq`` or
``numpy.linalg.pinv``), and the least-squares cores alone (the fit's Gram/Cholesky core,
``GramQR``, against ``lstsq`` on the same affine ``[1 | S]``, ``W``). Times are ratios against those baselines, measured
in the same process; RMSE is on a held-out simulated session. Each fit runs in its own
subprocess so its peak resident memory is its own.
"""

from __future__ import annotations

import os
import time
import tracemalloc
import warnings

import numpy as np
from scipy.signal import lfilter

from pito_core.calibration import (
    Calibration,
    CalibrationSession,
    GramQR,
    MountGeometry,
    StreamedQR,
    block_targets,
    calibrate,
    evaluate,
    fit_sensor,
    get_method,
    segment_ids,
)
from pito_core.sim import VirtualCube, random_sensor, random_sensor_session, simulate_calibration

from ._baseline import plain_affine_lstsq
from ._cubes import BenchCube, cube_session
from ._data import MOUNT_OF_METHOD, write_session_file
from ._timing import best_time, peak_rss_mb, run_worker

__all__ = ["METHODS", "run_calibration", "plain_fit", "rmse_summary", "random_cube_ratios", "interval_coverage", "hysteresis_trial"]

METHODS = ("face_to_face", "quasi_total", "total", "loaded_frame", "unloaded_frame")
#: Largest k fitted in memory (beyond, only the streamed fit from a file runs).
MAX_IN_MEMORY = 1_000_000
#: Largest k for which every method is streamed (beyond: ``unloaded_frame`` only).
MAX_ALL_METHODS_STREAMED = 1_000_000


def _current_rss_mb() -> float:
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1]) * 1024 / 1e6
    except OSError:  # pragma: no cover - not Linux
        pass
    return float("nan")


def rmse_summary(ev) -> dict:
    """Force RMSE (N) and torque RMSE (N·m) over the loaded faces' axes of an ``Evaluation``."""
    r = np.asarray(ev.rmse_single, dtype=float)
    return {
        "rmse_force_N": float(np.sqrt(np.nanmean(r[:, :3] ** 2))),
        "rmse_torque_Nm": float(np.sqrt(np.nanmean(r[:, 3:] ** 2))),
    }


def _design(session, method, output_faces):
    """Offset-free counts and targets as ``calibrate`` uses them: list of ``(faces, cols, S, W)``."""
    spec = get_method(method)
    counts = np.asarray(session.counts, dtype=float)
    loaded = np.asarray(session.loaded, dtype=bool)
    free = ~loaded.any(axis=1)
    offset = counts[free].mean(axis=0)
    S = counts - offset
    targets, carries, usable, _ = block_targets(np.asarray(session.reference, float), loaded, MountGeometry(session),
                                                spec.output_frame)
    groups = []
    if spec.inputs == "own":
        for f in output_faces:
            rows = usable & (carries[:, f - 1] | free)
            cols = np.arange(6 * (f - 1), 6 * f)
            groups.append(((f,), cols, S[np.ix_(rows, cols)], targets[rows, f - 1, :]))
    else:
        idx = [f - 1 for f in output_faces]
        groups.append((tuple(output_faces), np.arange(36), S[usable], targets[usable][:, idx, :].reshape(-1, 6 * len(idx))))
    return spec, offset, groups


def plain_fit(session, method, output_faces, solver: str = "lstsq"):
    """The baseline: the same offsets and targets, then one dense NumPy solve of the affine problem.

    Parameters
    ----------
    session : CalibrationSession
        In memory.
    method : str
    output_faces : tuple of int
        Faces to output (those ``calibrate`` chose).
    solver : {"lstsq", "pinv"}
        ``numpy.linalg.lstsq([1 | S], W, rcond=None)`` or ``numpy.linalg.pinv([1 | S]) @ W``.

    Returns
    -------
    Calibration
    """
    spec, offset, groups = _design(session, method, output_faces)
    matrix = np.zeros((6 * len(output_faces), 36))
    row_of = {f: r for r, f in enumerate(output_faces)}
    for faces, cols, S, W in groups:
        S1 = np.hstack([np.ones((S.shape[0], 1)), S])  # the affine problem calibrate solves (its intercept dropped:
        X = np.linalg.lstsq(S1, W, rcond=None)[0] if solver == "lstsq" else np.linalg.pinv(S1) @ W  # evaluate re-tares)
        C = X[1:].T
        for k, f in enumerate(faces):
            matrix[6 * row_of[f] : 6 * row_of[f] + 6][:, cols] = C[6 * k : 6 * k + 6]
    return Calibration(method, matrix, output_faces, spec.output_frame, offset, session.core, session.T_core_ati,
                       meta={"method": method, "solver": f"numpy.linalg.{solver}"})


def _traced_peak_mb(fn) -> float:
    """Peak memory allocated while ``fn()`` runs (tracemalloc, which numpy reports to), MB."""
    tracemalloc.start()
    try:
        fn()
        return tracemalloc.get_traced_memory()[1] / 1e6
    finally:
        tracemalloc.stop()


# ---------------------------------------------------------------- subprocess tasks
def task_generate(jobs) -> dict:
    """Write simulated session files: ``jobs`` = list of ``[path, flange, connected_face, n, seed]``."""
    out = []
    for path, flange, face, n, seed in jobs:
        t0 = time.perf_counter()
        write_session_file(path, flange, face, n, seed)
        out.append({"path": path, "flange": flange, "n": n, "seconds": time.perf_counter() - t0,
                    "file_MB": os.path.getsize(path) / 1e6})
    return {"generated": out}


def task_memory(k, train, test, methods, repeat=3) -> dict:
    """In-memory fits of every method at size k, with the NumPy baselines and the cores."""
    sessions = {fl: CalibrationSession.load(p) for fl, p in train.items()}
    tests = {fl: CalibrationSession.load(p) for fl, p in test.items()}
    rows = []
    for method in methods:
        flange = MOUNT_OF_METHOD[method][0]
        s, te = sessions[flange], tests[flange]
        budget = 20.0
        t_pito, cal = best_time(lambda: calibrate(s, method, model="linear"), repeat, budget)
        t_lstsq, cal_l = best_time(lambda: plain_fit(s, method, cal.output_faces, "lstsq"), repeat, budget)
        t_pinv, cal_p = best_time(lambda: plain_fit(s, method, cal.output_faces, "pinv"), repeat, budget)
        row = {"method": method, "k": len(s), "mode": "memory", "fit_s": t_pito, "lstsq_fit_s": t_lstsq,
               "pinv_fit_s": t_pinv, "time_ratio_lstsq": t_pito / t_lstsq, "time_ratio_pinv": t_pito / t_pinv}
        for name, c in (("", cal), ("lstsq_", cal_l), ("pinv_", cal_p)):
            for key, v in rmse_summary(evaluate(c, te)).items():
                row[name + key] = v
        # memory the fit allocates beyond its input (numpy reports to tracemalloc), pito vs lstsq
        row["fit_alloc_MB"] = _traced_peak_mb(lambda: calibrate(s, method, model="linear"))
        row["lstsq_fit_alloc_MB"] = _traced_peak_mb(lambda: plain_fit(s, method, cal.output_faces, "lstsq"))
        row["alloc_ratio_lstsq"] = row["fit_alloc_MB"] / row["lstsq_fit_alloc_MB"]
        row["rmse_ratio_lstsq"] = row["rmse_force_N"] / row["lstsq_rmse_force_N"]
        row["rmse_ratio_pinv"] = row["rmse_force_N"] / row["pinv_rmse_force_N"]
        row["rmse_torque_ratio_lstsq"] = row["rmse_torque_Nm"] / row["lstsq_rmse_torque_Nm"]
        # the least-squares cores alone, on the same S and W (methods fitting all 36 gauges at once)
        _, _, groups = _design(s, method, cal.output_faces)
        if len(groups) == 1:
            _, _, S, W = groups[0]

            def core():  # the fit's core: Gram of [1 | S | W] by blocks, Cholesky-QR; Householder QR if in doubt
                p = S.shape[1] + 1
                G = np.zeros((p + W.shape[1],) * 2)
                for a in range(0, S.shape[0], 65536):
                    Z = np.hstack([np.ones((min(65536, S.shape[0] - a), 1)), S[a : a + 65536], W[a : a + 65536]])
                    G += Z.T @ Z
                acc = GramQR(G[:p, :p], G[:p, p:], G[p:, p:], S.shape[0])
                if acc.trouble() is not None:
                    acc = StreamedQR(p, W.shape[1])
                    acc.add(np.hstack([np.ones((S.shape[0], 1)), S]), W)
                return acc.solve()

            t_core, _ = best_time(core, repeat, budget)
            S1 = np.hstack([np.ones((S.shape[0], 1)), S])  # the same affine problem
            t_core_l, _ = best_time(lambda: np.linalg.lstsq(S1, W, rcond=None), repeat, budget)
            row.update({"core_s": t_core, "lstsq_core_s": t_core_l, "core_time_ratio_lstsq": t_core / t_core_l,
                        "core_rows": int(S.shape[0]), "core_cols": f"{S.shape[1]}x{W.shape[1]}"})
        row.update(_model_choice_row(s, te, method, cal, t_pito, repeat, budget))
        rows.append(row)
    _spread_rounds(rows, sessions, repeat)
    return {"rows": rows}


def _spread_rounds(rows, sessions, repeat) -> None:
    """Time the linear fit and ``lstsq`` again in ``repeat`` rounds that visit every method in turn, and keep
    each one's best of both passes (with the ratios made from them). This VM's busy spells last seconds: back
    to back, 21 fits of 50 ms can all fall in one (``face_to_face`` 73.5 ms in one bench run, 48.6 ms in the
    same task run by hand a minute later); spread over the run, some fall outside."""
    for _ in range(repeat):
        for row in rows:
            method = row["method"]
            s = sessions[MOUNT_OF_METHOD[method][0]]
            t, cal = best_time(lambda: calibrate(s, method, model="linear"), 1)
            t_l, _ = best_time(lambda: plain_fit(s, method, cal.output_faces, "lstsq"), 1)
            row["fit_s"], row["lstsq_fit_s"] = min(row["fit_s"], t), min(row["lstsq_fit_s"], t_l)
    for row in rows:
        row["time_ratio_lstsq"] = row["fit_s"] / row["lstsq_fit_s"]
        row["time_ratio_pinv"] = row["fit_s"] / row["pinv_fit_s"]
        row["auto_time_ratio_linear"] = row["auto_fit_s"] / row["fit_s"]


def _model_choice_row(s, te, method, cal_lin, t_lin, repeat, budget) -> dict:
    """The default (model chosen by cross-validation) beside the linear fit: RMSE and fit-time ratios, coverage."""
    t_auto, cal = best_time(lambda: calibrate(s, method), repeat, budget)
    lin, auto = rmse_summary(evaluate(cal_lin, te)), rmse_summary(evaluate(cal, te))
    return {"model": cal.model.name, "auto_fit_s": t_auto, "auto_time_ratio_linear": t_auto / t_lin,
            "auto_rmse_force_N": auto["rmse_force_N"], "auto_rmse_torque_Nm": auto["rmse_torque_Nm"],
            "auto_force_ratio_linear": auto["rmse_force_N"] / lin["rmse_force_N"],
            "auto_torque_ratio_linear": auto["rmse_torque_Nm"] / lin["rmse_torque_Nm"],
            "coverage95": interval_coverage(cal, te), "coverage95_linear": interval_coverage(cal_lin, te)}


def interval_coverage(cal, session) -> dict:
    """Fraction of single-face samples whose target lies within the nominal 95 % interval, per face and axis.

    Targets come from the session's reference: the bench's simulated reference is noise-free
    (``_data.py``), so they are the true wrench; a noisy reference would make the figure a
    lower bound. Returns ``min``, ``median``, ``max`` over
    faces and axes, and ``per_face`` (6 × 6, NaN where no output); with 200 samples at rest or
    more, ``rest_min``, ``rest_max``: the same at rest (true wrench 0), tared on the first half of
    them and scored on the second.
    """
    counts = np.asarray(session.counts, dtype=float)
    loaded = np.asarray(session.loaded, dtype=bool)
    tared = cal.tare(counts[~loaded.any(axis=1)])
    T, carries, usable, _ = block_targets(np.asarray(session.reference, float), loaded, MountGeometry(session), "face")
    W, cov = tared.wrenches(counts[usable], return_cov=True)
    sd = np.sqrt(np.clip(np.diagonal(cov, axis1=-2, axis2=-1), 0, None))
    hit = np.abs(W - T[usable]) <= 1.959964 * sd
    single = loaded[usable].sum(axis=1) == 1
    per = np.where(cal.has_output[:, None], hit[single].mean(axis=0), np.nan)
    v = per[np.isfinite(per)]
    out = {"min": float(v.min()), "median": float(np.median(v)), "max": float(v.max()), "per_face": per.tolist()}
    rest = np.flatnonzero(~loaded.any(axis=1))
    if rest.size >= 200:  # at rest: tared on the first half, scored on the second (the true wrench is 0)
        W, cov = cal.tare(counts[rest[: rest.size // 2]]).wrenches(counts[rest[rest.size // 2 :]], return_cov=True)
        sd = np.sqrt(np.clip(np.diagonal(cov, axis1=-2, axis2=-1), 0, None))
        r = (np.abs(W) <= 1.959964 * sd).mean(axis=0)[cal.has_output]
        out.update(rest_min=float(r.min()), rest_max=float(r.max()))
    return out


def task_stream(path, method, test_path, block_size=65536, model="auto") -> dict:
    """One streamed fit from a session file (lazy), alone in its process: time and memory."""
    session = CalibrationSession.load(path, lazy=True)
    rss0 = _current_rss_mb()
    t0 = time.perf_counter()
    cal = calibrate(session, method, block_size=block_size, model=model)
    dt = time.perf_counter() - t0
    peak = peak_rss_mb()
    row = {"method": method, "k": len(session), "mode": "streamed", "model": model, "fit_s": dt, "rss_before_MB": rss0,
           "fit_peak_rss_MB": peak, "fit_extra_MB": peak - rss0, "block_size": block_size}
    row.update(rmse_summary(evaluate(cal, CalibrationSession.load(test_path))))
    # baseline: one bare pass over the file (HDF5 read + gzip inflate, float conversion)
    t0 = time.perf_counter()
    for _ in session.iter_blocks(block_size):
        pass
    row["read_pass_s"] = time.perf_counter() - t0
    row["ratio_read_pass"] = dt / row["read_pass_s"]
    return row


# ---------------------------------------------------------------- orchestration
def run_calibration(sizes, workdir, *, quick: bool = False, methods=METHODS, threads: int = 1,
                    n_test: int = 20_000, progress=print) -> dict:
    """Run the calibration benchmark (each measurement in a subprocess); returns the JSON section."""
    os.makedirs(workdir, exist_ok=True)
    mounts = sorted({MOUNT_OF_METHOD[m] for m in methods})
    test = {fl: os.path.join(workdir, f"test_{fl}.h5") for fl, _ in mounts}
    gen_rows = run_worker("cal_generate", {"jobs": [[test[fl], fl, c, n_test, 12345] for fl, c in mounts]},
                          threads=threads)["generated"]
    memory_rows, stream_rows = [], []
    for k in sizes:
        k = int(k)
        big = k > MAX_ALL_METHODS_STREAMED
        ms = [m for m in methods if not big or m == "unloaded_frame"]
        if big and not ms:
            continue
        need = sorted({MOUNT_OF_METHOD[m] for m in ms})
        train = {fl: os.path.join(workdir, f"train_{fl}_{k}.h5") for fl, _ in need}
        progress(f"calibration: generating {k:.0e} simulated samples × {len(need)} mount(s)")
        gen_rows += run_worker("cal_generate", {"jobs": [[train[fl], fl, c, k, 1] for fl, c in need]},
                               threads=threads)["generated"]
        if k <= MAX_IN_MEMORY:
            progress(f"calibration: in-memory fits, k = {k:.0e}")
            # best of 21 at k ≤ 10⁵, and of 21 more spread over the run (_spread_rounds): a fit of ~50 ms is
            # disturbed by any other job; the minimum is the fit's own time (the same code on this 2-CPU VM, best
            # of 7 back to back: `total` 67.3 and 69.6 ms in two runs, 47.4 ms best of 21 in a script between them)
            repeat = (2 if k < 100_000 else 1) if quick else (21 if k <= 100_000 else 1)
            r = run_worker("cal_memory", {"k": k, "train": train, "test": {fl: test[fl] for fl in train},
                                          "methods": list(ms), "repeat": repeat}, threads=threads)
            for row in r["rows"]:
                row["peak_rss_MB"] = r["peak_rss_mb"]
            memory_rows += r["rows"]
        stream_methods = ms if not quick else [m for m in ms if m == "unloaded_frame"]
        for m in stream_methods:
            progress(f"calibration: streamed fit from file, {m}, k = {k:.0e}")
            fl = MOUNT_OF_METHOD[m][0]
            for model in ("linear", "auto"):  # the papers' fit, and the default (model chosen by cross-validation)
                row = run_worker("cal_stream", {"path": train[fl], "method": m, "test_path": test[fl], "model": model},
                                 threads=threads)
                row["peak_rss_MB"] = row.pop("peak_rss_mb")
                stream_rows.append(row)
        for p in train.values():
            os.remove(p)
    mem_by = {(r["method"], r["k"]): r for r in memory_rows}
    for row in stream_rows:
        ref = mem_by.get((row["method"], row["k"]))
        if ref is not None:
            row["time_ratio_memory"] = row["fit_s"] / ref["fit_s"]
            row["time_ratio_lstsq"] = row["fit_s"] / ref["lstsq_fit_s"]
            row["rmse_ratio_lstsq"] = row["rmse_force_N"] / ref["lstsq_rmse_force_N"]
    for p in test.values():
        os.remove(p)
    return {
        "data": "simulated (pito_core.sim.VirtualCube seed 0; loads uniform ±15 N, ±0.1 N·m, one face at a time)",
        "threads": threads,
        "n_test": n_test,
        "memory": memory_rows,
        "streamed": stream_rows,
        "generation": gen_rows,
    }


# ---------------------------------------------------------------- default vs plain LS on random cubes
def task_random_cubes(n_cubes, k_choices, seed=0, prior=False) -> dict:
    """Held-out RMSE of ``calibrate`` (defaults) over the plain affine fit (``_baseline``), on random cubes, per method.

    Cubes from ``pito_core.sim.random_sensor`` (condition 1..10³, coupling 0–10 %, noise
    0.5–5 counts, offsets ±3·10⁷), every connected face in turn, 50–500 tare samples;
    held-out single-face and squeeze loads (pairs of faces) on the same mount; truth =
    the simulated face wrenches. With ``prior``, also ``prior="own_gauge"`` where it applies.
    """
    rng = np.random.default_rng(seed)
    rows = []
    for method in METHODS:
        flange = MOUNT_OF_METHOD[method][0]
        ratios = {key: [] for key in ("force", "torque", "prior_force", "prior_torque")}
        t_fit = 0.0
        for i in range(int(n_cubes)):
            face = 1 + i % 6
            sensor = random_sensor(int(rng.integers(2**31)), condition=(1.0, 10 ** rng.uniform(0, 3)),
                                   coupling=(0.0, rng.uniform(0, 0.1)), noise=tuple(sorted(rng.uniform(0.5, 5, 2))),
                                   offset=10 ** rng.uniform(0, np.log10(3e7)))
            faces = [f for f in range(1, 7) if f != face] if method == "unloaded_frame" else None
            k = int(rng.choice(k_choices))
            train, _ = random_sensor_session(sensor, flange, face, k, n_tare=int(rng.integers(50, 501)), faces=faces,
                                             seed=1)
            loadable = faces or [f for f in range(1, 7) if not (flange == "frame" and f == face)]
            pairs = [(loadable[j], loadable[(j + 1) % len(loadable)]) for j in range(len(loadable))]
            test, truth = random_sensor_session(sensor, flange, face, 500, n_tare=20, faces=faces, seed=2,
                                                squeeze_pairs=pairs)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                t0 = time.perf_counter()
                cal = calibrate(train, method)
                t_fit += time.perf_counter() - t0
                cal_p = calibrate(train, method, prior="own_gauge") if prior and method != "face_to_face" else None
            Wp = plain_affine_lstsq(train, method, cal.output_faces)(test.counts)
            n_loaded = test.loaded.sum(axis=1)
            for rows_k in (n_loaded == 1, n_loaded == 2):
                mask = test.loaded & rows_k[:, None] & cal.has_output[None]
                for name, c in (("", cal), ("prior_", cal_p)):
                    if c is None:
                        continue
                    e = (c.wrenches(test.counts) - truth)[mask]
                    ep = (Wp - truth)[mask]
                    ratios[name + "force"].append(np.sqrt(np.mean(e[:, :3] ** 2) / np.mean(ep[:, :3] ** 2)))
                    ratios[name + "torque"].append(np.sqrt(np.mean(e[:, 3:] ** 2) / np.mean(ep[:, 3:] ** 2)))
        row = {"method": method, "flange": flange, "n_cubes": int(n_cubes), "n_cases": len(ratios["force"]),
               "k_per_face": [int(k) for k in k_choices], "fit_s_total": t_fit}
        for key, v in ratios.items():
            if v:
                row[f"{key}_ratio_worst"] = float(np.max(v))
                row[f"{key}_ratio_median"] = float(np.median(v))
        rows.append(row)
    return {"rows": rows}


def random_cube_ratios(quick: bool = False, threads: int = 1, progress=print) -> dict:
    """The section ``calibration.random_cubes`` of ``pito bench`` (in a subprocess)."""
    n = 6 if quick else 24
    k_choices = [200, 1000] if quick else [200, 1000, 5000, 20000]
    progress(f"calibration: default vs plain least squares on {n} random cubes per method")
    r = run_worker("cal_random", {"n_cubes": n, "k_choices": k_choices, "seed": 0, "prior": True}, threads=threads)
    return {"data": "simulated: pito_core.sim.random_sensor (not the structured VirtualCube)", "rows": r["rows"]}


# ---------------------------------------------------------------- hysteresis trial (issue 25, item 3)
def hysteresis_trial(taus=(20, 100, 500), k: int = 3000, seed: int = 1) -> list[dict]:
    """Cross-validated gain of giving each face's fit the recent past of its gauges.

    On a simulated ``frame_hole`` session of ``pito_core.sim.VirtualCube`` (screw-joint play:
    the counts depend on the load's history), each face's own-gauge fit gets 6 more
    channels ``s − EMA_τ(s)`` (the counts less their exponential moving average over τ
    samples). ``fit_sensor`` scores both by cross-validation over loading segments (held-out
    gestures). Returns, per τ, the median over faces of the held-out score with / without
    the channels, for the linear and the polynomial model (< 1: the recent past helps).
    """
    s = simulate_calibration("frame_hole", 6, k=k, seed=seed, model=VirtualCube(seed=0))
    c, L = np.asarray(s.counts, float), np.asarray(s.loaded)
    T, carries, usable, _ = block_targets(np.asarray(s.reference, float), L, MountGeometry(s), "face")
    g = segment_ids(L)
    out = []
    for tau in taus:
        a = 1.0 / tau
        recent = c - (lfilter([a], [1, -(1 - a)], c - c[0], axis=0) + c[0])
        r = []
        for f in range(1, 7):
            rows = usable & (carries[:, f - 1] | ~L.any(axis=1))
            cols = slice(6 * (f - 1), 6 * f)
            base = fit_sensor(c[rows][:, cols], T[rows, f - 1], g[rows]).choice.cv_score
            hyst = fit_sensor(np.hstack([c[rows][:, cols], recent[rows][:, cols]]), T[rows, f - 1], g[rows]).choice.cv_score
            r.append((hyst["linear"] / base["linear"], hyst["poly"] / base["poly"]))
        r = np.array(r)
        out.append({"tau_samples": tau, "linear_ratio": float(np.median(r[:, 0])), "poly_ratio": float(np.median(r[:, 1]))})
    return out


#: Cubes of the coverage study (``_cubes.py``): (form, coupling, nonlinearity at full scale).
COVERAGE_CUBES = (("linear", 0.02, 0.0), ("linear", 0.10, 0.0), ("saturation", 0.05, 0.1), ("hub", 0.05, 0.1))
#: Reference noise levels of the coverage study (fraction of full scale): exact, and the tare's force limit.
COVERAGE_REFERENCE_NOISE = (0.0, 0.0033)


def task_coverage_cubes(k, draws, seed=1) -> dict:
    """Nominal 95 % intervals against the TRUE face wrench on the bench's own cubes (SIMULATED, ``_cubes.py``).

    Each method is fitted ``draws`` times (2000 samples at rest, as the wizard's 2 s tare) on single-face
    loads and scored on a later session of its own, re-tared on its own samples at rest (single-face
    loads): the share of samples inside ``W ± 1.96 σ``, per face and axis, pooled over the draws; ``se``
    is the standard error of the pooled figure over the draws (each draw's pooled share; a session's
    samples are not independent, so the binomial ``√(0.95 · 0.05 / n)`` over them understates it). One
    later session shared by every draw made a face axis's figure that session's: `face_to_face` face 3
    ``tz`` 90.2 / 93.8 / 95.9 % on three of them (docs/calibration/coverage.md).

    The pooled share mixes the faces that carry the load with those that carry nothing (five in six
    samples of a face): ``carrying`` and ``free`` are the shares over each kind, ``rms_z_carrying`` and
    ``rms_z_free`` the RMS of the error over its predicted standard deviation (1: intervals as wide as the
    errors; much below 1: too wide).
    """
    flanges = {"face_to_face": "frame_hole", "quasi_total": "frame", "total": "face", "loaded_frame": "frame_hole",
               "unloaded_frame": "face"}
    rows = []
    for form, coupling, level in COVERAGE_CUBES:
        cube = BenchCube(form, coupling, level, seed=0)
        for noise in COVERAGE_REFERENCE_NOISE:
            for method, fl in flanges.items():
                c = 6
                faces = [f for f in range(1, 7) if not ((fl == "frame" or method == "unloaded_frame") and f == c)]
                hits = n = 0
                per_draw = []
                split = np.zeros((2, 3))  # carrying, free: samples inside, samples, sum of z²
                for d in range(draws):  # each draw its own training and later session
                    train, _ = cube_session(cube, fl, c, faces, k, n_rest=2000, seed=seed + 31 * d,
                                            reference_noise=noise)
                    test, F = cube_session(cube, fl, c, faces, max(k // 2, 300), n_rest=1000,
                                           seed=seed + 500 + 31 * d, offset_shift=50.0)
                    ld = test.loaded.any(axis=1)
                    with warnings.catch_warnings():
                        warnings.simplefilter("ignore")
                        cal = calibrate(train, method).tare(test.counts[~ld])
                    W, cov = cal.wrenches(test.counts[ld], return_cov=True)
                    sd = np.sqrt(np.diagonal(cov, axis1=-2, axis2=-1))
                    inside = np.abs(W - F[ld]) <= 1.959964 * sd
                    z2 = np.divide((W - F[ld]) ** 2, sd**2, out=np.full(sd.shape, np.inf), where=sd > 0)
                    hits, n = hits + inside.sum(axis=0), n + ld.sum()
                    # a face carries where its true wrench is not zero (a face flange's connected face: every load)
                    carries = np.broadcast_to(np.any(F[ld] != 0, axis=2)[:, :, None], inside.shape)
                    for j, kind in enumerate((carries, ~carries)):
                        on = kind & cal.has_output[None, :, None]
                        split[j] += inside[on].sum(), on.sum(), z2[on].sum()
                    per_draw.append(float(inside.mean(axis=0)[cal.has_output].mean()))
                cover = (hits / n)[cal.has_output]
                rows.append({"cube": f"{form} {coupling:.0%}", "method": method, "reference_noise": noise,
                             "model": cal.model.name, "pooled": float(cover.mean()), "min": float(cover.min()),
                             "max": float(cover.max()), "out_of_93_97": int(((cover < 0.93) | (cover > 0.97)).sum()),
                             "se": float(np.std(per_draw, ddof=1) / np.sqrt(draws)) if draws > 1 else float("nan"),
                             "n_samples": int(n),
                             "n_axes": int(cover.size), "per_face_axis": np.where(cal.has_output[:, None],
                                                                                  hits / n, np.nan).tolist(),
                             **{f"{key}{kind}": float(v) for kind, (a, m, z) in zip(("carrying", "free"), split)
                                for key, v in (("", a / m if m else np.nan), ("rms_z_", np.sqrt(z / m) if m else np.nan))}})
    return {"rows": rows}


def coverage_cubes(quick: bool = False, threads: int = 1, progress=print) -> dict:
    """The section ``calibration.coverage_cubes`` of ``pito bench`` (in a subprocess)."""
    k, draws = (1000, 2) if quick else (2000, 8)
    progress(f"calibration: interval coverage on the bench's own cubes, k = {k} per face, {draws} draws")
    r = run_worker("cal_coverage_cubes", {"k": k, "draws": draws}, threads=threads)
    return {"data": "SIMULATED: pito_bench._cubes (independent of pito_core.sim)", "k": k, "draws": draws,
            "rows": r["rows"]}


def coverage_cubes_table(cc) -> tuple[str, list, list]:
    """``(title, header, rows)`` of the coverage study for the text report."""
    rows = [[r["cube"], r["method"], f"{100 * r['reference_noise']:.2f}", r["model"], f"{100 * r['pooled']:.1f}",
             "" if np.isnan(r.get("se", np.nan)) else f"{100 * r['se']:.2f}",
             f"{100 * r['min']:.1f}", f"{100 * r['max']:.1f}", f"{r['out_of_93_97']}/{r['n_axes']}",
             *(f"{100 * r.get(k, np.nan):.1f}" for k in ("carrying", "free")),
             *(f"{r.get(k, np.nan):.2f}" for k in ("rms_z_carrying", "rms_z_free"))] for r in cc["rows"]]
    title = (f"Calibration intervals, nominal 95 %, against the true face wrench ({cc['data']}; {cc['draws']} "
             f"calibrations pooled, later session re-tared; % of samples inside, per face and axis; ± its "
             f"standard error over the draws; carrying / free: over the faces that carry the load / carry "
             f"nothing; RMS z: RMS of error / predicted standard deviation, 1 when as wide as the errors)")
    return title, ["cube", "method", "ref noise %FS", "model", "pooled %", "±", "min %", "max %",
                   "axes outside 93-97", "carrying %", "free %", "RMS z carrying", "RMS z free"], rows


def coverage_faces_table(cc) -> tuple[str, list, list]:
    """``(title, header, rows)``: the coverage study per method, face and axis, pooled over its cubes
    and reference noise levels, with the lowest and highest row (cube and noise level) beside it."""
    axes = ("fx", "fy", "fz", "tx", "ty", "tz")
    rows = []
    for method in dict.fromkeys(r["method"] for r in cc["rows"]):
        per = np.array([r["per_face_axis"] for r in cc["rows"] if r["method"] == method], dtype=float)  # (rows, 6, 6)
        for f in range(6):
            if np.all(np.isnan(per[:, f])):
                continue
            rows.append([method, str(f + 1)] + [f"{100 * np.nanmean(per[:, f, a]):.1f} ({100 * np.nanmin(per[:, f, a]):.0f}-"
                                                f"{100 * np.nanmax(per[:, f, a]):.0f})" for a in range(6)])
    title = (f"Calibration intervals per face and axis, nominal 95 % ({cc['data']}): % inside, the mean over the "
             "cubes and reference noise levels (lowest-highest)")
    return title, ["method", "face", *axes], rows

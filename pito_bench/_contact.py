"""Contact benchmark: solves per second and RMS error against the Cramér–Rao bound.

Per surface (plane, sphere, ellipsoid, a 5,000-facet mesh) and per scenario:

- ``soft``: soft-finger contacts, force within 40° of the inward normal, torsion up
  to ±5 mN·m, solved in closed form (``solve``);
- ``near_tangent``: the same with the force 80–85° from the normal (nearly tangent);
- ``point``: exact point contacts (τ = 0), solved with ``point_contact=True`` and the
  true noise covariance (weighted least squares);

and per wrench noise level (Gaussian, independent per axis). The error figure is the RMS
distance between estimated and true contact points over the valid estimates, divided by
the RMS bound ``sqrt(mean trace(CRB))`` at the true contacts (``contact_crb``): 1.00 is
the best any unbiased estimator can do (on planes and meshes none has a finite variance:
docs/contact.md), with a 95 % percentile-bootstrap interval over the samples. Side by side, the same model solved per sample by
``scipy.optimize.least_squares`` (unknowns: chart coordinates of the point on the patch,
the force, the torsion; whitened residual; Levenberg–Marquardt from the patch apex, with
restarts when that does not end on a pushing contact) on a
subset of the same samples (no baseline on the mesh: it has no smooth chart). Speeds are on batches of ``n_speed`` wrenches, one thread, every mode called twice per round and the
second call timed (CPU time of the one-thread worker), the median of ``repeat`` rounds; the solver rows run
without the single-contact test (``single_contact=False``). The test has two rows of its own (with its
default noise): ``solve`` with it (the decision; ``single_contact_p`` left unread, so never computed) and
the same with the p-values read; each gives ``test_cost_ratio``, the median over the rounds of (test on −
test off) per solve, same wrenches, same round, over the median bare solve. On the analytic
surfaces the yardstick is the same model's closed form in plain numpy
(``pito_bench._baseline.plain_contact``, on the same wrench array): ``speed_ratio_plain``.
"""

from __future__ import annotations

import time

import numpy as np
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from pito_core.contact import Ellipsoid, MeshSurface, Plane, Sphere, contact_crb, reason_names, solve

from ._baseline import plain_contact
from ._contact_bounds import facet_of, mesh_exact_solutions, normal_snr_split, plane_second_order_ratio, ratio_ci
from ._timing import best_time, run_worker

__all__ = ["NOISE_LEVELS", "SCENARIOS", "SURFACES", "make_surface", "sample_contacts", "run_contact"]

#: Wrench noise standard deviations: force (N), moment (N·m).
NOISE_LEVELS = {"low": (0.005, 5e-5), "mid": (0.02, 2e-4), "high": (0.1, 1e-3)}
SCENARIOS = ("soft", "near_tangent", "point")
SURFACES = ("plane", "sphere", "ellipsoid", "mesh")
#: the speed rows' yardstick (pito_bench._baseline.plain_contact)
_PLAIN = "plain numpy closed form (soft finger)"
#: the single-contact test's rows: its decision (the p-values left unread), and with the p-values read
_TEST = "soft finger + single-contact test"
_TEST_P = "soft finger + single-contact test, p-values read"


def _bump_mesh(n: int = 50, half: float = 0.025):
    """A smooth bump over the face as a height field: ``2 n²`` facets (5,000 for n = 50), m."""
    import trimesh  # deferred: ~0.1 s to load, and this module loads with `pito --help`

    g = np.linspace(-half, half, n + 1)
    X, Y = np.meshgrid(g, g)
    Z = 0.004 + 0.012 * np.exp(-(X**2 + Y**2) / (2 * 0.012**2))
    V = np.c_[X.ravel(), Y.ravel(), Z.ravel()]
    a = (np.arange(n)[:, None] * (n + 1) + np.arange(n)[None, :]).ravel()
    F = np.concatenate([np.c_[a, a + 1, a + n + 2], np.c_[a, a + n + 2, a + n + 1]])
    return trimesh.Trimesh(V, F, process=False)


def make_surface(kind: str):
    """The benchmark's patch of ``kind`` in a face frame (m), and its apex (3,)."""
    if kind == "plane":
        return Plane([0.0, 0.0, 0.004], [0.0, 0.0, 1.0])
    if kind == "sphere":
        return Sphere([0.0, 0.0, -0.01], 0.025)
    if kind == "ellipsoid":
        return Ellipsoid([0.0, 0.0, -0.005], [0.03, 0.02, 0.015], Rotation.from_euler("z", 30, degrees=True).as_matrix())
    if kind == "mesh":
        return MeshSurface(_bump_mesh())
    raise ValueError(f"kind: expected one of {SURFACES}, got {kind!r}")


def sample_contacts(surface, n: int, scenario: str, rng):
    """True contacts: ``point (n, 3)`` m, ``normal (n, 3)``, ``force (n, 3)`` N, ``torsion (n,)`` N·m."""
    kind = surface.kind
    if kind == "plane":
        c = np.c_[rng.uniform(-0.02, 0.02, (n, 2)), np.full(n, surface.point[2])]
        nrm = np.broadcast_to(surface.normal, (n, 3)).copy()
    elif kind in ("sphere", "ellipsoid"):
        q = rng.normal(size=(n, 3))
        q /= np.linalg.norm(q, axis=1, keepdims=True)
        q[:, 2] = np.abs(q[:, 2]) * 0.7 + 0.3  # the upper cap
        q /= np.linalg.norm(q, axis=1, keepdims=True)
        c = surface.center + (q * surface.semi_axes) @ surface.rotation.T
        nrm = surface.normal_at(c)
    else:
        tri = surface.mesh.triangles
        cen = tri.mean(axis=1)
        inner = np.flatnonzero(np.all(np.abs(cen[:, :2]) < 0.02, axis=1))
        k = inner[rng.integers(0, inner.size, n)]
        u = rng.random((n, 2))
        flip = u.sum(axis=1) > 1
        u[flip] = 1 - u[flip]
        c = tri[k, 0] + u[:, :1] * (tri[k, 1] - tri[k, 0]) + u[:, 1:] * (tri[k, 2] - tri[k, 0])
        nrm = surface.facet_normals[k]
    lo, hi = (80.0, 85.0) if scenario == "near_tangent" else (0.0, 40.0)
    theta = np.deg2rad(rng.uniform(lo, hi, n))
    phi = rng.uniform(0, 2 * np.pi, n)
    a = np.where(np.abs(nrm[:, :1]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]])
    t1 = np.cross(nrm, a)
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    t2 = np.cross(nrm, t1)
    d = -np.cos(theta)[:, None] * nrm + np.sin(theta)[:, None] * (np.cos(phi)[:, None] * t1 + np.sin(phi)[:, None] * t2)
    f = d * rng.uniform(1.0, 10.0, (n, 1))
    tau = np.zeros(n) if scenario == "point" else rng.uniform(-0.005, 0.005, n)
    return c, nrm, f, tau


def _wrench(c, nrm, f, tau):
    return np.c_[f, np.cross(c, f) + tau[:, None] * nrm]


def _noise_cov(level: str) -> np.ndarray:
    sf, sm = NOISE_LEVELS[level]
    return np.diag([sf**2] * 3 + [sm**2] * 3)


# ---------------------------------------------------------------- scipy baseline
def _param(surface):
    """``(u, v) -> (c (3,), n (3,))``: a chart of the patch around its apex (for the baseline)."""
    if surface.kind == "plane":
        n0 = surface.normal
        t1 = np.cross(n0, [1.0, 0, 0] if abs(n0[0]) < 0.9 else [0, 1.0, 0])
        t1 /= np.linalg.norm(t1)
        t2 = np.cross(n0, t1)
        p0 = surface.point
        return lambda u, v: (p0 + u * t1 + v * t2, n0)
    c0, a, R = surface.center, surface.semi_axes, surface.rotation

    def chart(u, v):  # gnomonic chart of the upper half (principal frame)
        q = np.array([u, v, 1.0]) / np.sqrt(u * u + v * v + 1.0)
        n = R @ (q / a)
        return c0 + R @ (a * q), n / np.linalg.norm(n)

    return chart


def scipy_solve(surface, w, cov, point_contact: bool = False):
    """Per-sample ``scipy.optimize.least_squares`` of the same model: ``(n, 3)`` points, m.

    Unknowns: chart coordinates ``(u, v)`` of the contact on the patch, the force and
    (soft finger) the torsion; residual: the whitened wrench misfit ``L (w − [f, c × f +
    τ n(c)])`` with ``LᵀL = Σ⁻¹`` (the maximum-likelihood objective). Levenberg–Marquardt
    from the patch apex with the measured force; if that does not end on a pushing
    contact (``f · n < 0``) with a misfit within the noise, from four more chart points,
    keeping the best pushing solution (NaN if none).
    """
    chart = _param(surface)
    L = np.linalg.cholesky(np.linalg.inv(cov)).T
    out = np.full((len(w), 3), np.nan)
    starts = [(0.0, 0.0), (0.8, 0.0), (-0.8, 0.0), (0.0, 0.8), (0.0, -0.8)]
    for i, wi in enumerate(w):
        def res(x):
            c, n = chart(x[0], x[1])
            f = x[2:5]
            tau = 0.0 if point_contact else x[5]
            return L @ (wi - np.r_[f, np.cross(c, f) + tau * n])

        best = None
        for u0, v0 in starts:  # multistart: keep the best pushing solution (f · n < 0)
            x0 = np.r_[u0, v0, wi[:3]] if point_contact else np.r_[u0, v0, wi[:3], 0.0]
            sol = least_squares(res, x0, method="lm")
            c, n = chart(sol.x[0], sol.x[1])
            pushing = float(sol.x[2:5] @ n) < 0
            if pushing and (best is None or sol.cost < best[0]):
                best = (sol.cost, c)
            if pushing and sol.cost < 1.0:  # within the noise: no need for other starts
                break
        if best is not None:
            out[i] = best[1]
    return out


# ---------------------------------------------------------------- subprocess task
def _error_ratio(est, c, crb_tr, ok):
    if not ok.any():
        return float("nan"), float("nan")
    err = np.sqrt(np.mean(np.sum((est[ok] - c[ok]) ** 2, axis=1)))
    bound = np.sqrt(np.mean(crb_tr[ok]))
    return float(err), float(err / bound)


def task_contact(n_speed=100_000, n_acc=20_000, n_scipy=200, surfaces=SURFACES, levels=tuple(NOISE_LEVELS),
                 scipy_levels=("mid",), repeat=7, seed=0) -> dict:
    """Speed and accuracy of ``solve`` and of the scipy baseline on every surface and scenario."""
    rng = np.random.default_rng(seed)
    speed_rows, acc_rows = [], []
    for kind in surfaces:
        surface = make_surface(kind)
        speed_rows += _speed_rows(kind, surface, n_speed, n_scipy, repeat, rng)
        acc_rows += _accuracy_rows(kind, surface, n_acc, n_scipy, levels, scipy_levels, rng)
    return {"speed": speed_rows, "accuracy": acc_rows}


def _speed_rows(kind, surface, n_speed, n_scipy, repeat, rng) -> list[dict]:
    """Solves per second of each solver mode and of the scipy baseline on ``surface`` (one row each)."""
    rows = []
    # ---- speed: one batch of n_speed noisy soft-finger wrenches (mid noise)
    c, nrm, f, tau = sample_contacts(surface, n_speed, "soft", rng)
    cov = _noise_cov("mid")
    W = _wrench(c, nrm, f, tau) + rng.normal(size=(n_speed, 6)) * np.sqrt(np.diag(cov))
    modes = {  # the solvers alone; the single-contact test's cost on its own rows
        "closed form (soft finger)": dict(single_contact=False),
        "point contact (weighted LS)": dict(point_contact=True, wrench_cov=cov, single_contact=False),
        "soft finger + CRB covariance": dict(wrench_cov=cov, single_contact=False),
        _TEST: dict(single_contact=True),
        _TEST_P: dict(single_contact=True),
    }
    sizes = {name: n_speed if kind != "mesh" and "point" not in name else max(1000, n_speed // 10) for name in modes}
    calls = {name: (lambda kw=kw, nb=sizes[name]: solve(surface, W[:nb], **kw)) for name, kw in modes.items()}
    calls[_TEST_P] = lambda nb=sizes[_TEST_P]: solve(surface, W[:nb]).single_contact_p  # the p-values read
    if kind != "mesh":  # the yardstick: the same model's closed form in plain numpy (_baseline)
        geo = (dict(point=surface.point, normal=surface.normal) if kind == "plane" else
               dict(center=surface.center, semi_axes=surface.semi_axes, rotation=surface.rotation))
        sizes[_PLAIN] = n_speed
        calls[_PLAIN] = lambda: plain_contact(kind, W[:, :3], W[:, 3:], **geo)
    times = {name: [] for name in calls}  # s per call, one per round
    for _ in range(max(1, repeat)):  # side by side: every mode twice per round (the first call after another
        # mode pays the page faults of that mode's freed memory), the second call timed
        for name, call in calls.items():
            call()
            t0 = time.process_time()
            call()
            times[name].append(time.process_time() - t0)
    best = {name: float(np.median(t)) for name, t in times.items()}  # the median round (name kept: the timing)
    rates = {name: sizes[name] / best[name] for name in calls}
    if kind != "mesh":
        ns = max(5, n_scipy // 4)
        t0 = time.perf_counter()
        scipy_solve(surface, W[:ns], cov)
        rates["scipy least_squares (soft finger)"] = ns / (time.perf_counter() - t0)
        t0 = time.perf_counter()
        scipy_solve(surface, W[:ns], cov, point_contact=True)
        rates["scipy least_squares (point contact)"] = ns / (time.perf_counter() - t0)
    per = {name: np.asarray(t) / sizes[name] for name, t in times.items()}  # s per solve, round by round
    solve_s = float(np.median(per["closed form (soft finger)"]))  # test off
    for name, r in rates.items():
        model = "point contact" if "point" in name else "soft finger"
        base = rates.get(f"scipy least_squares ({model})", float("nan"))
        row = {"surface": kind, "solver": name, "solves_per_s": r, "speed_ratio_scipy": r / base,
               "speed_ratio_plain": r / rates.get(_PLAIN, float("nan")),
               "batch": sizes.get(name, max(5, n_scipy // 4))}
        if name in (_TEST, _TEST_P):  # the test's own cost over the bare solve's: test on minus test off, the
            # same wrenches, each round's pair, the median of the rounds
            row["test_cost_ratio"] = float(np.median(per[name] - per["closed form (soft finger)"])) / solve_s
            row["rounds"] = len(per[name])
        rows.append(row)
    return rows


def _accuracy_rows(kind, surface, n_acc, n_scipy, levels, scipy_levels, rng) -> list[dict]:
    """Point and force error against the CRB on ``surface``, one row per scenario and noise level."""
    rows = []
    # ---- accuracy: every scenario and noise level
    for scenario in SCENARIOS:
        pc = scenario == "point"
        c, nrm, f, tau = sample_contacts(surface, n_acc, scenario, rng)
        w0 = _wrench(c, nrm, f, tau)
        for level in levels:
            cov = _noise_cov(level)
            w = w0 + rng.normal(size=w0.shape) * np.sqrt(np.diag(cov))
            est = solve(surface, w, point_contact=pc, wrench_cov=cov)
            crb = contact_crb(surface, c, f, cov, torsion=tau, normal=nrm, point_contact=pc)
            crb_tr = np.trace(crb.point_cov, axis1=1, axis2=2)
            ok = est.valid & np.isfinite(crb_tr)
            err, ratio = _error_ratio(est.point, c, crb_tr, ok)
            ci = ratio_ci(np.sum((est.point[ok] - c[ok]) ** 2, axis=1), crb_tr[ok])
            ferr = np.sqrt(np.mean(np.sum((est.force[ok] - f[ok]) ** 2, axis=1))) if ok.any() else np.nan
            fbound = np.sqrt(np.mean(np.trace(crb.force_cov, axis1=1, axis2=2)[ok])) if ok.any() else np.nan
            row = {"surface": kind, "scenario": scenario, "noise": level,
                   "sigma_force_N": NOISE_LEVELS[level][0], "sigma_moment_Nm": NOISE_LEVELS[level][1],
                   "n": n_acc, "valid_fraction": float(est.valid.mean()),
                   "rms_point_error_m": err, "crb_rms_m": float(np.sqrt(np.mean(crb_tr[ok]))) if ok.any() else np.nan,
                   "crb_ratio": ratio, "crb_ratio_ci": ci, "force_crb_ratio": float(ferr / fbound),
                   "flagged_fraction": float(1.0 - est.single_contact.mean()),
                   "flag_reason": _main_reason(est)}
            est.noise = w - w0  # for _beyond_crb
            row.update(_beyond_crb(surface, scenario, c, f, w0, est, crb, nrm, cov, ok))
            if kind != "mesh" and level in scipy_levels:
                k = min(n_scipy, n_acc)
                sc = scipy_solve(surface, w[:k], cov, point_contact=pc)
                okk = np.isfinite(crb_tr[:k]) & np.isfinite(sc).all(axis=1)
                e_s, r_s = _error_ratio(sc, c[:k], crb_tr[:k], okk)
                e_p, r_p = _error_ratio(est.point[:k], c[:k], crb_tr[:k], est.valid[:k] & okk)
                row.update({"scipy_n": k, "scipy_crb_ratio": r_s, "scipy_valid_fraction": float(okk.mean()), "pito_crb_ratio_same_subset": r_p,
                            "error_ratio_scipy": e_p / e_s if e_s > 0 else float("nan")})
            rows.append(row)
    return rows


def _beyond_crb(surface, scenario, c, f, w0, est, crb, nrm, cov, ok, n_mesh=5000) -> dict:
    """Where the bound is out of reach (``_contact_bounds``): the share of samples whose normal force
    is within 5 σ of its noise and the error ratio on the others; on the mesh, the share of samples
    with two exact solutions (noise-free or noisy), the error ratio on the others, and among those the
    share whose estimate lies on another facet than the true contact's (where the facet's bound does
    not apply)."""

    crb_tr = np.trace(crb.point_cov, axis1=1, axis2=2)
    out = normal_snr_split(est.point, c, f, nrm, crb_tr, ok, float(np.sqrt(cov[2, 2])))
    if surface.kind == "plane" and scenario != "point":  # the maximum-likelihood estimate's own excess
        mse, bound = plane_second_order_ratio(surface, c, f, cov)
        strong = ok & (-np.einsum("ij,ij->i", f, nrm) >= 5.0 * np.sqrt(cov[2, 2]))
        out["second_order_ratio_fn_5sigma"] = float(np.sqrt(mse[strong].mean() / bound[strong].mean())) if strong.any() else float("nan")
    if surface.kind == "mesh" and scenario != "point":
        k = min(n_mesh, len(c))
        one = (mesh_exact_solutions(surface, w0[:k]) <= 1)
        one_noisy = one & (mesh_exact_solutions(surface, w0[:k] + est.noise[:k]) <= 1)
        keep = ok[:k] & one_noisy
        _, r = _error_ratio(est.point[:k], c[:k], crb_tr[:k], keep)
        other = keep & (est.facet[:k] != facet_of(surface, c[:k]))
        out.update({"other_facet_fraction_unambiguous": float(other.sum() / max(keep.sum(), 1)),
                    "crb_ratio_unambiguous_ci": ratio_ci(np.sum((est.point[:k][keep] - c[:k][keep]) ** 2, axis=1), crb_tr[:k][keep]),"ambiguous_fraction": float(1.0 - one.mean()),
                    "ambiguous_fraction_noisy": float(1.0 - one_noisy.mean()), "crb_ratio_unambiguous": r})
    return out


def _main_reason(est) -> str:
    """The most common reason among flagged estimates ("" if none is flagged)."""
    bad = ~est.single_contact
    if not bad.any():
        return ""
    names, counts = np.unique(reason_names(est.single_contact_reason[bad]), return_counts=True)
    return str(names[np.argmax(counts)])


def pareto(speed_rows, acc_rows) -> list[dict]:
    """Speed-vs-error points per surface and solver, with the Pareto-optimal ones marked.

    Error: the worst CRB ratio over the scenarios and noise levels the solver handles
    (closed form: soft and near-tangent; point contact: point; scipy: at the levels run).
    """
    pts = []
    for s in speed_rows:
        kind, solver = s["surface"], s["solver"]
        if solver.startswith("soft finger +"):
            continue
        if solver.startswith("closed form"):
            rs = [a["crb_ratio"] for a in acc_rows if a["surface"] == kind and a["scenario"] != "point"]
        elif solver.startswith("point contact"):
            rs = [a["crb_ratio"] for a in acc_rows if a["surface"] == kind and a["scenario"] == "point"]
        elif "soft" in solver:
            rs = [a.get("scipy_crb_ratio") for a in acc_rows if a["surface"] == kind and a["scenario"] != "point"]
        else:
            rs = [a.get("scipy_crb_ratio") for a in acc_rows if a["surface"] == kind and a["scenario"] == "point"]
        rs = [r for r in rs if r is not None and np.isfinite(r)]
        pts.append({"surface": kind, "solver": solver, "solves_per_s": s["solves_per_s"],
                    "worst_crb_ratio": max(rs) if rs else float("nan")})
    for p in pts:
        p["pareto"] = not any(
            q is not p and q["surface"] == p["surface"] and q["solves_per_s"] >= p["solves_per_s"]
            and q["worst_crb_ratio"] <= p["worst_crb_ratio"]
            and (q["solves_per_s"] > p["solves_per_s"] or q["worst_crb_ratio"] < p["worst_crb_ratio"])
            for q in pts)
    return pts


def run_contact(*, quick: bool = False, threads: int = 1, n_speed=None, n_acc=None, n_scipy=None, n_single=None,
                n_two=None, progress=print) -> dict:
    """Run the contact benchmark in a one-thread subprocess; returns the JSON section."""
    params = {"n_speed": 100_000, "n_acc": 20_000, "n_scipy": 100, "scipy_levels": list(NOISE_LEVELS)}
    if quick:
        params.update({"n_acc": 4000, "n_scipy": 20, "scipy_levels": ["mid"], "repeat": 3, "n_single": 1000,
                       "n_two": 400})
    for k, v in (("n_speed", n_speed), ("n_acc", n_acc), ("n_scipy", n_scipy), ("n_single", n_single), ("n_two", n_two)):
        if v is not None:
            params[k] = int(v)
    progress("contact: solves per second and error against the Cramér–Rao bound")
    single_params = {k: params.pop(k) for k in ("n_single", "n_two") if k in params}
    r = run_worker("contact", params, threads=threads)
    progress("contact: the single-contact test's false alarms and detection")
    r["single"] = run_worker("contact_single", single_params, threads=threads)
    return {
        "data": "simulated contacts on benchmark patches (face frame); Gaussian wrench noise",
        "threads": threads,
        "batch": params["n_speed"],
        "noise_levels": {k: {"sigma_force_N": v[0], "sigma_moment_Nm": v[1]} for k, v in NOISE_LEVELS.items()},
        "speed": r["speed"],
        "accuracy": r["accuracy"],
        "pareto": pareto(r["speed"], r["accuracy"]),
        "single": r["single"],
    }

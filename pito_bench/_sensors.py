"""Real sensors: ``fit_sensor``'s default against least squares and a quadratic baseline, held out by group.

Each data set is an ``.npz`` in a folder (``--datasets DIR``, else ``$PITO_DATASETS``, else
:data:`DEFAULT_DIR`) with ``channels (n, m)``, ``target (n, p)`` (N, N·m), ``group (n,)`` (the
loading group of each sample: a session, mass, pose or trial), the strings ``target_names``,
``units``, ``source`` and ``license``, and optionally ``level (n,)`` (a load level) and
``level_name``. The data are MEASURED on real sensors by others (see each file's ``source``); no
pito code made them.

Four fits, each trained only on the training groups of a fold:

- ``auto``: :func:`pito_core.calibration.fit_sensor` with its default model, given the training
  groups (its own cross-validation sees nothing else);
- ``ls``: plain affine least squares, ``numpy.linalg.lstsq`` — independent of pito's fit;
- ``quad``: the issue's baseline, independent of pito: the affine terms plus every product of two
  standardised channels, the products (standardised again) ridge-penalised, intercept and linear
  terms free, the strength (× the sample count, a decade grid with 0 and ∞) chosen per output by
  grouped cross-validation over the training groups only (inner folds). On few training groups
  the choice is fragile: the 3-axis cell's first session (15 rows, 3 groups of one loaded axis
  each) leaves one output unloaded in each inner fold, and its beyond-range ratio to LS moves
  from 0.77 (this grid) to 1.06 (half decades) or 1.39 (the load steps as groups);
- ``poly`` (for contrast): ``fit_sensor(..., model="poly")``, pito's correction always on at the
  ridge its own cross-validation picks — what ``auto`` would give had it chosen the correction.

Hold-out: leave-one-group-out up to :data:`MAX_LOGO` groups, else grouped K-fold
(:data:`K_FOLDS` folds, the groups dealt round-robin in a fixed shuffled order, repeated over
:data:`REPEATS` shuffles). Held-out predictions of all folds (and shuffles) are pooled: RMSE per
target column, and per kind (force: the RMS over the N columns; torque: over the N·m ones). Where
a data set has ``level`` with two or more values, "beyond range" trains on the levels up to the
median level and tests on the higher ones.
"""

from __future__ import annotations

import glob
import os
from dataclasses import dataclass

import numpy as np

__all__ = ["DEFAULT_DIR", "ENV", "Dataset", "load_dataset", "find_datasets", "outer_folds", "fit_ls", "fit_quad",
           "fit_auto", "fit_poly", "METHODS", "evaluate", "run_sensors", "sensor_tables", "SENSORS_HELP"]

#: Environment variable naming the data-set folder; then this default (relative to the working folder).
ENV = "PITO_DATASETS"
DEFAULT_DIR = "datasets"
#: Leave-one-group-out up to this many groups; grouped K-fold beyond.
MAX_LOGO = 12
K_FOLDS = 10
#: Shuffles of the grouped K-fold (the split of few groups moves the figures by several per cent).
REPEATS = 3
#: Inner folds of the quadratic baseline's ridge choice (leave-one-group-out when fewer groups).
INNER_FOLDS = 5
#: Ridge strengths of the quadratic products (relative to the sample count; 0 = unpenalised) and an
#: infinite one (= the affine fit), so the baseline can always fall back to least squares.
QUAD_ALPHAS = (0.0, 1e-6, 1e-5, 1e-4, 1e-3, 1e-2, 1e-1, 1.0, 10.0, np.inf)
#: Rows kept per data set (a stride over the samples; static loads repeat their counts).
MAX_ROWS = 30_000

SENSORS_HELP = """\
  sensors      real sensors of other kinds, measured by others (public data sets, .npz
               in --datasets DIR, else $PITO_DATASETS, else ./datasets):
               held-out RMSE (N, N·m) per target column and per force/torque of
               fit_sensor's default (auto), plain affine least squares (numpy) and a
               quadratic baseline (products of channels, ridge by inner grouped CV),
               held out by loading group (leave-one-group-out, or grouped 10-fold);
               beside them fit_sensor(model="poly") for contrast;
               ratios auto/LS and auto/min(LS, quad); and "beyond range": trained on
               the lower load levels, tested on the higher ones. Before them, SIMULATED
               sensors of four response forms (pito_bench/_sim_sensors.py; seeds 0–99,
               0–7 with --quick, 0 … N−1 with --sim-sensors N): how many force and
               torque cells auto loses to LS by more than 2 %, the worst, the median.
"""


@dataclass
class Dataset:
    name: str
    channels: np.ndarray
    target: np.ndarray
    group: np.ndarray
    target_names: list
    units: list
    source: str
    license: str
    level: np.ndarray | None = None
    level_name: str = ""
    stride: int = 1


def load_dataset(path, max_rows: int = MAX_ROWS) -> Dataset:
    """One ``.npz`` data set, every ``stride``-th row kept so at most ``max_rows`` remain."""
    with np.load(path, allow_pickle=False) as d:
        c = np.asarray(d["channels"], dtype=float)
        t = np.asarray(d["target"], dtype=float)
        g = np.asarray(d["group"]).reshape(-1)
        if c.ndim != 2 or t.ndim != 2 or not (c.shape[0] == t.shape[0] == g.shape[0]):
            raise ValueError(f"{path}: expected channels (n, m), target (n, p), group (n,), got "
                             f"{c.shape}, {t.shape}, {g.shape}")
        level = np.asarray(d["level"], dtype=float).reshape(-1) if "level" in d.files else None
        names = [str(s) for s in d["target_names"]]
        units = [str(s) for s in d["units"]]
        text = {k: str(d[k]) if k in d.files else "" for k in ("source", "license", "level_name")}
    stride = max(1, -(-c.shape[0] // max_rows))
    sl = slice(None, None, stride)
    return Dataset(os.path.splitext(os.path.basename(path))[0], c[sl], t[sl], g[sl], names, units, text["source"],
                   text["license"], None if level is None else level[sl], text["level_name"], stride)


def find_datasets(directory=None) -> tuple[str, list[str]]:
    """The folder used and its ``*.npz`` files, sorted."""
    directory = directory or os.environ.get(ENV) or DEFAULT_DIR
    return directory, sorted(glob.glob(os.path.join(directory, "*.npz")))


def _dealt(groups, k: int, seed: int = 0) -> list[np.ndarray]:
    """``k`` lists of groups: the unique groups in a fixed shuffled order, dealt round-robin."""
    u = np.unique(groups)
    u = u[np.random.default_rng(seed).permutation(u.size)]
    return [u[i::k] for i in range(k)]


def outer_folds(groups, max_logo: int = MAX_LOGO, k: int = K_FOLDS,
                repeats: int = REPEATS) -> tuple[str, list[list[np.ndarray]]]:
    """``(scheme, rounds)``, each round a list of the test groups of its folds: leave-one-group-out
    (one round), or beyond ``max_logo`` groups grouped K-fold repeated over ``repeats`` shuffles."""
    u = np.unique(groups)
    if u.size <= max_logo:
        return "leave-one-group-out", [[u[i : i + 1] for i in range(u.size)]]
    return f"grouped {k}-fold × {repeats} shuffles", [_dealt(groups, k, seed) for seed in range(repeats)]


# --- the fits: each takes training rows only and returns predict(channels) -> target ------------------

def fit_ls(X, Y, groups=None):
    """Plain affine least squares (numpy.linalg.lstsq), channels centred for conditioning."""
    mu = X.mean(axis=0)
    A = np.hstack([np.ones((X.shape[0], 1)), X - mu])
    B = np.linalg.lstsq(A, Y, rcond=None)[0]
    return lambda Z: np.hstack([np.ones((Z.shape[0], 1)), Z - mu]) @ B


def _quad_design(X, mu, sd):
    u = (X - mu) / sd
    i, j = np.triu_indices(u.shape[1])
    return np.hstack([np.ones((u.shape[0], 1)), u, u[:, i] * u[:, j]])


def _ridge_solve(G, b, n_lin: int, alpha: float, n: int):
    """Solve (G + α n P) B = b, P the identity on the product terms (columns ≥ n_lin); α = inf drops them."""
    if np.isinf(alpha):
        B = np.zeros_like(b)
        B[:n_lin] = np.linalg.lstsq(G[:n_lin, :n_lin], b[:n_lin], rcond=None)[0]
        return B
    P = np.zeros(G.shape[0])
    P[n_lin:] = alpha * n
    return np.linalg.lstsq(G + np.diag(P), b, rcond=None)[0]


def fit_quad(X, Y, groups, alphas=QUAD_ALPHAS, inner: int = INNER_FOLDS):
    """The quadratic baseline: ridge strength per output column by grouped CV over ``groups`` (training only)."""
    mu, sd = X.mean(axis=0), X.std(axis=0)
    sd = np.where(sd > 0, sd, 1.0)
    F = _quad_design(X, mu, sd)
    n_lin = 1 + X.shape[1]
    fm, fs = F[:, n_lin:].mean(axis=0), F[:, n_lin:].std(axis=0)
    fs = np.where(fs > 0, fs, 1.0)
    F[:, n_lin:] = (F[:, n_lin:] - fm) / fs  # products standardised so one α means the same for each
    u = np.unique(groups)
    folds = [u[i : i + 1] for i in range(u.size)] if u.size <= inner else _dealt(groups, inner)
    best = np.full(Y.shape[1], alphas[-1])
    if len(folds) >= 2:
        sse = np.zeros((len(alphas), Y.shape[1]))
        G, b = F.T @ F, F.T @ Y
        for test_groups in folds:
            te = np.isin(groups, test_groups)
            Gk, bk = G - F[te].T @ F[te], b - F[te].T @ Y[te]
            for a, alpha in enumerate(alphas):
                sse[a] += ((F[te] @ _ridge_solve(Gk, bk, n_lin, alpha, int((~te).sum())) - Y[te]) ** 2).sum(axis=0)
        best = np.asarray(alphas)[np.argmin(sse, axis=0)]
    G, b = F.T @ F, F.T @ Y
    B = np.empty((F.shape[1], Y.shape[1]))
    for alpha in np.unique(best):
        cols = best == alpha
        B[:, cols] = _ridge_solve(G, b[:, cols], n_lin, alpha, F.shape[0])

    def predict(Z):
        Fz = _quad_design(Z, mu, sd)
        Fz[:, n_lin:] = (Fz[:, n_lin:] - fm) / fs
        return Fz @ B
    predict.alphas = best
    predict.inner_folds = len(folds)
    return predict


def fit_auto(X, Y, groups):
    """``pito_core.calibration.fit_sensor`` with its default model, given the training groups."""
    from pito_core.calibration import fit_sensor

    fit = fit_sensor(X, Y, groups=groups)

    def predict(Z):
        return fit.predict(Z)
    ra = fit.choice.row_alpha or []
    predict.corrected_rows = sum(a is not None for a in ra) if fit.model == "poly" else 0
    sc = fit.choice.cv_score or {}
    predict.cv_ratio = sc["chosen"] / sc["linear"] if sc.get("linear") else None  # its inner CV's forecast
    predict.extension = [e for e in fit.extension_ if e]  # how each corrected output continues beyond its range
    predict.reach = fit.reach_  # up to this multiple of the range (as far as its held-out groups reached); then a fade
    return predict


def fit_poly(X, Y, groups):
    """``fit_sensor(..., model="poly")``: pito's correction always on, at its cross-validated ridge (for contrast)."""
    from pito_core.calibration import fit_sensor

    fit = fit_sensor(X, Y, groups=groups, model="poly")
    return lambda Z: fit.predict(Z)


METHODS = {"auto": fit_auto, "ls": fit_ls, "quad": fit_quad, "poly": fit_poly}


# --- evaluation -------------------------------------------------------------------------------------------

def _rmse_rows(ds: Dataset, Y, P) -> dict:
    """RMSE per target column and per kind (force: N columns, torque: N·m columns)."""
    mse = ((P - Y) ** 2).mean(axis=0)
    out = {name: float(np.sqrt(v)) for name, v in zip(ds.target_names, mse)}
    for kind, unit in (("force", "N"), ("torque", "N·m")):
        cols = [i for i, u in enumerate(ds.units) if u == unit]
        if len(cols) >= 2:
            out[kind] = float(np.sqrt(mse[cols].mean()))
    return out


def _run_split(ds: Dataset, methods, train, test) -> tuple[dict, dict]:
    """Fit each method on rows ``train`` (with their groups), predict rows ``test``."""
    preds, info = {}, {}
    X, Y, g = ds.channels[train], ds.target[train], ds.group[train]
    for name, fit in methods.items():
        p = fit(X, Y, g)
        preds[name] = p(ds.channels[test])
        info[name] = {"corrected_rows": getattr(p, "corrected_rows", None), "cv_ratio": getattr(p, "cv_ratio", None),
                      "extension": getattr(p, "extension", None), "reach": getattr(p, "reach", None),
                      "alphas": getattr(p, "alphas", None), "inner_folds": getattr(p, "inner_folds", None)}
    if "auto" in preds and "ls" in preds:  # the same dimensionless score on this split: RMSE / target std, pooled
        s = ds.target.std(axis=0)
        s = np.where(s > 0, s, 1.0)
        score = {m: np.sqrt(np.mean(((preds[m] - ds.target[test]) / s) ** 2)) for m in ("auto", "ls")}
        info["auto"]["held_out_ratio"] = float(score["auto"] / score["ls"]) if score["ls"] > 0 else None
    return preds, info


def _table(ds: Dataset, methods, Y, preds) -> list[dict]:
    per = {name: _rmse_rows(ds, Y, P) for name, P in preds.items()}
    unit = dict(zip(ds.target_names, ds.units), force="N", torque="N·m")
    rows = []
    for col in per[next(iter(per))]:
        r = {"column": col, "unit": unit[col], "rmse": {m: per[m][col] for m in per}}
        if {"auto", "ls", "quad"} <= set(per):
            ls, q, a = r["rmse"]["ls"], r["rmse"]["quad"], r["rmse"]["auto"]
            r["auto_over_ls"] = a / ls if ls > 0 else float("nan")
            r["auto_over_best"] = a / min(ls, q) if min(ls, q) > 0 else float("nan")
            r["quad_over_ls"] = q / ls if ls > 0 else float("nan")
        rows.append(r)
    return rows


def _listed(a):
    return None if a is None else [float(x) for x in a]


def evaluate(ds: Dataset, methods=None) -> dict:
    """Grouped hold-out (and, with levels, beyond range) of ``methods`` on ``ds``.

    Returns a dict with ``scheme``, ``folds`` (the train and test groups of every fold, for
    checking), ``rows`` (per column and kind: RMSE per method and the ratios), and
    ``beyond`` (the same for the level split, or None).
    """
    methods = METHODS if methods is None else methods
    scheme, rounds = outer_folds(ds.group)
    preds = {m: np.full((len(rounds),) + ds.target.shape, np.nan) for m in methods}
    folds, corrected, forecast = [], [], []
    for r, test_groups in ((r, t) for r, test_sets in enumerate(rounds) for t in test_sets):
        te = np.isin(ds.group, test_groups)
        tr = ~te
        p, info = _run_split(ds, methods, tr, te)
        for m in methods:
            preds[m][r, te] = p[m]
        folds.append({"train": np.unique(ds.group[tr]).tolist(), "test": np.unique(ds.group[te]).tolist()})
        corrected.append(info.get("auto", {}).get("corrected_rows"))
        a = info.get("auto", {})
        if a.get("corrected_rows"):
            forecast.append([a.get("cv_ratio"), a.get("held_out_ratio")])
    stacked = {m: P.reshape(-1, P.shape[-1]) for m, P in preds.items()}  # every round's held-out predictions
    Y = np.tile(ds.target, (len(rounds), 1))
    out = {"name": ds.name, "n": int(ds.channels.shape[0]), "stride": ds.stride, "m": int(ds.channels.shape[1]),
           "groups": int(np.unique(ds.group).size), "scheme": scheme, "folds": folds,
           "auto_corrected_rows": corrected, "auto_forecast": forecast, "n_outputs": int(ds.target.shape[1]),
           "source": ds.source, "license": ds.license, "rows": _table(ds, methods, Y, stacked), "beyond": None}
    if ds.level is not None and np.unique(ds.level).size >= 2:
        lv = np.unique(ds.level)
        cut = np.median(lv)
        tr, te = ds.level <= cut, ds.level > cut
        p, info = _run_split(ds, methods, tr, te)
        out["beyond"] = {"level_name": ds.level_name, "train_levels": lv[lv <= cut].tolist(),
                         "test_levels": lv[lv > cut].tolist(), "n_train": int(tr.sum()), "n_test": int(te.sum()),
                         "train_groups": np.unique(ds.group[tr]).tolist(),
                         "auto_corrected_rows": info.get("auto", {}).get("corrected_rows"),
                         "auto_extension": info.get("auto", {}).get("extension"),
                         "auto_reach": info.get("auto", {}).get("reach"),
                         "quad_alphas": _listed(info.get("quad", {}).get("alphas")),
                         "quad_inner_folds": info.get("quad", {}).get("inner_folds"),
                         "rows": _table(ds, methods, ds.target[te], p)}
    return out


def run_sensors(directory=None, progress=None, max_rows: int = MAX_ROWS) -> dict:
    """Every data set in the folder: ``{"dir", "datasets": [...]}`` or ``{"dir", "status": "skipped: ..."}``."""
    progress = progress or (lambda s: None)
    directory, paths = find_datasets(directory)
    out = {"dir": directory}
    if not paths:
        out["status"] = (f"skipped: no data sets found in {directory}; give --datasets DIR or set {ENV} (the .npz "
                         "format: pito_bench/_sensors.py)")
    else:
        results = []
        for path in paths:
            ds = load_dataset(path, max_rows)
            progress(f"sensors: {ds.name} ({ds.channels.shape[0]:,} rows × {ds.channels.shape[1]} channels, "
                     f"{np.unique(ds.group).size} groups)")
            results.append(evaluate(ds))
        out["datasets"] = results
    return out


def _fmt(x) -> str:
    return f"{x:10.4g}" if x is not None and np.isfinite(x) else f"{'—':>10s}"


def _r(x) -> str:
    return f"{x:8.2f}" if x is not None and np.isfinite(x) else f"{'—':>8s}"


def _rows_text(rows) -> list[str]:
    lines = [f"    {'column':8s} {'unit':4s} {'auto':>10s} {'LS':>10s} {'quad':>10s} {'poly':>10s} {'auto/LS':>8s} "
             f"{'auto/best':>9s} {'quad/LS':>8s} {'poly/LS':>8s}"]
    for r in rows:
        m = r["rmse"]
        poly_ls = m["poly"] / m["ls"] if m.get("poly") is not None and m.get("ls") else None
        lines.append(f"    {r['column']:8s} {r['unit']:4s} {_fmt(m.get('auto'))} {_fmt(m.get('ls'))} "
                     f"{_fmt(m.get('quad'))} {_fmt(m.get('poly'))} {_r(r.get('auto_over_ls'))}  "
                     f"{_r(r.get('auto_over_best'))} {_r(r.get('quad_over_ls'))} {_r(poly_ls)}")
    return lines


def sensor_tables(sec: dict, simulated=()) -> list[str]:
    """The sensors section as text lines; ``simulated``: the SIMULATED sensors' lines
    (``_sim_sensors.simulated_tables``), put first."""
    lines = ["SENSORS — fit_sensor on sensors of other kinds: SIMULATED response forms, then real sensors measured by "
             "others (public data sets); held-out RMSE, auto = fit_sensor default, LS = numpy lstsq, quad = ridge "
             "quadratic baseline, best = min(LS, quad), poly = fit_sensor(model='poly')"]
    lines += list(simulated)
    if "status" in sec:
        lines.append(f"  {sec['status']}")
    for d in sec.get("datasets", ()):
        n_out = d["n_outputs"]
        corr = [c for c in d["auto_corrected_rows"] if c is not None]
        rows = "all rows" if d["stride"] == 1 else f"every {d['stride']}th row"
        lines += [f"  {d['name']}: {d['n']:,} rows ({rows}) × {d['m']} channels, {d['groups']} groups, "
                  f"{d['scheme']}; auto corrected {sum(corr)}/{n_out * len(corr)} output rows over the folds",
                  f"    source {d['source']}", f"    license {d['license']}"]
        lines += _rows_text(d["rows"])
        fc = [f for f in d.get("auto_forecast", []) if None not in f]
        if fc:
            f = np.array(fc)
            lines.append(f"    on the {len(fc)} fold(s) where auto corrected: its inner CV forecast "
                         f"{np.median(f[:, 0]):.2f}× LS (median; range {f[:, 0].min():.2f}–{f[:, 0].max():.2f}), "
                         f"held out {np.median(f[:, 1]):.2f}× ({f[:, 1].min():.2f}–{f[:, 1].max():.2f}); "
                         "RMSE/std pooled over outputs")
        b = d["beyond"]
        if b:
            lines.append(f"    beyond range: trained on {b['level_name']} ≤ {max(b['train_levels']):.4g} "
                         f"({b['n_train']:,} rows), tested on {', '.join(f'{x:.4g}' for x in b['test_levels'])} "
                         f"({b['n_test']:,} rows); auto corrected {b['auto_corrected_rows']}/{n_out} output rows"
                         + (f" (beyond its range: {', '.join(sorted(set(b['auto_extension'])))} up to "
                            f"{b['auto_reach']:.2g}× the range, then a fade)" if b.get("auto_extension") else ""))
            if b.get("quad_alphas") is not None:
                alphas = ", ".join("inf" if a is None or np.isinf(a) else f"{a:.0e}" if a else "0"
                                   for a in b["quad_alphas"])  # json_safe: inf → None
                lines.append(f"    quad's ridge per output (α × sample count; inf = affine), by "
                             f"{b['quad_inner_folds']} inner folds of the training groups: {alphas}")
            lines += _rows_text(b["rows"])
    return lines

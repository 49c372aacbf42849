"""Figures (PNG, units on every axis, marked SIMULATED) and their data (CSV)."""

from __future__ import annotations

import os

import numpy as np

from ..frames import WRENCH_COMPONENTS
from ..report import new_figure, save_png, write_csv
from ._experiments import METHOD_ORDER, Results

__all__ = ["write_figures", "FIGURES"]

#: Figure files, in the summary's order: name -> (title, csv files).
FIGURES = {
    "identification.png": ("Face identification (Fig. 6): single face (forces) and squeeze (torques), unloaded_frame",
                           ("identification_single.csv", "identification_squeeze.csv")),
    "identification_loaded_frame.png": ("Face identification (Fig. 6) with the loaded-frame calibration (frame_hole mount)",
                                        ("identification_loaded_frame_single.csv", "identification_loaded_frame_squeeze.csv")),
    "comparison_forces.png": ("Comparison with the reference, forces", ("comparison.csv",)),
    "comparison_torques.png": ("Comparison with the reference, torques", ("comparison.csv",)),
    "rmse_methods.png": ("RMSE per face: the five methods", ("rmse_methods.csv",)),
    "model_choice.png": ("Held-out RMSE per method: the papers' linear fit beside the model chosen by cross-validation",
                         ("model_choice.csv",)),
    "rmse_connected_face.png": ("RMSE per connected face: loaded vs unloaded frame (single-face loads)",
                                ("rmse_connected_face.csv",)),
    "squeeze_connected_face.png": ("Squeeze resultant RMSE per connected face (Figs 11, 12, 16, 19)",
                                   ("squeeze_connected_face.csv",)),
    "table1_icn.png": ("Table I: inverse condition numbers per connected face", ("table1_inverse_condition_numbers.csv",)),
    "equilibrium.png": ("Equilibrium during a free grasp", ("equilibrium.csv",)),
    "contact_points.png": ("8-point test (8 points + centre): cube and reference sensor, realistic touch placement",
                           ("contact_points.csv",)),
}

_SIM = " [SIMULATED]"
_COLORS = {"face_to_face": "#d62728", "quasi_total": "#ff7f0e", "total": "#2ca02c", "loaded_frame": "#9467bd",
           "unloaded_frame": "#1f77b4", "unloaded_frame+frame_hole": "#17becf"}
#: The three per-connected-face calibrations.
_PER_CONNECTED = ("loaded_frame", "unloaded_frame", "unloaded_frame+frame_hole")


_SIM_NOTE = "SIMULATED data — pito_core.sim default cube"


def _save(fig, path):
    save_png(fig, path, dpi=110, note=_SIM_NOTE, tight=False)


def write_figures(res: Results, out_dir) -> list[str]:
    """Write every figure and its CSV into ``out_dir``; returns the file names written."""
    written = []
    for fn in (_identification, _identification_loaded, _comparison, _rmse_methods, _model_choice, _rmse_connected,
               _squeeze_connected,
               _table1, _equilibrium, _contact):
        written += fn(res, out_dir)
    return written


# ---------------------------------------------------------------------- model choice
def _overall(ev, a0):
    """RMS over the faces and axes ``a0..a0+2`` of an evaluation's single-face RMSE (N or N·m)."""
    r = np.asarray(ev.rmse_single, dtype=float)[:, a0 : a0 + 3]
    return float(np.sqrt(np.nanmean(r**2)))


def _model_choice(res, out):
    methods = [m for m in METHOD_ORDER if m in res.linear_evaluations]
    rows = []
    for m in methods:
        lin, ch = res.linear_evaluations[m], res.evaluations[m]
        rows.append([m, res.calibrations[m].model.name, _overall(lin, 0), _overall(ch, 0), _overall(lin, 3),
                     _overall(ch, 3)])
    write_csv(os.path.join(out, "model_choice.csv"), ["method", "model_chosen", "linear_force_rmse_N",
                                                       "chosen_force_rmse_N", "linear_torque_rmse_Nm",
                                                       "chosen_torque_rmse_Nm"], rows)
    fig, axs = new_figure(1, 2, figsize=(11, 3.9))
    x = np.arange(len(methods))
    for ax, (k, unit, what) in zip(axs, ((2, "N", "force"), (4, "N·m", "torque"))):
        ax.bar(x - 0.2, [r[k] for r in rows], 0.4, color="0.6", label="papers' linear fit")
        ax.bar(x + 0.2, [r[k + 1] for r in rows], 0.4, color="C0", label="model chosen (auto)")
        ax.set_xticks(x, [f"{r[0]}\n({r[1]})" for r in rows], fontsize=7)
        ax.set_ylabel(f"held-out {what} RMSE, single-face loads [{unit}]")
        ax.set_title(f"{what.capitalize()}s: linear vs chosen model, a later session{_SIM}", fontsize=9)
        ax.legend(fontsize=7)
    fig.tight_layout()
    _save(fig, os.path.join(out, "model_choice.png"))
    return ["model_choice.csv", "model_choice.png"]


# ---------------------------------------------------------------------- identification
def _identification(res, out, method="unloaded_frame"):
    tag = "" if method == "unloaded_frame" else f"_{method}"
    fig, axs = new_figure(2, 1, figsize=(9, 6.5))
    files = []
    for ax, kind, key, unit, thr in (
        (axs[0], "single", "force_norm", "N", 0.5),
        (axs[1], "squeeze", "torque_norm", "N·m", 0.01),
    ):
        s = res.identification_series[kind if method == "unloaded_frame" else (method, kind)]
        t, v, loaded = s["time"], s[key], s["loaded"]
        step = max(1, t.size // 4000)
        cf = s["connected_face"]
        if s.get("flange", "face") == "face":
            ax.plot(t[::step], v[::step, cf - 1], color="0.6", ls=":", lw=0.8,
                    label=f"face {cf} (connected: flange reaction)")
        for i in range(6):
            if i != cf - 1 or s.get("flange", "face") != "face":
                ax.plot(t[::step], v[::step, i], lw=0.9, color=f"C{i}", label=f"face {i + 1}")
        # shade the loaded face(s) per block
        for i in range(6):
            on = loaded[:, i]
            edges = np.flatnonzero(np.diff(np.r_[0, on.astype(int), 0]))
            for a, b in zip(edges[::2], edges[1::2]):
                ax.axvspan(t[a], t[b - 1], color=f"C{i}", alpha=0.08)
        ax.axhline(thr, color="k", ls="--", lw=0.8, label=f"threshold {thr} {unit}")
        what = "‖F‖" if key == "force_norm" else "‖T‖"
        ax.set_ylabel(f"{what} per face [{unit}]")
        ax.set_xlabel("time [s]")
        title = "single face loads, forces" if kind == "single" else "squeeze pairs, torques"
        ax.set_title(f"Face identification ({title}), {method} calibration, {s.get('flange', 'face')} mount{_SIM}",
                     fontsize=9)
        ax.legend(fontsize=7, ncol=4, loc="upper right")
        name = f"identification{tag}_{kind}.csv"
        rows = [[float(t[n])] + [float(x) for x in v[n]] + [int(x) for x in loaded[n]] for n in range(0, t.size, step)]
        write_csv(os.path.join(out, name), ["time_s"] + [f"face{i}_{key}_{'N' if unit == 'N' else 'Nm'}" for i in range(1, 7)]
                   + [f"face{i}_loaded" for i in range(1, 7)], rows)
        files.append(name)
    fig.tight_layout()
    _save(fig, os.path.join(out, f"identification{tag}.png"))
    return files + [f"identification{tag}.png"]


def _identification_loaded(res, out):
    return _identification(res, out, "loaded_frame")


# ---------------------------------------------------------------------- comparison
def _comparison(res, out):
    methods = ("face_to_face", "loaded_frame", "unloaded_frame")  # drawn in this order: best on top
    rows = []
    for m in methods:
        cmp = res.evaluations[m].comparison
        for n in range(len(cmp["kind"])):
            rows.append([m, str(cmp["kind"][n]), int(cmp["face"][n])] + [float(x) for x in cmp["reference"][n]]
                        + [float(x) for x in cmp["predicted"][n]])
    write_csv(os.path.join(out, "comparison.csv"), ["method", "kind", "face"] + [f"ref_{a}" for a in WRENCH_COMPONENTS]
               + [f"pred_{a}" for a in WRENCH_COMPONENTS], rows)
    files = ["comparison.csv"]
    for name, axes, unit in (("comparison_forces.png", (0, 1, 2), "N"), ("comparison_torques.png", (3, 4, 5), "N·m")):
        fig, axs = new_figure(1, 3, figsize=(11, 3.9))
        for ax, k in zip(axs, axes):
            lim = 0.0
            for m in methods:
                cmp = res.evaluations[m].comparison
                ok = np.isfinite(cmp["predicted"][:, k])
                ax.scatter(cmp["reference"][ok, k], cmp["predicted"][ok, k], s=2, alpha=0.4, color=_COLORS[m], label=m)
                if ok.any():
                    lim = max(lim, np.abs(cmp["reference"][ok, k]).max())
            ax.plot([-lim, lim], [-lim, lim], "k-", lw=0.7)
            ax.set_xlabel(f"reference {WRENCH_COMPONENTS[k]} [{unit}]")
            ax.set_ylabel(f"calibrated cube {WRENCH_COMPONENTS[k]} [{unit}]")
            ax.set_title(f"{WRENCH_COMPONENTS[k]}, reference frame{_SIM}", fontsize=9)
        axs[0].legend(fontsize=7, markerscale=4)
        fig.tight_layout()
        _save(fig, os.path.join(out, name))
        files.append(name)
    return files


# ---------------------------------------------------------------------- RMSE
def squeeze_rmse(ev):
    """Force RMSE (N) and torque RMSE (N·m) of the squeeze resultant, over its 3 axes each."""
    sq = ev.rmse_squeeze
    return float(np.sqrt(np.nanmean(sq[:3] ** 2))), float(np.sqrt(np.nanmean(sq[3:] ** 2)))


def _force_torque_bars(path, x, series, width, *, ylabel, title, xlabel, xticklabels=None, figsize):
    """Grouped bars, force RMSE (N) on the left and torque RMSE (N·m) on the right, saved to ``path``.

    ``series``: ``(method, force values, torque values)``, one bar per ``x`` each, centred
    as a group on ``x``; ``ylabel`` and ``title`` are formatted with ``what`` ("force" or
    "torque") and ``unit``.
    """
    fig, axs = new_figure(1, 2, figsize=figsize)
    for j, (m, f, t) in enumerate(series):
        dx = (j - (len(series) - 1) / 2) * width
        axs[0].bar(x + dx, f, width, label=m, color=_COLORS[m])
        axs[1].bar(x + dx, t, width, label=m, color=_COLORS[m])
    for ax, unit, what in ((axs[0], "N", "force"), (axs[1], "N·m", "torque")):
        ax.set_xticks(x, xticklabels)
        ax.set_xlabel(xlabel)
        ax.set_ylabel(ylabel.format(what=what, unit=unit))
        ax.set_title(title.format(what=what, unit=unit) + _SIM, fontsize=9)
    axs[0].legend(fontsize=7)
    fig.tight_layout()
    _save(fig, path)


def _rmse_methods(res, out):
    rows = []
    for m in METHOD_ORDER:
        ev = res.evaluations[m]
        for i in range(6):
            rows.append([m, i + 1, float(ev.rmse_force()[i]), float(ev.rmse_torque()[i])])
        rows.append([m, "squeeze", *squeeze_rmse(ev)])
    write_csv(os.path.join(out, "rmse_methods.csv"), ["method", "face", "rmse_force_N", "rmse_torque_Nm"], rows)
    series = [(m, [r[2] for r in rows if r[0] == m], [r[3] for r in rows if r[0] == m]) for m in METHOD_ORDER]
    _force_torque_bars(os.path.join(out, "rmse_methods.png"), np.arange(7), series, 0.8 / len(METHOD_ORDER),
                       ylabel="RMSE, {what} [{unit}]", title="{what} RMSE per face and method",
                       xlabel="loaded face (single-face loads) / squeeze resultant",
                       xticklabels=[f"face {i}" for i in range(1, 7)] + ["squeeze"], figsize=(12, 4.2))
    return ["rmse_methods.csv", "rmse_methods.png"]


def _per_connected_bars(path, rows, *, ylabel, title):
    """``rows`` = ``[connected_face, method, force, torque, ...]``: bars per connected face, one per calibration."""
    series = [(m, [r[2] for r in rows if r[1] == m], [r[3] for r in rows if r[1] == m]) for m in _PER_CONNECTED]
    _force_torque_bars(path, np.arange(1, 7), series, 0.27, ylabel=ylabel, title=title,
                       xlabel="connected face (flange)", figsize=(10, 3.8))


def _rmse_connected(res, out):
    rows = []
    for c in range(1, 7):
        for m in _PER_CONNECTED:
            _, ev = res.per_connected[(m, c)]
            rows.append([c, m, float(np.nanmean(ev.rmse_force())), float(np.nanmean(ev.rmse_torque()))])
    write_csv(os.path.join(out, "rmse_connected_face.csv"),
               ["connected_face", "method", "rmse_force_N", "rmse_torque_Nm"], rows)
    _per_connected_bars(os.path.join(out, "rmse_connected_face.png"), rows, ylabel="mean RMSE, {what} [{unit}]",
                        title="loaded vs unloaded frame, {what}")
    return ["rmse_connected_face.csv", "rmse_connected_face.png"]


def _squeeze_connected(res, out):
    rows = []
    for c in range(1, 7):
        for m in _PER_CONNECTED:
            ev = res.squeeze_per_connected[(m, c)]
            rows.append([c, m, *squeeze_rmse(ev), ev.n_squeeze])
    write_csv(os.path.join(out, "squeeze_connected_face.csv"),
               ["connected_face", "method", "squeeze_rmse_force_N", "squeeze_rmse_torque_Nm", "samples"], rows)
    _per_connected_bars(os.path.join(out, "squeeze_connected_face.png"), rows,
                        ylabel="squeeze resultant RMSE, {what} [{unit}]", title="squeeze pairs vs reference, {what}")
    return ["squeeze_connected_face.csv", "squeeze_connected_face.png"]


def table1_rows(res):
    """Per connected face ``[c, 1/cond loaded frame, unloaded frame alone, unloaded frame + frame_hole]``,
    each of the papers' linear fit (Table I's figure): a polynomial model's affine part is chosen per face and
    output group, so under a face flange alone it is not of rank 30 (1.0·10⁻⁴–7.6·10⁻⁴ where the linear fit
    has ≈ 0)."""
    rows = []
    for c in range(1, 7):
        cals = [res.per_connected[(m, c)][0] for m in ("loaded_frame", "unloaded_frame", "unloaded_frame+frame_hole")]
        rows.append([c, *(cal.linear_alternative().inverse_condition_number for cal in cals)])
    return rows


def _table1(res, out):
    rows = table1_rows(res)
    write_csv(os.path.join(out, "table1_inverse_condition_numbers.csv"),
               ["connected_face", "loaded_frame_icn", "unloaded_frame_icn", "unloaded_frame_with_frame_hole_icn"], rows)
    fig, ax = new_figure(figsize=(7, 3.8))
    x = np.arange(1, 7)
    ax.bar(x - 0.27, [r[1] for r in rows], 0.27, label="loaded_frame (36×36)", color=_COLORS["loaded_frame"])
    ax.bar(x, [max(r[2], 3.1e-5) for r in rows], 0.27, label="unloaded_frame alone (rank 30: ≈0, clipped)",
           color=_COLORS["unloaded_frame"])
    ax.bar(x + 0.27, [r[3] for r in rows], 0.27, label="unloaded_frame + frame_hole session",
           color=_COLORS["unloaded_frame+frame_hole"])
    ax.axhspan(1e-4, 1e-3, color="0.85", zorder=0, label="paper's range 10⁻⁴–10⁻³")
    ax.set_yscale("log")
    ax.set_ylim(3e-5, 1e-2)
    ax.set_xlabel("connected face (flange)")
    ax.set_ylabel("inverse condition number σmin/σmax [1]")
    ax.set_title(f"Table I: inverse condition numbers, the papers' linear fit{_SIM}", fontsize=9)
    ax.legend(fontsize=7, loc="upper center", ncol=2)
    fig.tight_layout()
    _save(fig, os.path.join(out, "table1_icn.png"))
    return ["table1_inverse_condition_numbers.csv", "table1_icn.png"]


# ---------------------------------------------------------------------- equilibrium
def _equilibrium(res, out):
    g = res.grasp
    run = g["run"]
    t = run.time - run.time[0]
    step = max(1, t.size // 3000)
    fig, axs = new_figure(2, 1, figsize=(9, 6), sharex=True)
    axs[0].plot(t[::step], g["m_a_minus_g"][::step], "k-", lw=1.2, label="truth m‖a − g‖")
    axs[0].axhline(run.weight, color="0.5", ls="--", lw=0.9, label=f"weight m g = {run.weight:.2f} N")
    for m, eq in g["methods"].items():
        net = res.grasp_net_load.get(m, "")
        axs[0].plot(t[::step], eq.force_sum_norm[::step], lw=0.8, color=_COLORS[m],
                    label=f"‖ΣF‖, {m} (net load {'measured' if net == 'measured' else 'NOT measured'})")
        axs[1].plot(t[::step], eq.torque_cog_norm[::step], lw=0.8, color=_COLORS[m], label=f"‖ΣT‖ about the cog, {m}")
    axs[1].plot(t[::step], g["truth"].torque_cog_norm[::step], "k-", lw=1.0, label="truth")
    on = run.state.on_table
    for ax in axs:
        edges = np.flatnonzero(np.diff(np.r_[0, on.astype(int), 0]))
        for a, b in zip(edges[::2], edges[1::2]):
            ax.axvspan(t[a], t[b - 1], color="0.9", zorder=0)
        ax.legend(fontsize=7, loc="upper right")
    axs[0].set_ylim(0, 2.5 * run.weight)
    tmax = max(float(np.nanpercentile(eq.torque_cog_norm[~on], 99)) for eq in g["methods"].values()) if (~on).any() else 0.1
    axs[1].set_ylim(0, max(1.5 * tmax, 0.01))
    axs[0].text(0.01, 0.97, "quasi_total has no output for face 6 (the connected face of its calibration):\n"
                "off scale while the object rests on face 6", transform=axs[0].transAxes, fontsize=7, va="top")
    axs[0].set_ylabel("‖ΣF‖ [N]")
    axs[1].set_ylabel("‖ΣT‖ about the cog [N·m]")
    axs[1].set_xlabel("time [s] (grey: object resting on the table, face 6)")
    axs[0].set_title(f"Free grasp equilibrium, mass {run.mass} kg{_SIM}", fontsize=9)
    fig.tight_layout()
    _save(fig, os.path.join(out, "equilibrium.png"))
    methods = list(g["methods"])
    rows = []
    for n in range(0, t.size, step):
        rows.append([float(t[n]), int(on[n]), float(g["m_a_minus_g"][n]), float(g["truth"].torque_cog_norm[n])]
                    + [float(g["methods"][m].force_sum_norm[n]) for m in methods]
                    + [float(g["methods"][m].torque_cog_norm[n]) for m in methods])
    write_csv(os.path.join(out, "equilibrium.csv"),
               ["time_s", "on_table", "truth_m_a_minus_g_N", "truth_torque_cog_Nm"]
               + [f"{m}_force_sum_N" for m in methods] + [f"{m}_torque_cog_Nm" for m in methods], rows)
    return ["equilibrium.png", "equilibrium.csv"]


# ---------------------------------------------------------------------- contact points
def _contact(res, out):
    tc = res.touches
    if not tc.get("available"):
        return []
    pts = tc["points"]
    rows = [[src, int(r[0]) + 1, float(pts[int(r[0]), 0]), float(pts[int(r[0]), 1]), float(r[1]), float(r[2]), float(r[3]),
             float(r[4]), int(r[5])]
            for src in ("cube", "reference") for r in tc[src]["rows"]]
    write_csv(os.path.join(out, "contact_points.csv"),
               ["sensor", "point", "target_x_m", "target_y_m", "est_mean_x_m", "est_mean_y_m", "rms_error_to_target_m",
                "rms_error_to_placed_m", "samples"], rows)
    fig, ax = new_figure(figsize=(5.2, 5.2))
    half = 0.023 * 1000
    ax.plot([-half, half, half, -half, -half], [-half, -half, half, half, -half], "k-", lw=0.8, label="46×46 mm patch")
    smp = tc["samples"]
    ok = smp["valid"]
    sel = np.flatnonzero(ok)[:: max(1, ok.sum() // 3000)]
    rv = smp["ref_valid"]
    rsel = np.flatnonzero(rv)[:: max(1, rv.sum() // 3000)]
    ax.scatter(smp["ref_est"][rsel, 0] * 1000, smp["ref_est"][rsel, 1] * 1000, s=2, alpha=0.3, color="C2",
               label=f"reference sensor, RMS {1000 * tc['reference']['rms_target']:.2f} mm")
    ax.scatter(smp["est"][sel, 0] * 1000, smp["est"][sel, 1] * 1000, s=2, alpha=0.3, color="C0",
               label=f"cube (unloaded_frame), RMS {1000 * tc['cube']['rms_target']:.2f} mm")
    ax.scatter(smp["placed"][:, 0] * 1000, smp["placed"][:, 1] * 1000, marker="+", color="k", s=30,
               label=f"where touches landed (σ {1000 * tc['scatter_m']:.1f} mm/axis)")
    ax.scatter(pts[:, 0] * 1000, pts[:, 1] * 1000, marker="x", color="C3", s=60, label="marked targets")
    ax.set_aspect("equal")
    ax.set_xlabel(f"x on face {tc['face']} [mm]")
    ax.set_ylabel(f"y on face {tc['face']} [mm]")
    ax.set_title(f"8-point test, errors to the targets{_SIM}", fontsize=9)
    ax.legend(fontsize=7)
    fig.tight_layout()
    _save(fig, os.path.join(out, "contact_points.png"))
    return ["contact_points.csv", "contact_points.png"]

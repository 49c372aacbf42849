"""The one-page summary (Markdown) with the papers' qualitative findings checked."""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from ._experiments import METHOD_MOUNTS, METHOD_ORDER, Results
from ._figures import FIGURES, squeeze_rmse, table1_rows

__all__ = ["Finding", "findings", "write_summary"]

#: Identification accuracy counted as "identified".
IDENTIFICATION_MIN = 0.75


@dataclass(frozen=True)
class Finding:
    """One qualitative finding of the papers, checked on the simulated data."""

    key: str
    text: str
    holds: bool
    detail: str


def _force(ev) -> float:
    return float(np.nanmean(ev.rmse_force()))


def _torque(ev) -> float:
    return float(np.nanmean(ev.rmse_torque()))


def _squeeze_force(ev) -> float:
    return squeeze_rmse(ev)[0]


def findings(res: Results) -> list[Finding]:
    """The qualitative findings, each with the numbers behind it."""
    return _calibration_findings(res) + _grasp_findings(res) + _contact_findings(res)


def _calibration_findings(res: Results) -> list[Finding]:
    """Methods against each other: coupling, loaded vs unloaded frame, identification, conditioning."""
    ev = res.evaluations
    out = []
    # the papers' claim is of their linear fits: pito's face_to_face correction reads the other
    # faces' crosstalk out of a face's gauges (docs/calibration.md), so its default models coupling too
    lin = res.linear_evaluations
    f2f = _squeeze_force(lin["face_to_face"])
    cpl = {m: _squeeze_force(lin[m]) for m in ("quasi_total", "total")}
    out.append(Finding(
        "coupling",
        "methods that model coupling (quasi_total, total) beat face_to_face (squeeze resultant RMSE, forces; "
        "the papers' linear fits)",
        all(v < f2f for v in cpl.values()),
        f"quasi_total {cpl['quasi_total']:.3f} N, total {cpl['total']:.3f} N vs face_to_face {f2f:.3f} N",
    ))
    lf, uf = ev["loaded_frame"], ev["unloaded_frame"]
    out.append(Finding(
        "frame",
        "unloaded frame beats loaded frame on RMSE (single-face loads, forces and torques)",
        _force(uf) < _force(lf) and _torque(uf) < _torque(lf),
        f"forces {_force(uf):.3f} N vs {_force(lf):.3f} N; torques {_torque(uf):.4f} N·m vs {_torque(lf):.4f} N·m",
    ))
    wins = [c for c in range(1, 7)
            if _force(res.per_connected[("unloaded_frame", c)][1]) < _force(res.per_connected[("loaded_frame", c)][1])]
    out.append(Finding(
        "frame_per_face",
        "unloaded frame beats loaded frame for every connected face (forces)",
        len(wins) == 6,
        f"{len(wins)} of 6 connected faces ({', '.join(map(str, wins)) or 'none'})",
    ))
    idn = ev["unloaded_frame"].identification
    single = idn["single"]["force"]
    squeeze = idn["squeeze"]["torque"]
    out.append(Finding(
        "identification",
        f"loaded faces are identified in single (by force) and squeeze (by torque) runs (≥ {IDENTIFICATION_MIN:.0%} of samples)",
        single is not None and squeeze is not None and single >= IDENTIFICATION_MIN and squeeze >= IDENTIFICATION_MIN,
        f"unloaded_frame: single {100 * (single or 0):.1f} %, squeeze {100 * (squeeze or 0):.1f} % "
        f"(thresholds {idn['force_threshold_N']} N, {idn['torque_threshold_Nm']} N·m)",
    ))
    sqw = [c for c in range(1, 7)
           if _squeeze_force(res.squeeze_per_connected[("unloaded_frame", c)])
           < _squeeze_force(res.squeeze_per_connected[("loaded_frame", c)])]
    out.append(Finding(
        "squeeze_per_face",
        "unloaded frame beats loaded frame on squeeze loads for every connected face (resultant forces; Figs 11, 12, 16, 19)",
        len(sqw) == 6,
        f"{len(sqw)} of 6 connected faces ({', '.join(map(str, sqw)) or 'none'}); "
        + ", ".join(f"face {c}: {_squeeze_force(res.squeeze_per_connected[('unloaded_frame', c)]):.3f} vs "
                    f"{_squeeze_force(res.squeeze_per_connected[('loaded_frame', c)]):.3f} N" for c in range(1, 7)),
    ))
    t1 = table1_rows(res)
    vals = [r[1] for r in t1] + [r[3] for r in t1]
    inside = sum(1e-4 <= v <= 1e-3 for v in vals)
    out.append(Finding(
        "icn",
        "inverse condition numbers in the paper's range 10⁻⁴ – 10⁻³ (loaded frame; unloaded frame with its net-load "
        "directions measured by a frame_hole session, 36×36)",
        inside == len(vals),
        f"{inside} of {len(vals)} in range; min {min(vals):.2e}, max {max(vals):.2e}. The unloaded frame fitted on its "
        f"face-flange session alone (plain least squares) has rank 30 of 36: 1/cond ≤ {max(r[2] for r in t1):.1e}, "
        "so Table I's unloaded values rest on the net-load directions being measured (or on a prior)",
    ))
    return out


def _grasp_findings(res: Results) -> list[Finding]:
    """The free grasp's equilibrium (Fig. 20), with the net load measured and without."""
    out = []
    g = res.grasp
    run = g["run"]
    free = ~run.state.on_table & (np.arange(run.time.size) > 0)
    errs = {m: float(np.median(np.abs(eq.force_sum_norm - g["m_a_minus_g"])[free])) for m, eq in g["methods"].items()}
    measured = [m for m in g["methods"] if res.grasp_net_load.get(m) == "measured"]
    unmeasured = [m for m in g["methods"] if m not in measured]
    ok = [m for m in measured if errs[m] < 0.15 * run.weight]
    out.append(Finding(
        "equilibrium",
        "free grasp (Fig. 20): with the net load measured, ‖ΣF‖ follows the weight (m‖a − g‖) within 15 % of m g "
        "while held in the air, for every such calibration",
        bool(measured) and len(ok) == len(measured),
        "median |‖ΣF‖ − m‖a − g‖|: " + ", ".join(f"{m} {errs[m]:.3f} N" for m in measured)
        + f" (m g = {run.weight:.2f} N; net load measured); median ‖ΣT‖ about the cog "
        + ", ".join(f"{m} {float(np.median(g['methods'][m].torque_cog_norm[free])):.4f} N·m" for m in measured),
    ))
    face_only = [m for m in unmeasured if METHOD_MOUNTS.get(m, ("face",))[0] == "face"]
    other = [m for m in unmeasured if m not in face_only]
    if face_only:
        zero = [m for m in face_only if float(np.median(g["methods"][m].force_sum_norm[free])) < 0.15 * run.weight]
        out.append(Finding(
            "equilibrium_unmeasured",
            "free grasp under a face-flange calibration without a net-load measurement: the data do not identify "
            "the net force (every training sample has ΣF = 0), so plain least squares outputs ‖ΣF‖ ≈ 0 in the air",
            len(zero) == len(face_only),
            "; ".join(f"{m}: median ‖ΣF‖ {float(np.median(g['methods'][m].force_sum_norm[free])):.3f} N, "
                      f"|‖ΣF‖ − m‖a − g‖| {errs[m]:.3f} N ({res.grasp_net_load.get(m)})" for m in face_only)
            + "".join(f"; {m} (frame flange, {res.grasp_net_load.get(m)}: its unfitted connected face is not touched "
                      f"in the air, so it still follows within {errs[m]:.3f} N)" for m in other),
        ))
    return out


def _contact_findings(res: Results) -> list[Finding]:
    """The 8-point contact test (when it ran)."""
    out = []
    tc = res.touches
    if tc.get("available"):
        cube, ref = tc["cube"], tc["reference"]
        out.append(Finding(
            "contact",
            "8-point test: with realistic touch placement the error to the marked points is a few mm (papers: ~3 mm) "
            "and comes from the placement, not the cube: cube and reference sensor agree within 1 mm, and the cube "
            "is within 1 mm of where the touch landed",
            bool(0.5e-3 < cube["rms_target"] < 5e-3 and abs(cube["rms_target"] - ref["rms_target"]) < 1e-3
                 and cube["rms_placed"] < 1e-3),
            f"RMS to targets: cube {1000 * cube['rms_target']:.2f} mm, reference {1000 * ref['rms_target']:.2f} mm; "
            f"to where touches landed: cube {1000 * cube['rms_placed']:.2f} mm, reference "
            f"{1000 * ref['rms_placed']:.2f} mm; placement scatter σ {1000 * tc['scatter_m']:.1f} mm per axis "
            f"(RMS offset {1000 * tc['placement_rms']:.2f} mm, {tc['repeats']} touches per point)",
        ))
    return out


def _fmt(x, d=4):
    return "—" if x is None or not np.isfinite(x) else f"{x:.{d}g}"


def write_summary(res: Results, out_dir, files: list[str], elapsed: float, quick: bool) -> str:
    """Write ``summary.md`` in ``out_dir``; returns its path."""
    L = (_intro_lines(res, elapsed, quick) + _findings_lines(findings(res)) + _rmse_lines(res) + _table1_lines(res)
         + _squeeze_and_grasp_lines(res) + _figure_lines(res, files) + _notes_lines(res))
    path = os.path.join(out_dir, "summary.md")
    with open(path, "w", encoding="utf-8") as f:
        f.write("\n".join(L) + "\n")
    return path


def _intro_lines(res: Results, elapsed: float, quick: bool) -> list[str]:
    cfg = res.config
    L = []
    L.append("# PITO: both papers' experiments, reproduced on the simulator — SIMULATED DATA")
    L.append("")
    L.append(f"> **Every number and figure on this page is simulated** (`pito_core.sim`, default `SimParams`, "
             f"cube seed {cfg.cube_seed}, run seed {cfg.seed}); nothing was measured on hardware. "
             f"{'Quick run (`--quick`, small k). ' if quick else ''}k = {cfg.k} samples per face for calibration, "
             f"{cfg.k_test} per face held out, {cfg.k_squeeze} per squeeze pair; connected face {cfg.connected_face}. "
             f"Generated in {elapsed:.0f} s.")
    L.append("")
    return L


def _findings_lines(fs: list[Finding]) -> list[str]:
    L = []
    L.append("## Findings (checked automatically)")
    L.append("")
    L.append("| finding | holds | numbers |")
    L.append("| --- | --- | --- |")
    for f in fs:
        cells = [x.replace("|", "\\|") for x in (f.text, f.detail)]  # Markdown table cells
        L.append(f"| {cells[0]} | {'**yes**' if f.holds else '**NO**'} | {cells[1]} |")
    L.append("")
    return L


def _rmse_lines(res: Results) -> list[str]:
    L = []
    L.append("## RMSE per method (held-out data, SIMULATED)")
    L.append("")
    L.append("| method | mount (calibration) | force RMSE [N] | torque RMSE [N·m] | squeeze force RMSE [N] | "
             "squeeze torque RMSE [N·m] | model | 1/cond, linear fit [1] |")
    L.append("| --- | --- | --- | --- | --- | --- | --- | --- |")
    for m in METHOD_ORDER:
        ev = res.evaluations[m]
        fl, cs = METHOD_MOUNTS[m]
        sq_force, sq_torque = squeeze_rmse(ev)
        L.append(f"| {m} | {fl} on face {', '.join(map(str, cs))} | {_fmt(_force(ev))} | {_fmt(_torque(ev))} | "
                 f"{_fmt(sq_force)} | {_fmt(sq_torque)} | "
                 f"{res.calibrations[m].model.name} | {res.calibrations[m].linear_alternative().inverse_condition_number:.2e} |")
    L.append("")
    return L


def _table1_lines(res: Results) -> list[str]:
    L = []
    L.append("## Table I: inverse condition numbers per connected face, the papers' linear fits (SIMULATED)")
    L.append("")
    L.append("| connected face | loaded frame (36×36) | unloaded frame alone (36×36) | unloaded frame + frame_hole session (36×36) |")
    L.append("| --- | --- | --- | --- |")
    for r in table1_rows(res):
        L.append(f"| {r[0]} | {r[1]:.2e} | {r[2]:.2e} | {r[3]:.2e} |")
    L.append("")
    L.append("Under a face flange every sample has Σ_i F_i = 0 (the flange's reaction balances the loads): the "
             "loads span 30 of 36 dimensions, and the unloaded frame fitted on its face-flange session alone leaves "
             "the 6 net-load directions unidentified (rank 30, 1/cond ≈ 0; `meta[\"net_load\"]` = \"not measured\"). "
             "The table is of the papers' linear fits: where the default chose the polynomial correction, its affine "
             "part is fitted per face and output group and is not of rank 30, but the net load is no better measured. "
             "Adding a frame_hole session to the same fit measures it (full rank). A ridge prior (each face's "
             "own-gauge fit) gives full-rank unloaded values too: the option `prior=\"own_gauge\"`.")
    L.append("")
    return L


def _squeeze_and_grasp_lines(res: Results) -> list[str]:
    L = []
    L.append("## Squeeze resultant RMSE per connected face (SIMULATED; Figs 11, 12, 16, 19)")
    L.append("")
    L.append("| connected face | loaded frame [N] | unloaded frame [N] | unloaded frame + frame_hole [N] |")
    L.append("| --- | --- | --- | --- |")
    for c in range(1, 7):
        v = [_squeeze_force(res.squeeze_per_connected[(m, c)]) for m in
             ("loaded_frame", "unloaded_frame", "unloaded_frame+frame_hole")]
        L.append(f"| {c} | {v[0]:.3f} | {v[1]:.3f} | {v[2]:.3f} |")
    L.append("")
    L.append("## Free grasp (Fig. 20): how each calibration got the net force (SIMULATED)")
    L.append("")
    L.append("| calibration | net force of a free grasp |")
    L.append("| --- | --- |")
    for m, words in res.grasp_net_load.items():
        L.append(f"| {m} | {words} |")
    L.append("")
    return L


def _figure_lines(res: Results, files: list[str]) -> list[str]:
    L = []
    L.append("## Figures (SIMULATED)")
    L.append("")
    for name, (title, csvs) in FIGURES.items():
        if name not in files:
            if name == "contact_points.png":
                L.append(f"- {title}: {res.touches.get('reason', 'skipped')}")
            continue
        data = ", ".join(f"[{c}]({c})" for c in csvs if c in files)
        L.append(f"### {title}")
        L.append("")
        L.append(f"![{title} (simulated)]({name})")
        L.append("")
        L.append(f"Data: {data}")
        L.append("")
    return L


def _notes_lines(res: Results) -> list[str]:
    L = []
    L.append("## Notes")
    L.append("")
    L.append("- Equilibrium: every calibration is shown; only those whose net-load directions were measured "
             "(`meta[\"net_load\"] == \"measured\"`) can follow m‖a − g‖ (see the table above).")
    L.append("- 8-point test: touches land with a Gaussian placement error (σ per in-plane axis, fixed per touch; "
             "`simulate_touches(placement_scatter=, repeats=)`); the cube's contact points also carry the "
             "calibration's own error; errors are given to the marked targets (as in the papers) and to where "
             "each touch landed.")
    L.append(f"- Simulator speed: {res.generation_rate / 1e6:.2f} million samples per second "
             "(calibration sessions, counts + reference).")
    for n in res.notes:
        L.append(f"- {n}")
    L.append("- Progress log: " + "; ".join(f"{t:.1f} s {s}" for t, s in res.timings[-3:]))
    return L

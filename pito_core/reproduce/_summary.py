"""The one-page summary (Markdown) with the papers' qualitative findings checked."""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from ._experiments import METHOD_MOUNTS, METHOD_ORDER, Results
from ._figures import FIGURES, table1_rows

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
    return float(np.sqrt(np.nanmean(ev.rmse_squeeze[:3] ** 2)))


def findings(res: Results) -> list[Finding]:
    """The qualitative findings, each with the numbers behind it."""
    ev = res.evaluations
    out = []
    f2f = _squeeze_force(ev["face_to_face"])
    cpl = {m: _squeeze_force(ev[m]) for m in ("quasi_total", "total")}
    out.append(Finding(
        "coupling",
        "methods that model coupling (quasi_total, total) beat face_to_face (squeeze resultant RMSE, forces)",
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
    t1 = table1_rows(res)
    vals = [r[1] for r in t1] + [r[2] for r in t1]
    inside = sum(1e-4 <= v <= 1e-3 for v in vals)
    out.append(Finding(
        "icn",
        "inverse condition numbers in the paper's range 10⁻⁴ – 10⁻³ (loaded and unloaded frame, 36×36)",
        inside == len(vals),
        f"{inside} of {len(vals)} in range; min {min(vals):.2e}, max {max(vals):.2e}",
    ))
    g = res.grasp
    run = g["run"]
    free = ~run.state.on_table & (np.arange(run.time.size) > 0)
    best = min(g["methods"], key=lambda m: np.median(np.abs(g["methods"][m].force_sum_norm - g["m_a_minus_g"])[free]))
    err = float(np.median(np.abs(g["methods"][best].force_sum_norm - g["m_a_minus_g"])[free]))
    out.append(Finding(
        "equilibrium",
        "free grasp: ‖ΣF‖ follows the weight (m‖a − g‖) within 15 % of m g while held in the air",
        err < 0.15 * run.weight,
        f"median |‖ΣF‖ − m‖a − g‖| = {err:.3f} N ({best}) for m g = {run.weight:.2f} N; "
        f"median ‖ΣT‖ about the cog {float(np.median(g['methods'][best].torque_cog_norm[free])):.4f} N·m",
    ))
    tc = res.touches
    if tc.get("available"):
        e = tc["rows"][:, 3]
        out.append(Finding(
            "contact",
            "contact points on the flat patch within 2 mm (RMS, 8 points + centre)",
            bool(np.all(np.isfinite(e)) and np.nanmax(e) < 0.002),
            f"RMS error per point {', '.join(f'{1000 * v:.2f}' for v in e)} mm",
        ))
    return out


def _fmt(x, d=4):
    return "—" if x is None or not np.isfinite(x) else f"{x:.{d}g}"


def write_summary(res: Results, out_dir, files: list[str], elapsed: float, quick: bool) -> str:
    """Write ``summary.md`` in ``out_dir``; returns its path."""
    cfg = res.config
    fs = findings(res)
    L = []
    L.append("# PITO: both papers' experiments, reproduced on the simulator — SIMULATED DATA")
    L.append("")
    L.append(f"> **Every number and figure on this page is simulated** (`pito_core.sim`, default `SimParams`, "
             f"cube seed {cfg.cube_seed}, run seed {cfg.seed}); nothing was measured on hardware. "
             f"{'Quick run (`--quick`, small k). ' if quick else ''}k = {cfg.k} samples per face for calibration, "
             f"{cfg.k_test} per face held out, {cfg.k_squeeze} per squeeze pair; connected face {cfg.connected_face}. "
             f"Generated in {elapsed:.0f} s.")
    L.append("")
    L.append("## Findings (checked automatically)")
    L.append("")
    L.append("| finding | holds | numbers |")
    L.append("| --- | --- | --- |")
    for f in fs:
        cells = [x.replace("|", "\\|") for x in (f.text, f.detail)]  # Markdown table cells
        L.append(f"| {cells[0]} | {'**yes**' if f.holds else '**NO**'} | {cells[1]} |")
    L.append("")
    L.append("## RMSE per method (held-out data, SIMULATED)")
    L.append("")
    L.append("| method | mount (calibration) | force RMSE [N] | torque RMSE [N·m] | squeeze force RMSE [N] | "
             "squeeze torque RMSE [N·m] | 1/cond [1] |")
    L.append("| --- | --- | --- | --- | --- | --- | --- |")
    for m in METHOD_ORDER:
        ev = res.evaluations[m]
        fl, cs = METHOD_MOUNTS[m]
        sq = ev.rmse_squeeze
        L.append(f"| {m} | {fl} on face {', '.join(map(str, cs))} | {_fmt(_force(ev))} | {_fmt(_torque(ev))} | "
                 f"{_fmt(_squeeze_force(ev))} | {_fmt(float(np.sqrt(np.nanmean(sq[3:] ** 2))))} | "
                 f"{res.calibrations[m].inverse_condition_number:.2e} |")
    L.append("")
    L.append("## Table I: inverse condition numbers per connected face (SIMULATED)")
    L.append("")
    L.append("| connected face | loaded frame (36×36) | unloaded frame (36×36) |")
    L.append("| --- | --- | --- |")
    for r in table1_rows(res):
        L.append(f"| {r[0]} | {r[1]:.2e} | {r[2]:.2e} |")
    L.append("")
    L.append("Under a face flange every sample has Σ_i F_i = 0 (the flange's reaction balances the loads): the "
             "loads span 30 of 36 dimensions. The fit keeps those 30 and acts as each face's own-gauge fit on the "
             "6 net-load directions (docs/calibration.md), so the matrix has full rank.")
    L.append("")
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
    L.append("## Notes")
    L.append("")
    L.append("- Equilibrium uses methods whose face outputs are independent (face_to_face, quasi_total, "
             "loaded_frame); total and unloaded_frame output ΣF ≡ 0 by construction (see Table I note).")
    L.append(f"- Simulator speed: {res.generation_rate / 1e6:.2f} million samples per second "
             "(calibration sessions, counts + reference).")
    for n in res.notes:
        L.append(f"- {n}")
    L.append("- Progress log: " + "; ".join(f"{t:.1f} s {s}" for t, s in res.timings[-3:]))
    path = os.path.join(out_dir, "summary.md")
    with open(path, "w", encoding="utf-8") as f:
        f.write("\n".join(L) + "\n")
    return path

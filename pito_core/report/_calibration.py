"""The calibration report: the results figures (matplotlib) and an exported folder (figures + numbers).

The same figure functions feed the wizard's results page and the exported report, so what
the operator accepted is what the report shows.
"""

from __future__ import annotations

import datetime as _dt
import json
import warnings
from pathlib import Path

from typing import TYPE_CHECKING

import numpy as np

from ..frames import FACE_COLORS, WRENCH_COMPONENTS, WRENCH_UNITS
from ._identification import identification_note, identification_text

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["rmse_figure", "identification_figure", "comparison_figure", "export_report", "style_figure", "model_summary",
           "SMALL", "SCREEN_DPI"]

AXES = WRENCH_COMPONENTS
UNITS = WRENCH_UNITS
DARK = {"bg": "#252b32", "fg": "#d5dde5", "grid": "#3d4650"}
#: pt: the smallest text in a figure (tick labels, annotations, legends): readable at screen DPI
SMALL = 9.0
#: pt: panel titles
TITLE = 10.0
#: dots per inch the app draws its figures at (a screen's; 9 pt = 12 px)
SCREEN_DPI = 96


def _figure(figsize, dpi):
    """A new ``matplotlib.figure.Figure`` (no pyplot, no global state)."""
    # deferred: matplotlib takes ~0.4 s to import and pito_core.report loads with `pito --help`
    from matplotlib.figure import Figure

    return Figure(figsize=figsize, dpi=dpi)


def model_summary(choice, output_faces=()) -> str:
    """Words for a ``ModelChoice``: the model in use, why, and the cross-validated RMSE (N, N·m) of each
    candidate, the one in use marked — the name and the figures beside it always agree."""
    groups = choice.corrected(output_faces) if choice.name != "linear" else []
    rms = choice.cv_rms()
    if choice.name == "linear":
        head, used = "the papers' linear fit (C = W S⁺)", "linear"
    elif output_faces and not groups:
        head, used = "the linear fit (the correction won on no output group)", "chosen" if "chosen" in rms else "poly"
    elif output_faces:
        head = (f"linear fit + polynomial correction on {len(groups)} of {2 * len(output_faces)} output groups: "
                + ", ".join(f"face {f} {part}" for f, part in groups))
        used = "chosen" if "chosen" in rms else "poly"
    else:
        head, used = "linear fit + polynomial correction", "chosen" if "chosen" in rms else "poly"
    text = f"<b>In use: {head}</b> — {choice.reason}"
    words = {"linear": "the linear fit everywhere", "poly": "the correction on every output group",
             "chosen": "the correction only where it won"}
    for key, (force, torque) in rms.items():
        mark = " <b>(in use)</b>" if key == used else ""
        text += f"<br>cross-validated RMSE, {words[key]}{mark}: forces {force:.3f} N, torques {torque * 1000:.2f} mN·m"
    return text


def style_figure(fig: Figure, dark: bool = True) -> None:
    """Tick labels of :data:`SMALL` pt; dark colours for the app, default (white) for the exported report."""
    for ax in fig.axes:
        ax.tick_params(labelsize=SMALL)
    if not dark:
        return
    fig.patch.set_facecolor(DARK["bg"])
    for ax in fig.axes:
        ax.set_facecolor(DARK["bg"])
        for s in ax.spines.values():
            s.set_color(DARK["grid"])
        ax.tick_params(colors=DARK["fg"])
        ax.xaxis.label.set_color(DARK["fg"])
        ax.yaxis.label.set_color(DARK["fg"])
        ax.title.set_color(DARK["fg"])


def face_rmse(evaluation, reactions: int | None = None, figures=None):
    """``(force (6,) N, torque (6,) N·m, reactions)``: each face's RMSE, the figures of the results page.

    With ``figures`` (:class:`~pito_core.calibration.ValidationFigures`), each face's own loads in the
    validation passes, and a face flange's face without loads of its own its reactions (``reactions``
    stays that face, else None: the face was validated under its own loads, on the second mount);
    without, the evaluation's RMSE per loaded face.
    """
    if figures is None:
        return evaluation.rmse_force(), evaluation.rmse_torque(), reactions
    f, t = np.array(figures.rmse_force, float), np.array(figures.rmse_torque, float)
    if reactions is not None:
        if np.isfinite(f[reactions - 1]):
            reactions = None
        else:
            f[reactions - 1], t[reactions - 1] = figures.reaction_force, figures.reaction_torque
    return f, t, reactions


def rmse_figure(evaluation, fig: Figure | None = None, dark: bool = True, *, reactions: int | None = None,
                kind: str = "held-out", figures=None) -> Figure:
    """RMSE per face: force (N) and torque (mN·m), each bar one face's loads.

    ``reactions``: the connected face of a face flange, which carried only the reactions of the
    others' loads (its bar is hatched and labelled so); ``kind``: what the figures come from
    ("validation", "held-out"), in the titles; ``figures``: the validation passes' figures per face
    (:func:`face_rmse`: a face loaded on the second mount has its own bar).
    """
    fig = fig or _figure(figsize=(6.4, 2.8), dpi=100)
    fig.clear()
    axf, axt = fig.subplots(1, 2)
    faces = np.arange(1, 7)
    f, t, reactions = face_rmse(evaluation, reactions, figures)
    t = t * 1000
    colors = [FACE_COLORS[i] for i in faces]
    for ax, v, title, unit in ((axf, f, "force RMSE", "N"), (axt, t, "torque RMSE", "mN·m")):
        ok = np.isfinite(v)
        ax.bar(faces[ok], v[ok], color=np.array(colors)[ok], width=0.7)
        u = _interval_marks(evaluation, unit)
        for x, y in zip(faces[ok], v[ok]):
            # the value above its bar and above the ± mark, never struck through by it
            above = max(y, u[x - 1]) if np.isfinite(u[x - 1]) else y
            ax.annotate(f"{y:.3g}", (x, above), xytext=(0, 3), textcoords="offset points", ha="center", va="bottom",
                        fontsize=SMALL, color=DARK["fg"] if dark else "black")
        for x in faces[~ok]:
            ax.annotate("n/a", (x, 0), ha="center", va="bottom", fontsize=SMALL, color="#888888")
        ax.set_xticks(faces, [f"{i}\nreactions" if i == reactions else str(i) for i in faces])
        if reactions is not None and ok[reactions - 1]:
            ax.patches[int(np.flatnonzero(ok).tolist().index(reactions - 1))].set_hatch("///")
        ax.set_xlabel("loaded face" if reactions is None else "face (loaded; the flange's face: reactions only)", fontsize=SMALL)
        ax.set_ylabel(f"{title} ({unit})", fontsize=SMALL)
        ax.set_title(f"{kind} {title} ({unit})", fontsize=TITLE)
        top = np.nanmax(v) if ok.any() else 1.0
        if np.isfinite(u).any():
            okU = np.isfinite(u)
            if okU.any():
                ax.scatter(faces[okU], u[okU], marker="_", s=250, linewidths=2,
                           color=DARK["fg"] if dark else "black",
                           label="± 95 % (may be short)" if getattr(evaluation, "uncertainty95_caveat", None)
                           else "± 95 % of the wrench")
                leg = ax.legend(fontsize=SMALL, loc="upper left", framealpha=0.6)
                if dark:
                    leg.get_frame().set_facecolor(DARK["bg"])
                    for text in leg.get_texts():
                        text.set_color(DARK["fg"])
                top = max(top, float(np.nanmax(u)))
        ax.set_ylim(0, top * 1.45 if top > 0 else 1.0)  # room for the values and the legend
        ax.grid(axis="y", alpha=0.25)
    style_figure(fig, dark)
    fig.tight_layout()
    return fig


def _interval_marks(evaluation, unit: str) -> np.ndarray:
    """(6,) the ± 95 % half-width per face, RMS over its force (N) or torque (mN·m) axes; NaN without one."""
    unc = getattr(evaluation, "uncertainty95", None)  # (6, 6) half-widths of the 95 % intervals, or None
    if unc is None:
        return np.full(6, np.nan)
    u = np.asarray(unc, dtype=float)[:, :3] if unit == "N" else np.asarray(unc, dtype=float)[:, 3:] * 1000
    with np.errstate(invalid="ignore"):
        return np.sqrt(np.nanmean(u**2, axis=1))


def identification_figure(evaluation, fig: Figure | None = None, dark: bool = True) -> Figure:
    """Face identification: mean ‖F‖ on every scored face (rows) when one face is loaded (columns; under
    each, the share of its loads identified). A face that is not scored under a load (a face flange's
    face carrying the reactions) is left blank."""
    fig = fig or _figure(figsize=(3.6, 3.0), dpi=100)
    fig.clear()
    ax = fig.subplots()
    fn = np.asarray(evaluation.identified.get("force_norm", np.zeros((0, 6))), dtype=float)
    if "evaluable" in evaluation.identified:
        fn = np.where(np.asarray(evaluation.identified["evaluable"], dtype=bool), fn, np.nan)
    face = np.asarray(evaluation.comparison.get("face", np.zeros(0)), dtype=int)
    M = np.full((6, 6), np.nan)
    with np.errstate(invalid="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # a face never scored under a load: NaN, blank
        for j in range(1, 7):
            rows = face == j
            if rows.any():
                M[:, j - 1] = np.nanmean(fn[rows], axis=0)
    im = ax.imshow(M, cmap="magma", origin="upper", vmin=0)
    by = (evaluation.identification.get("by_loaded_face") or {}).get("force") or [None] * 6
    ax.set_xticks(range(6), [f"{i}\n{100 * a:.0f} %" if a is not None and np.isfinite(a) else str(i)
                             for i, a in zip(range(1, 7), by)])
    ax.set_yticks(range(6), [str(i) for i in range(1, 7)])
    ax.set_xlabel("loaded face (identified)", fontsize=SMALL)
    ax.set_ylabel("face reading a force", fontsize=SMALL)
    for i in range(6):
        for j in range(6):
            if np.isfinite(M[i, j]):
                ax.text(j, i, f"{M[i, j]:.1f}", ha="center", va="center", fontsize=SMALL,
                        color="black" if M[i, j] > 0.6 * np.nanmax(M) else "white")
    acc = (evaluation.identification.get("single") or {}).get("force")  # the papers' rule for single-face loads
    # two short lines: the figure is narrow, a one-line title was cut at both ends
    ax.set_title("face identification: mean ‖F‖ (N)"
                 + (f"\n{100 * acc:.1f} % of single-face loads identified by force" if acc is not None else ""),
                 fontsize=TITLE)
    style_figure(fig, dark)
    fig.tight_layout()
    return fig


def comparison_figure(evaluation, fig: Figure | None = None, dark: bool = True) -> Figure:
    """Calibrated total load against the reference, per axis (reference frame), held-out samples."""
    fig = fig or _figure(figsize=(6.4, 3.4), dpi=100)
    fig.clear()
    axes = fig.subplots(2, 3)
    pred = np.asarray(evaluation.comparison.get("predicted", np.zeros((0, 6))), dtype=float)
    ref = np.asarray(evaluation.comparison.get("reference", np.zeros((0, 6))), dtype=float)
    face = np.asarray(evaluation.comparison.get("face", np.zeros(0)), dtype=int)
    cols = np.array([FACE_COLORS.get(int(f), "#aaaaaa") for f in face]) if face.size else np.zeros(0)
    for k, ax in enumerate(axes.ravel()):
        scale = 1000.0 if k >= 3 else 1.0
        unit = "mN·m" if k >= 3 else "N"
        ok = np.isfinite(pred[:, k]) & np.isfinite(ref[:, k]) if pred.size else np.zeros(0, bool)
        if ok.any():
            ax.scatter(ref[ok, k] * scale, pred[ok, k] * scale, s=2, c=cols[ok], alpha=0.6, linewidths=0)
            lo = min(np.min(ref[ok, k]), np.min(pred[ok, k])) * scale
            hi = max(np.max(ref[ok, k]), np.max(pred[ok, k])) * scale
            ax.plot([lo, hi], [lo, hi], color="#888888", lw=0.8)
            rmse = np.sqrt(np.mean((pred[ok, k] - ref[ok, k]) ** 2)) * scale
            ax.set_title(f"{AXES[k]}: RMSE {rmse:.3g} {unit}", fontsize=SMALL)
        else:
            ax.set_title(f"{AXES[k]}", fontsize=SMALL)
        ax.locator_params(nbins=4)  # few ticks: readable at 9 pt in a small panel
        ax.set_xlabel(f"reference ({unit})", fontsize=SMALL)
        if k % 3 == 0:
            ax.set_ylabel(f"calibrated ({unit})", fontsize=SMALL)
        ax.grid(alpha=0.2)
    fig.suptitle("calibrated against the reference (held-out, total load, reference frame)", fontsize=TITLE,
                 color=DARK["fg"] if dark else "black")
    style_figure(fig, dark)
    fig.tight_layout()
    return fig


def export_report(folder, calibration, evaluation, info: dict | None = None, progress=None, *, rmse: dict | None = None,
                  figures=None) -> Path:
    """Write ``folder/``: ``report.md``, ``numbers.json`` and the three figures as PNG.

    Parameters
    ----------
    folder : path
        Created if missing.
    calibration : Calibration
    evaluation : Evaluation
    info : dict, optional
        Extra facts for the report (mount, devices, samples, simulated).
    progress : callable, optional
        ``progress(fraction 0..1, text)`` after each file written.
    rmse : dict, optional
        The results page's RMSE options (``reactions``: the flange's face, ``kind``: "validation"
        or "held-out"; ``completed``: the faces loaded on the second mount): the report says and
        draws what the page does.
    figures : ValidationFigures, optional
        The page's headline (worst face, 95 % intervals, the reactions' face) and each face's figure
        (:func:`face_rmse`).

    Returns
    -------
    Path of ``report.md``.
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    info = dict(info or {})

    def step(k: int, text: str) -> None:
        if progress is not None:
            progress(k / 5, text)

    rmse = dict(rmse or {})
    rmse.setdefault("figures", figures)
    options = {k: v for k, v in rmse.items() if k != "completed"}  # rmse_figure's
    draw = {"rmse.png": lambda ev, dark: rmse_figure(ev, dark=dark, **options),
            "identification.png": identification_figure, "comparison.png": comparison_figure}
    for k, (name, figure) in enumerate(draw.items()):
        step(k, f"drawing {folder / name}")
        figure(evaluation, dark=False).savefig(folder / name, dpi=150, bbox_inches="tight", pad_inches=0.1)
    step(3, f"writing {folder / 'numbers.json'}")
    numbers = _numbers(calibration, evaluation, info)
    (folder / "numbers.json").write_text(json.dumps(numbers, indent=2, default=_json_default))
    path = folder / "report.md"
    step(4, f"writing {path}")
    path.write_text("\n".join(_report_lines(calibration, evaluation, info, numbers["generated"], rmse, figures)))
    step(5, f"report written to {folder}")
    return path


def _numbers(calibration, evaluation, info: dict) -> dict:
    """``numbers.json``: when, the facts given, the calibration's description and the evaluation."""
    return {
        "generated": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
        "info": info,
        "calibration": {
            "method": calibration.method,
            "output_faces": list(calibration.output_faces),
            "output_frame": calibration.output_frame,
            "inverse_condition_number": calibration.inverse_condition_number,
            "model": calibration.model.to_dict(),
            "meta": calibration.meta,
        },
        "evaluation": evaluation.to_dict(),
    }


def _report_lines(calibration, evaluation, info: dict, generated: str, rmse: dict | None = None,
                  figures=None) -> list[str]:  # rmse: rmse_figure's options, and "completed" (second mount's faces)
    """The lines of ``report.md`` (Markdown): the facts, RMSE per face (the results page's words: validation
    or held-out, 95 % intervals, the flange's face as reactions), identification, the figures."""
    rmse = rmse or {}
    kind = rmse.get("kind", "held-out")
    f, t, reaction = face_rmse(evaluation, rmse.get("reactions"), figures)
    uf, ut = _interval_marks(evaluation, "N"), _interval_marks(evaluation, "mN·m")
    lines = [
        f"# PITO calibration report — {calibration.method}",
        "",
        f"Generated {generated}." + (" **SIMULATED DEVICES** — not a real instrument." if info.get("simulated") else ""),
        "",
        "| item | value |",
        "| --- | --- |",
    ]
    for k, v in info.items():
        lines.append(f"| {k} | {v} |")
    model = model_summary(calibration.model, calibration.output_faces).replace("<b>", "**").replace("</b>", "**")
    lines += [
        f"| inverse condition number σmin/σmax | {calibration.inverse_condition_number:.3e} |",
        f"| calibration model | {model.split('<br>')[0]} |",
    ] + [f"| | {line} |" for line in model.split("<br>")[1:]] + [
        f"| {kind} single-face samples | {evaluation.n_single} |",
    ]
    if figures is not None and np.isfinite(figures.worst_force):
        wf = int(np.nanargmax(figures.rmse_force)) + 1
        wt = int(np.nanargmax(figures.rmse_torque)) + 1
        lines += [
            f"| worst {kind} force RMSE | {figures.worst_force:.4f} N (face {wf}), 95 %: "
            f"{figures.worst_force_ci[0]:.4f}–{figures.worst_force_ci[1]:.4f} N |",
            f"| worst {kind} torque RMSE | {figures.worst_torque * 1000:.3f} mN·m (face {wt}), 95 %: "
            f"{figures.worst_torque_ci[0] * 1000:.3f}–{figures.worst_torque_ci[1] * 1000:.3f} mN·m |",
        ]
        if reaction:
            lines.append(f"| reactions (face {reaction}) | {figures.reaction_force:.3f} N, "
                         f"{figures.reaction_torque * 1000:.2f} mN·m — carried only the others' reactions |")
    lines += [
        f"| 95 % intervals | **may be short**: {caveat} |"
        for caveat in [getattr(evaluation, "uncertainty95_caveat", None)] if caveat
    ] + [
        "",
        f"## {kind.capitalize()} RMSE per loaded face",
        "",
        "± 95 %: half-width of the wrench's 95 % interval, RMS over the face's axes (the marks in rmse.png).",
        "",
        "| face | force RMSE (N) | ± 95 % (N) | torque RMSE (mN·m) | ± 95 % (mN·m) |",
        "| --- | --- | --- | --- | --- |",
    ]

    def num(x, fmt):
        return format(x, fmt) if np.isfinite(x) else "n/a"

    for i in range(6):
        name = f"{i + 1} (reactions only)" if reaction == i + 1 else str(i + 1)
        lines.append(f"| {name} | {num(f[i], '.4f')} | {num(uf[i], '.4f')} | {num(t[i] * 1000, '.4f')} | "
                     f"{num(ut[i], '.4f')} |")
    head = evaluation.identification_headline()  # single-face loads by force, squeeze loads by torque
    note = identification_note(evaluation, reaction)  # what holds it down: the results page's line
    lines += [
        "",
        ("Face identification (the papers' rule): " + identification_text(evaluation, rmse.get("completed", ()))
         + (f" — {note}" if note else "") + ".") if head else "",
        "",
        f"![{kind} RMSE per face](rmse.png)",
        "",
        "![Face identification](identification.png)",
        "",
        "![Comparison with the reference](comparison.png)",
        "",
    ]
    return lines


def _json_default(x):
    if isinstance(x, np.ndarray):
        return x.tolist()
    if isinstance(x, np.generic):
        return x.item()
    if isinstance(x, float) and not np.isfinite(x):
        return None
    return str(x)

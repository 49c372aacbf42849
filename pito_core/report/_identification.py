"""Why the face identification figure is what it is: the loaded face's and the unloaded faces'
force norms against the threshold (the wizard's results page: a line under the figure and its
tooltip)."""

from __future__ import annotations

import numpy as np

__all__ = ["identification_breakdown", "identification_why", "identification_note", "identification_text"]


def identification_breakdown(evaluation, reaction: int | None = None) -> dict | None:
    """Where single-face identification by force fails, from the evaluation's sample series.

    Parameters
    ----------
    evaluation : pito_core.calibration.Evaluation
        Its ``identified`` series (``force_norm (M, 6)`` N, ``true_loaded (M, 6)``) and
        ``comparison["kind"]`` are read.
    reaction : int, optional
        The flange's face (1–6), left out (it carries reactions, not loads) where the evaluation
        does not say per sample which faces count (``identified["evaluable"]``).

    Returns
    -------
    dict or None
        ``threshold`` N; ``n`` single-face samples; ``missed`` fraction whose loaded face reads
        ‖F‖ ≤ threshold; ``phantom`` fraction where an unloaded face reads ‖F‖ > threshold
        (``phantom_by_loaded`` (6,): the same by loaded face, NaN where none was loaded);
        ``unloaded_median`` and ``unloaded_p90`` ‖F‖ of the unloaded faces, N; ``accuracy`` at
        1 and 2 × the threshold (fractions). None without single-face samples.
    """
    thr = float(evaluation.identification.get("force_threshold_N") or 0.0)
    fn = np.asarray(evaluation.identified["force_norm"], dtype=float)
    true = np.asarray(evaluation.identified["true_loaded"], dtype=bool)
    kind = np.asarray(evaluation.comparison["kind"])
    keep = np.ones(fn.shape, dtype=bool)
    if "evaluable" in evaluation.identified:  # per sample: each session's mount says which faces count
        keep &= np.asarray(evaluation.identified["evaluable"], dtype=bool)
    elif reaction:
        keep[:, reaction - 1] = False
    fn = np.where(keep, fn, np.nan)  # faces that do not count: neither loaded nor unloaded
    true &= keep
    rows = (kind == "single") & (true.sum(axis=1) == 1) & (np.isfinite(fn) | ~keep).all(axis=1)
    if thr <= 0 or not rows.any():
        return None
    fn, true, keep = fn[rows], true[rows], keep[rows]
    off = np.where(true | ~keep, np.nan, fn)

    def accuracy(t):
        return float((((fn > t) == true) | ~keep).all(axis=1).mean())

    phantom = (np.nan_to_num(off, nan=-1.0) > thr).any(axis=1)
    face = np.argmax(true, axis=1)
    n_by = np.bincount(face, minlength=6)
    with np.errstate(invalid="ignore", divide="ignore"):
        phantom_by = np.where(n_by > 0, np.bincount(face, weights=phantom, minlength=6) / np.maximum(n_by, 1), np.nan)

    return {"threshold": thr, "n": int(rows.sum()),
            "missed": float((np.where(true, fn, np.inf) <= thr).any(axis=1).mean()),
            "phantom": float(phantom.mean()), "phantom_by_loaded": phantom_by,
            "unloaded_median": float(np.nanmedian(off)), "unloaded_p90": float(np.nanpercentile(off, 90)),
            "accuracy": {1.0: accuracy(thr), 2.0: accuracy(2 * thr)}}


def _where(b: dict, short: bool = False) -> str:
    """Under which faces' loads the crosstalk shows, where it is not alike under all: the faces whose rate
    is at least half the highest, against the rest (``""`` otherwise)."""
    by = b["phantom_by_loaded"]
    ok = np.isfinite(by)
    top = np.nanmax(by) if ok.any() else 0.0
    worst = ok & (by >= top / 2)
    if top <= 0 or worst.sum() == ok.sum():
        return ""
    names = ", ".join(str(f + 1) for f in np.flatnonzero(worst))
    rest = float(np.nanmean(np.where(worst, np.nan, by)))
    mean_worst = float(np.nanmean(np.where(worst, by, np.nan)))
    if short:
        return f" — under face {names}'s loads {100 * mean_worst:.0f} %, the others' {100 * rest:.1f} %"
    return (f" Under face {names}'s loads an unloaded face read above the threshold in {100 * mean_worst:.1f} % of "
            f"the samples, under the other faces' in {100 * rest:.1f} %.")


def identification_why(evaluation, reaction: int | None = None) -> str:
    """One paragraph for the operator: why single-face identification scores what it does."""
    b = identification_breakdown(evaluation, reaction)
    if b is None:
        return ""
    t = b["threshold"]
    return (f"A single-face load counts as identified only if the loaded face reads ‖F‖ > {t:g} N and every other "
            f"face ≤ {t:g} N. On these {b['n']} samples (a subsample), the loaded face stayed at or below the "
            f"threshold in {100 * b['missed']:.1f} %; an unloaded face read above it in {100 * b['phantom']:.1f} % "
            f"(unloaded faces: median {b['unloaded_median']:.2f} N, 90th percentile {b['unloaded_p90']:.2f} N — the "
            f"calibration's crosstalk). With a {2 * t:g} N threshold, {100 * b['accuracy'][2.0]:.1f} % would be "
            f"identified.{_where(b)} Fresh loads show this crosstalk; held-out samples of the fitted captures share "
            f"the fit's errors and score higher.")


def identification_note(evaluation, reaction: int | None = None) -> str:
    """One line under the identification figure: what holds it down, with its numbers (N, %).

    Names the larger failure (an unloaded face above the threshold, the calibration's crosstalk;
    or the loaded face at or below it) and the figure at twice the threshold; ``""`` when no
    single-face samples were evaluated or fewer than 5 % of them fail.
    """
    b = identification_breakdown(evaluation, reaction)
    if b is None or b["accuracy"][1.0] >= 0.95:
        return ""
    t = b["threshold"]
    if b["phantom"] >= b["missed"]:
        why = (f"crosstalk: an unloaded face read > {t:g} N in {100 * b['phantom']:.0f} %{_where(b, short=True)} "
               f"(unloaded faces: median {b['unloaded_median']:.2f} N, 90th percentile {b['unloaded_p90']:.2f} N)")
    else:
        why = f"light loads: the loaded face read ≤ {t:g} N in {100 * b['missed']:.0f} %"
    return f"{why}; {100 * b['accuracy'][2.0]:.1f} % at a {2 * t:g} N threshold"


def identification_text(evaluation, completed=()) -> str:
    """The papers' identification figure (single-face loads by force, squeeze by torque) and, for single-face
    loads, the figure by loaded face (``completed``: faces loaded on the second mount, said so) — the results
    page's words and the report's."""
    head = evaluation.identification_headline()
    text = "; ".join(h["text"] for h in head) if head else "n/a"
    by = evaluation.identification.get("by_loaded_face", {}).get("force")
    if by is not None and any(h["kind"] == "single" for h in head):
        parts = [f"{f + 1}: {100 * a:.1f} %" + (" (2nd mount)" if f + 1 in completed else "")
                 for f, a in enumerate(by) if a is not None and np.isfinite(a)]
        text += "; by loaded face — " + ", ".join(parts)
    return text

"""Metrics per trial × phase (object level) and per trial × phase × patch, as plain row dicts.

Every number is a mean over the phase's samples unless its name says otherwise
(docs/analysis.md gives each formula). Columns end in their unit.
"""

from __future__ import annotations

import numpy as np

from ._grasp import norm3
from ._segment import AnalysisSettings, Trial

__all__ = ["phase_rows", "PHASE_COLUMNS", "PATCH_COLUMNS", "GRAVITY_MS2"]

#: |g| for the force residual, m/s² (the simulator's value).
GRAVITY_MS2 = 9.81
_G = GRAVITY_MS2

#: Object-level columns (one row per trial × phase) and their meaning.
PHASE_COLUMNS = {
    "trial": "trial number (1-based)",
    "phase": "load, lift, hold, replace or release",
    "start_s": "phase start, s from the start of the recording",
    "stop_s": "phase end, s",
    "duration_s": "phase length, s",
    "n_samples": "samples in the phase",
    "contacts": "faces in contact during the phase, e.g. '1 3 6'",
    "grip_force_N": "Σ normal force of the finger contacts (all but the base), N",
    "load_force_N": "Σ tangential force of the finger contacts, N",
    "grip_load_ratio": "grip_force_N / load_force_N (ratio of the phase means), 1",
    "support_force_N": "normal force of the base patch (the table), N",
    "net_force_N": "‖Σ contact forces‖, N (m·|g| when still in the air)",
    "manipulation_force_N": "Σ_k ‖(G⁺G f)_k‖: the part of the forces that holds and moves the object, N",
    "internal_force_N": "Σ_k ‖((I − G⁺G) f)_k‖: the squeezing part, no net wrench, N",
    "residual_force_N": "|‖Σ f_k‖ − m·|g||: static force balance (inertia included during lift/replace), N",
    "residual_moment_Nmm": "‖Σ (p_k − c) × f_k + τ_k n_k‖ about the centre of mass c, N·mm",
    "single_contact_frac": "smallest fraction, over the phase's contacts, of samples flagged single contacts, 1",
    "plausible": "every contact of the phase is a single contact (single_contact_frac >= threshold); "
                 "empty when the contacts carry no flag",
}
#: Patch-level columns (one row per trial × phase × patch in contact).
PATCH_COLUMNS = {
    "trial": "trial number", "phase": "phase name", "face": "face 1..6 whose patch carries the contact",
    "role": "finger or base",
    "onset_s": "contact onset of this patch in the trial, s",
    "contact_frac": "fraction of the phase's samples in contact, 1",
    "normal_force_N": "normal (pushing-in) force −f·n, N (mean over the samples in contact)",
    "tangential_force_N": "‖f + (−f·n) n‖, N",
    "share_pct": "this patch's share of the phase's Σ normal force (all patches), %",
    "manipulation_force_N": "‖(G⁺G f)_k‖, N", "internal_force_N": "‖((I − G⁺G) f)_k‖, N",
    "path_length_mm": "length of the low-pass filtered contact path on the patch, mm",
    "spread_mm": "RMS distance of the filtered contact point from its mean, mm",
    "single_contact_frac": "fraction of the samples in contact flagged single contacts, 1",
    "plausible": "single_contact_frac >= threshold (empty without a flag)",
}


def _mean(x, mask) -> float:
    return float(np.mean(x[mask])) if mask.any() else float("nan")


def _path(p) -> tuple[float, float]:
    """Length and RMS spread of a path ``(n, 3)`` m (NaN rows dropped), mm."""
    p = p[np.isfinite(p).all(axis=1)]
    if len(p) < 2:
        return (0.0, 0.0) if len(p) else (float("nan"), float("nan"))
    length = norm3(np.diff(p, axis=0)).sum()
    spread = np.sqrt(((p - p.mean(axis=0)) ** 2).sum(axis=1).mean())
    return float(1e3 * length), float(1e3 * spread)


def _plausible(frac: float, s: AnalysisSettings):
    return None if not np.isfinite(frac) else bool(frac >= s.single_contact_min)


def phase_rows(g, trials: list[Trial], s: AnalysisSettings, mass: float | None = None):
    """``(phase rows, patch rows)`` of the :class:`GraspSeries` ``g``: lists of dicts with
    :data:`PHASE_COLUMNS` / :data:`PATCH_COLUMNS` keys.

    A phase ``[a, b)`` (the trial's last: ``[a, b]``) is a range of samples of the increasing
    times, found by bisection; every mean is over a contiguous copy of its samples, as the
    boolean selection ``x[(t >= a) & (t < b)]`` gives them (the same numbers, bit for bit).
    """
    fingers = np.array([i + 1 != s.base_face for i in range(6)])
    man, inn = norm3(g.f_manip), norm3(g.f_int)
    net = norm3(g.net_force)
    moment = norm3(g.net_moment)
    by_face = _by_face(g, man, inn)
    phases, patches = [], []
    for tr in trials:
        names = list(tr.phases)
        for name in names:
            a, b = tr.phases[name]
            lo = int(np.searchsorted(g.time, a, "left"))
            hi = int(np.searchsorted(g.time, b, "right" if name == names[-1] else "left"))
            if hi <= lo:
                continue
            m = slice(lo, hi)
            on = g.on[m]
            faces = [i for i in range(6) if on[:, i].any()]
            rows = [_patch_row(by_face, tr, name, m, i, s) for i in faces]
            f_n = np.ascontiguousarray(g.f_n[m])
            total_n = f_n.sum(axis=1).mean()
            for r in rows:
                r["share_pct"] = 100.0 * r.pop("_fn_sum") / (hi - lo) / total_n if total_n > 0 else float("nan")
            fracs = [r["single_contact_frac"] for r in rows]
            frac = float(min(fracs)) if fracs and np.isfinite(fracs).all() else float("nan")
            grip = float((f_n * fingers).sum(axis=1).mean())
            load = float((np.ascontiguousarray(g.f_t[m]) * fingers).sum(axis=1).mean())
            base = np.ascontiguousarray(f_n[:, s.base_face - 1]).mean() if s.base_face else 0.0
            net_m = np.ascontiguousarray(net[m])
            phases.append({
                "trial": tr.index, "phase": name, "start_s": a, "stop_s": b, "duration_s": b - a,
                "n_samples": hi - lo, "contacts": " ".join(str(i + 1) for i in faces),
                "grip_force_N": grip, "load_force_N": load,
                "grip_load_ratio": grip / load if load > 0 else float("nan"), "support_force_N": float(base),
                "net_force_N": float(net_m.mean()),
                "manipulation_force_N": float(np.ascontiguousarray(man[m]).sum(axis=1).mean()),
                "internal_force_N": float(np.ascontiguousarray(inn[m]).sum(axis=1).mean()),
                "residual_force_N": float(np.abs(net_m - mass * _G).mean()) if mass else float("nan"),
                "residual_moment_Nmm": float(1e3 * moment[m].mean()),
                "single_contact_frac": frac, "plausible": _plausible(frac, s)})
            patches += rows
    return phases, patches


def _by_face(g, man, inn) -> dict:
    """Per-face copies ``(6, N, …)`` of the series: a face's samples of a phase are then a contiguous slice."""
    out = {k: np.ascontiguousarray(np.moveaxis(v, 1, 0)) for k, v in
           (("on", g.on), ("f_n", g.f_n), ("f_t", g.f_t), ("man", man), ("inn", inn), ("path", g.path))}
    out["single"] = None if g.single is None else np.ascontiguousarray(np.asarray(g.single).T)
    return out


def _patch_row(by_face, tr: Trial, name, m: slice, i, s) -> dict:
    """The row of face ``i + 1`` (0-based ``i``) in the phase of samples ``m`` (a slice).

    ``by_face``: :func:`_by_face`; every mean is over the same samples in the same order as
    the boolean selection of the ``(N, 6)`` arrays gives them.
    """
    on = by_face["on"][i, m]
    n = m.stop - m.start
    length, spread = _path(by_face["path"][i, m][on])
    single = by_face["single"]
    frac = _mean(single[i, m], on) if single is not None else float("nan")
    f_n = by_face["f_n"][i, m]
    return {"trial": tr.index, "phase": name, "face": i + 1, "role": "base" if i + 1 == s.base_face else "finger",
            "onset_s": tr.onset.get(i + 1, float("nan")), "contact_frac": float(on.sum() / n),
            "normal_force_N": _mean(f_n, on), "tangential_force_N": _mean(by_face["f_t"][i, m], on),
            "_fn_sum": float(f_n.sum()),
            "manipulation_force_N": _mean(by_face["man"][i, m], on), "internal_force_N": _mean(by_face["inn"][i, m], on),
            "path_length_mm": length, "spread_mm": spread, "single_contact_frac": frac,
            "plausible": _plausible(frac, s)}

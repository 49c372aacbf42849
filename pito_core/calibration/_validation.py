"""Figures of a validation pass (fresh loads, not fitted) with their 95 % intervals.

The wizard's headline: what a new session will show. Errors of one capture (a held load)
hold together, so the intervals come from a bootstrap over captures (runs of samples of one
loaded face, split where the time jumps), not over samples.
"""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np

from ._calibration import Calibration
from ._fit import calibrate, session_offsets
from ..io import CalibrationSession
from ._targets import MountGeometry, block_targets

__all__ = ["ValidationFigures", "confirm_model", "validation_figures"]

#: Bootstrap draws of the intervals.
N_BOOT = 400


class ValidationFigures:
    """RMSE of the loaded faces on a validation session, with 95 % intervals (SI units).

    Attributes
    ----------
    rmse_force, rmse_torque : ndarray, shape (6,)
        RMS error over the three force (N) / torque (N·m) axes of each directly loaded face; NaN
        for faces not loaded directly (the connected face of a ``face`` flange: see ``reaction_*``).
    worst_force, worst_torque : float
        The largest of them, N and N·m.
    worst_force_ci, worst_torque_ci : tuple of float
        95 % interval of the worst figure (bootstrap over captures).
    reaction_force, reaction_torque : float
        RMS error of the connected face of a ``face`` flange, which carried only reactions (NaN otherwise).
    n_samples, n_captures : int
    """

    def __init__(self, rmse_force, rmse_torque, worst_force_ci, worst_torque_ci, reaction, n_samples, n_captures):
        self.rmse_force = rmse_force
        self.rmse_torque = rmse_torque
        self.worst_force = float(np.nanmax(rmse_force)) if np.isfinite(rmse_force).any() else float("nan")
        self.worst_torque = float(np.nanmax(rmse_torque)) if np.isfinite(rmse_torque).any() else float("nan")
        self.worst_force_ci = tuple(float(x) for x in worst_force_ci)
        self.worst_torque_ci = tuple(float(x) for x in worst_torque_ci)
        self.reaction_force, self.reaction_torque = (float(x) for x in reaction)
        self.n_samples = int(n_samples)
        self.n_captures = int(n_captures)


def _captures(time: np.ndarray | None, face: np.ndarray) -> np.ndarray:
    """(n,) capture index: runs of one loaded face, cut where the time jumps (> 5 median steps)."""
    cut = np.r_[True, face[1:] != face[:-1]]
    if time is not None and time.size > 2:
        dt = np.diff(time)
        step = np.median(dt[dt > 0]) if (dt > 0).any() else 0.0
        cut[1:] |= (dt > 5 * step) | (dt < 0)
    else:
        cut[::200] = True
    return np.cumsum(cut) - 1


def _rmse(sse, n, pick):
    """(6, 2) RMSE per face (force, torque) of the captures ``pick`` (indices)."""
    s, m = sse[pick].sum(axis=0), n[pick].sum(axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(m > 0, np.sqrt(s / np.maximum(m, 1)), np.nan)


def _session_errors(calibration: Calibration, session: CalibrationSession):
    """Per capture of ``session``: squared errors ``(n_cap, 7, 2)`` and counts of the directly loaded faces
    (faces 0..5) and of a ``face`` flange's reactions (6), forces (0) and torques (1); and the face of each capture."""
    offset = session_offsets(session)
    counts, reference = np.asarray(session.counts[:], float), np.asarray(session.reference[:], float)
    loaded = np.asarray(session.loaded[:], bool)
    pred = calibration.wrenches(counts, offset=offset)
    targets, carries, usable, _ = block_targets(reference, loaded, MountGeometry(session), "face")
    one = usable & (loaded.sum(axis=1) == 1)
    c = session.connected_face - 1
    if session.flange == "face":
        one &= ~loaded[:, c]  # a direct load on the flange's face goes into the flange: no face senses it
    face = np.where(one, np.argmax(loaded, axis=1), -1)
    cap = _captures(None if session.time is None else np.asarray(session.time[:], float), face)
    err2 = (pred - targets) ** 2  # (n, 6, 6)
    rows = np.flatnonzero(one)
    used, cap_rows = np.unique(cap[rows], return_inverse=True)  # captures with single-face loads, renumbered
    sse = np.zeros((used.size, 7, 2))
    cnt = np.zeros((used.size, 7, 2))
    for part, ax in ((0, slice(0, 3)), (1, slice(3, 6))):
        np.add.at(sse[:, :, part], (cap_rows, face[rows]), err2[rows, face[rows], ax].sum(axis=1))
        np.add.at(cnt[:, :, part], (cap_rows, face[rows]), 3)
        if session.flange == "face":
            np.add.at(sse[:, 6, part], cap_rows, err2[rows, c, ax].sum(axis=1))
            np.add.at(cnt[:, 6, part], cap_rows, 3)
    cap_face = np.full(used.size, -1)
    cap_face[cap_rows] = face[rows]
    return sse, cnt, cap_face, rows.size


def validation_figures(calibration: Calibration, session, *, seed: int = 0) -> ValidationFigures:
    """RMSE of each directly loaded face on ``session`` (tared on its own unloaded samples), with intervals.

    Parameters
    ----------
    calibration : Calibration
    session : CalibrationSession or sequence of them
        Fresh single-face loads, not used in the fit (and their unloaded samples, each session's
        offset). Several sessions (the validation passes of a main and a second mount) pool their
        captures: each face's figure comes from the sessions that load it directly.
    seed : int
        Seed of the bootstrap.
    """
    sessions = [session] if isinstance(session, CalibrationSession) else list(session)
    if not sessions:
        raise ValueError("session: expected at least one validation session, got none")
    parts = [_session_errors(calibration, s) for s in sessions]
    sse = np.concatenate([p[0] for p in parts])
    cnt = np.concatenate([p[1] for p in parts])
    cap_face = np.concatenate([p[2] for p in parts])
    n_samples = sum(p[3] for p in parts)
    used = np.arange(cap_face.size)
    point = _rmse(sse, cnt, used)
    rng = np.random.default_rng(seed)
    worst = np.full((N_BOOT, 2), np.nan)
    by_face = [used[cap_face == f] for f in range(6)]
    for b in range(N_BOOT):
        pick = np.concatenate([rng.choice(ix, ix.size) for ix in by_face if ix.size] or [np.zeros(0, int)])
        r = _rmse(sse[:, :6], cnt[:, :6], pick)
        worst[b] = np.nanmax(r, axis=0) if np.isfinite(r).any() else np.nan
    lo, hi = np.nanpercentile(worst, [2.5, 97.5], axis=0) if np.isfinite(worst).any() else (np.full(2, np.nan),) * 2
    return ValidationFigures(point[:6, 0], point[:6, 1], (lo[0], hi[0]), (lo[1], hi[1]), point[6], n_samples, used.size)


def _corrected_groups(calibration: Calibration) -> list[tuple[int, int]]:
    """``(face 1..6, part)`` (part 0: forces, 1: torques) whose rows use the polynomial correction."""
    rows = calibration.model.row_alpha if calibration.model is not None else None
    if not rows:  # a correction on every row (files written before the per-row choice)
        return [(f, part) for f in calibration.output_faces for part in (0, 1)]
    return sorted({(calibration.output_faces[r // 6], (r % 6) // 3) for r, a in enumerate(rows) if a is not None})


def confirm_model(calibration: Calibration, session: CalibrationSession, *, seed: int = 0, sessions=None,
                  fit_options: dict | None = None):
    """Keep a polynomial correction only if the validation pass confirms it; its figures.

    Cross-validation inside one session can miss what a later session shows (new loads,
    drift). Each face's forces or torques that the correction serves are compared on
    ``session`` (fresh loads, not fitted) with the papers' linear fit of the same data; if
    the correction is worse on any of them, the linear fit is used, and its
    ``model.reason`` says where the correction lost (``session``: one or several validation
    sessions, as :func:`validation_figures` takes them). The choice looks at the validation
    pass, so that pass's figures are then, by a little, optimistic for the choice made.

    ``sessions`` (the training sessions; ``fit_options``: more arguments of :func:`calibrate`):
    the linear fit is then fitted again from them, so that its error model is its own (the same
    matrix; :meth:`Calibration.linear_alternative` keeps the correction's error model, whose
    residuals are smaller than the linear fit's).

    Returns
    -------
    (Calibration, ValidationFigures)
        The calibration to use and its figures on ``session`` (see :func:`validation_figures`).
    """
    figures = validation_figures(calibration, session, seed=seed)
    if calibration.correction is None or calibration.linear_fit is None:
        return calibration, figures
    linear = calibration.linear_alternative()
    lin_figures = validation_figures(linear, session, seed=seed)
    lost = []
    for face, part in _corrected_groups(calibration):
        def pick(fig):  # the face's own loads; a face flange's face without any: its reactions
            direct = (fig.rmse_force, fig.rmse_torque)[part][face - 1]
            return direct if np.isfinite(direct) else (fig.reaction_force, fig.reaction_torque)[part]

        a, b = pick(figures), pick(lin_figures)
        if np.isfinite(a) and np.isfinite(b) and a > b:
            unit, k = ("N", 1.0) if part == 0 else ("mN·m", 1e3)
            lost.append(f"face {face} {('forces', 'torques')[part]} {a * k:.3g} against {b * k:.3g} {unit}")
    if not lost:
        return calibration, figures
    if sessions is not None:
        with warnings.catch_warnings():  # the first fit of the same data has warned already
            warnings.simplefilter("ignore")
            linear = calibrate(sessions, calibration.method, **{**(fit_options or {}), "model": "linear"})
    linear.model = dataclasses.replace(
        linear.model, requested=calibration.model.requested,
        reason="the polynomial correction chosen by cross-validation lost on the "
               f"validation pass ({'; '.join(lost)})")
    return linear, lin_figures

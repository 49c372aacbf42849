"""Cubes of the bench's own forms, built without ``pito_core.sim`` (SIMULATED).

A cube maps the six face wrenches ``F (n, 6, 6)`` (face frames, N and N·m) to 36 counts:
``lin = F K'`` with ``K (36, 36)`` of well-conditioned own-face blocks and inter-face
coupling blocks of relative size ``coupling``; then, per form,

- ``saturation``: each gauge ``s tanh(lin / s)``, ``s`` set so a full-scale load is compressed
  by ``level`` (amplifier or bridge saturation);
- ``hub``: each gauge adds a quadratic form of its own face's wrench (scaled to full scale),
  at most ``level`` of the gauge's full-scale span within full scale (hub bending);
- ``both``: the two together.

Loads move smoothly (piecewise-linear between random knots, within ± ``load_scale`` full
scale per axis), so neighbouring samples are alike, as in a hand-held session.
"""

from __future__ import annotations

import numpy as np

from pito_core.calibration import CalibrationSession
from pito_core.defaults import FULL_SCALE_FACE
from pito_core.frames import CubeCore, invert_pose, pose_from_rotation_translation, transform_wrench

__all__ = ["FULL_SCALE", "BenchCube", "cube_session"]

#: Full-scale face load, [fx, fy, fz, tx, ty, tz], N and N·m.
FULL_SCALE = np.asarray(FULL_SCALE_FACE)
#: Samples between the knots of a load's path.
KNOT_SAMPLES = 40


class BenchCube:
    """A cube of the bench's own forms (see the module docstring)."""

    def __init__(self, form: str = "linear", coupling: float = 0.05, level: float = 0.1, seed: int = 0):
        if form not in ("linear", "saturation", "hub", "both"):
            raise ValueError(f"form: expected linear, saturation, hub or both, got {form!r}")
        rng = np.random.default_rng(seed)
        gains = np.array([2000.0] * 3 + [2e5] * 3)  # counts per N and per N·m
        K = np.zeros((36, 36))
        for i in range(6):
            for j in range(6):
                B = rng.normal(size=(6, 6)) * gains
                K[6 * i : 6 * i + 6, 6 * j : 6 * j + 6] = B + 3.0 * np.diag(gains) if i == j else coupling * B
        self.form, self.coupling, self.level, self.K = form, coupling, level, K
        span = np.abs(K * np.tile(FULL_SCALE, 6)).sum(axis=1)  # counts of a full-scale load, per gauge
        self.span = span
        # tanh(x)/x = 1 − level at x = span / s: solve for s
        x = np.linspace(1e-3, 5, 20001)
        xs = x[np.argmin(np.abs(np.tanh(x) / x - (1 - level)))]
        self.sat = span / xs
        A = rng.normal(size=(36, 6, 6))
        A = 0.5 * (A + A.transpose(0, 2, 1))
        # per gauge, a quadratic form of its face's wrench scaled to full scale, |uᵀAu| ≤ 1 within full scale
        self.hub = A / np.abs(A).sum(axis=(1, 2))[:, None, None]
        self.offset = 1e6 * rng.uniform(0.5, 1.0, size=36)

    def counts(self, F: np.ndarray) -> np.ndarray:
        """``(n, 36)`` counts less the offset, for face wrenches ``F (n, 6, 6)``."""
        y = F.reshape(-1, 36) @ self.K.T
        if self.form in ("saturation", "both"):
            y = self.sat * np.tanh(y / self.sat)
        if self.form in ("hub", "both"):
            u = (F / FULL_SCALE).reshape(-1, 6, 6)
            face = np.repeat(np.arange(6), 6)
            q = np.einsum("nga,gab,ngb->ng", u[:, face], self.hub, u[:, face])
            y = y + self.level * self.span * q
        return y


def _path(rng, n: int, scale: float) -> np.ndarray:
    """``(n, 6)`` a smooth load path within ± ``scale`` full scale per axis."""
    k = max(2, n // KNOT_SAMPLES + 2)
    knots = rng.uniform(-1, 1, size=(k, 6)) * FULL_SCALE * scale
    t = np.linspace(0, k - 1, n)
    return np.stack([np.interp(t, np.arange(k), knots[:, a]) for a in range(6)], axis=1)


def cube_session(cube: BenchCube, flange: str, connected_face: int, faces, k: int, *, pairs=(), load_scale=1.0,
                 n_rest=300, noise=2.0, seed=1, offset_shift=0.0, reference_noise=0.0):
    """A session of ``k`` samples per loaded face in ``faces`` (then per squeezed pair in ``pairs``).

    ``flange``: ``face`` (the connected face carries the reaction), ``frame`` (it carries
    nothing) or ``frame_hole`` (every face carries its own load only). Returns
    ``(session, F)``: the :class:`CalibrationSession` and the true face wrenches ``F (N, 6, 6)``
    (face frames, N and N·m). ``offset_shift`` moves the zero-load counts (a later session);
    ``reference_noise`` is the reference's own noise (standard deviation, a fraction of ``FULL_SCALE``
    per axis, on every sample).
    """
    rng = np.random.default_rng(seed)
    core = CubeCore()
    c = connected_face
    poses = core.face_poses()
    T_core_ati = core.face_pose(c) @ pose_from_rotation_translation(
        np.array([[np.cos(0.5), -np.sin(0.5), 0], [np.sin(0.5), np.cos(0.5), 0], [0, 0, 1]]), [0.0, 0.0, 0.03])
    groups = [(f,) for f in faces] + [tuple(p) for p in pairs]
    applied = [np.zeros((n_rest, 6, 6))]
    loaded = [np.zeros((n_rest, 6), bool)]
    for g in groups:
        a = np.zeros((k, 6, 6))
        m = np.zeros((k, 6), bool)
        for f in g:
            a[:, f - 1] = transform_wrench(_path(rng, k, load_scale), invert_pose(poses[f - 1]))  # core frame
            m[:, f - 1] = True
        applied.append(a)
        loaded.append(m)
        applied.append(np.zeros((n_rest // 3, 6, 6)))  # back at rest between loads
        loaded.append(np.zeros((n_rest // 3, 6), bool))
    applied, loaded = np.concatenate(applied), np.concatenate(loaded)
    total = applied.sum(axis=1)
    carried = applied.copy()
    if flange == "face":
        carried[:, c - 1] = applied[:, c - 1] - (total - applied[:, c - 1])
    elif flange == "frame":
        carried[:, c - 1] = 0.0
    F = np.stack([transform_wrench(carried[:, i], poses[i]) for i in range(6)], axis=1)
    counts = cube.offset + offset_shift + cube.counts(F) + rng.normal(scale=noise, size=(len(F), 36))
    reference = transform_wrench(total, T_core_ati)
    if np.any(reference_noise):
        reference = reference + rng.normal(size=reference.shape) * reference_noise * FULL_SCALE
    s = CalibrationSession(np.round(counts).astype(np.int64), reference, loaded, T_core_ati, flange, c, core=core,
                           meta={"generator": "pito_bench._cubes (simulated)", "simulated": True})
    return s, F

"""A lift-hold-replace task with known truth: the grasp analysis's test bench (SIMULATED).

The object rests on a table on face 6 (gravity along −z of the core frame, no rotation).
Each trial lasts :data:`LIFT_TRIAL_S` seconds; times from the trial's start, s:

======================  =====================================================================
0 – 0.5                 rest: the table carries the weight
0.5 – 1.0  (touch)      thumb (face 3) and index (face 1) touch; squeeze rises to 1 N
1.0 – 1.6  (load)       the fingers take the weight from the table, squeeze rises to ``grip``
1.6 – 2.0  (lift)       the object rises ``LIFT_HEIGHT`` (accelerates up, then down)
2.0 – 4.0  (hold)       still; the index finger slides ``slide`` along +y of the core frame
                        (2.4 – 3.6 s)
4.0 – 4.4  (replace)    the object is lowered onto the table
4.4 – 4.8               the table takes the weight back
4.8 – 5.3  (release)    the squeeze falls to 0; rest until 6 s
======================  =====================================================================

Loads are in equilibrium at every instant (Newton: Σ contact wrenches = m(a − g) about the
centre of mass, no rotation): the fingers carry the minimum-norm share of the wrench the
table does not carry (forces and torsions, torsion weighted as a force at 10 mm as in
:class:`~pito_core.sim.GraspScenario`), plus the squeeze along the line between the two
fingertips. The table's load is one contact on face 6's patch, at the centre of mass
projected onto the patch plane.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..frames import CubeCore, cross_rows
from ..io import RecordingWriter
from ._grasp import GRAVITY
from ._model import VirtualCube
from ._protocols import PATCH_HEIGHT
from ._signals import smoothstep

__all__ = ["LIFT_TRIAL_S", "LIFT_HEIGHT", "LIFT_TIMELINE", "LiftTask", "LiftTruth", "write_lift_recording"]

#: Length of one trial, s.
LIFT_TRIAL_S = 6.0
#: Height of the lift, m.
LIFT_HEIGHT = 0.03
#: The designed phases of a trial: name → (start, stop), s from the trial's start.
LIFT_TIMELINE = {"touch": (0.5, 1.0), "load": (1.0, 1.6), "lift": (1.6, 2.0), "hold": (2.0, 4.0),
                 "replace": (4.0, 4.4), "settle": (4.4, 4.8), "release": (4.8, 5.3)}
_THUMB, _INDEX, _BASE = 3, 1, 6  # faces
_LEVER = 0.01  # torsion weighted as a force at this lever, m


def _ramp(t, start, stop):
    """Cosine smoothstep from 0 (``t <= start``) to 1 (``t >= stop``) and its second derivative, 1/s²."""
    T = stop - start
    s = np.clip((t - start) / T, 0.0, 1.0)
    inside = (t > start) & (t < stop)
    return smoothstep(s), np.where(inside, 0.5 * np.pi**2 * np.cos(np.pi * s) / T**2, 0.0)


@dataclass(frozen=True)
class LiftTruth:
    """Truth of the task at N instants (core frame; face i at index ``i − 1``).

    Attributes
    ----------
    time : ndarray, shape (N,)
        s.
    point : ndarray, shape (N, 6, 3)
        Contact point on each patch, m (NaN where no contact).
    normal : ndarray, shape (N, 6, 3)
        Outward unit normal of the patch at the contact.
    force : ndarray, shape (N, 6, 3)
        Force of the finger (or table) on the object, N (zero where no contact).
    torsion : ndarray, shape (N, 6)
        Torsion about the normal, N·m.
    valid : ndarray of bool, shape (N, 6)
        A contact is there (any force).
    face_wrenches : ndarray, shape (N, 6, 6)
        Wrench on each face in its frame, ``[fx, fy, fz, tx, ty, tz]`` N and N·m.
    accel : ndarray, shape (N, 3)
        Acceleration of the object, m/s².
    """

    time: np.ndarray
    point: np.ndarray
    normal: np.ndarray
    force: np.ndarray
    torsion: np.ndarray
    valid: np.ndarray
    face_wrenches: np.ndarray
    accel: np.ndarray


class LiftTask:
    """``n_trials`` lift-hold-replace trials of a two-finger grasp (module docstring).

    Parameters
    ----------
    n_trials : int
    mass : float
        kg.
    cog : array-like, shape (3,)
        Centre of mass in the core frame, m.
    grips : sequence of float, optional
        Squeeze of each trial while holding, N (default ``3, 4.5, 6, …``).
    slides : sequence of float, optional
        Slide of the index finger during each trial's hold, m (default ``2, 4, 6, … mm``).
    seed : int
        Jitter of the fingertips on their patches (±3 mm).
    core : CubeCore, optional
    """

    def __init__(self, n_trials=3, mass=0.25, cog=(0.001, -0.002, 0.0), grips=None, slides=None, seed=0, core=None):
        if int(n_trials) < 1:
            raise ValueError(f"n_trials: expected >= 1, got {n_trials!r}")
        if not mass > 0:
            raise ValueError(f"mass: expected > 0 kg, got {mass!r}")
        self.n_trials = int(n_trials)
        self.mass = float(mass)
        self.cog = np.asarray(cog, dtype=float).reshape(3)
        self.grips = np.asarray(grips if grips is not None else 3.0 + 1.5 * np.arange(self.n_trials), float)
        self.slides = np.asarray(slides if slides is not None else 0.002 * (1 + np.arange(self.n_trials)), float)
        if self.grips.shape != (self.n_trials,) or self.slides.shape != (self.n_trials,):
            raise ValueError(f"grips, slides: expected {self.n_trials} values each, got {self.grips.size}, {self.slides.size}")
        self.core = CubeCore() if core is None else core
        rng = np.random.default_rng([int(seed), 0x1F7])
        self.jitter = rng.uniform(-0.003, 0.003, (self.n_trials, 2, 2))  # (trial, finger, [y, z])
        self.duration = self.n_trials * LIFT_TRIAL_S

    def trial_times(self, k: int) -> dict:
        """Designed phase times of trial ``k`` (0-based), s from the start of the recording."""
        t0 = k * LIFT_TRIAL_S
        return {name: (t0 + a, t0 + b) for name, (a, b) in LIFT_TIMELINE.items()}

    def truth(self, t) -> LiftTruth:
        """The task's contacts and face wrenches at times ``t (N,)``, s."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        n = t.size
        k = np.clip((t // LIFT_TRIAL_S).astype(int), 0, self.n_trials - 1)
        tau = t - k * LIFT_TRIAL_S
        up, up_dd = _ramp(tau, 1.6, 2.0)
        down, down_dd = _ramp(tau, 4.0, 4.4)
        accel = np.zeros((n, 3))
        accel[:, 2] = LIFT_HEIGHT * (up_dd - down_dd)
        table = 1.0 - _ramp(tau, 1.0, 1.6)[0] + _ramp(tau, 4.4, 4.8)[0]
        squeeze = (_ramp(tau, 0.5, 1.0)[0] + (self.grips[k] - 1.0) * _ramp(tau, 1.0, 1.6)[0]) * (1 - _ramp(tau, 4.8, 5.3)[0])
        touching = (tau > 0.5) & (tau < 5.3)
        h = self.core.edge / 2 + PATCH_HEIGHT
        slide = self.slides[k] * _ramp(tau, 2.4, 3.6)[0]
        j = self.jitter[k]
        p_thumb = np.stack([np.full(n, -h), j[:, 0, 0], j[:, 0, 1]], axis=1)
        p_index = np.stack([np.full(n, h), j[:, 1, 0] + slide, j[:, 1, 1]], axis=1)
        n_thumb, n_index = np.array([-1.0, 0, 0]), np.array([1.0, 0, 0])
        F_req = self.mass * (accel - GRAVITY)  # Σ contact forces, N
        W_req = np.concatenate([F_req, cross_rows(np.broadcast_to(self.cog, (n, 3)), F_req)], axis=1)
        W_fing = (1 - table)[:, None] * W_req
        G = np.zeros((n, 6, 8))
        for c, (p, nn) in enumerate(((p_thumb, n_thumb), (p_index, n_index))):
            G[:, :3, 3 * c:3 * c + 3] = np.eye(3)
            G[:, 3:, 3 * c:3 * c + 3] = _skew(p)
            G[:, 3:, 6 + c] = nn * _LEVER
        x = np.einsum("nij,nj->ni", np.linalg.pinv(G), W_fing)
        d = p_index - p_thumb
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        f_thumb = x[:, 0:3] + squeeze[:, None] * d  # pushing in: along +d at the thumb
        f_index = x[:, 3:6] - squeeze[:, None] * d
        point = np.full((n, 6, 3), np.nan)
        normal = np.zeros((n, 6, 3))
        force = np.zeros((n, 6, 3))
        torsion = np.zeros((n, 6))
        valid = np.zeros((n, 6), bool)
        for face, p, nn, f, tq, on in ((_THUMB, p_thumb, n_thumb, f_thumb, x[:, 6] * _LEVER, touching),
                                       (_INDEX, p_index, n_index, f_index, x[:, 7] * _LEVER, touching),
                                       (_BASE, np.broadcast_to(np.r_[self.cog[:2], -h], (n, 3)), np.array([0, 0, -1.0]),
                                        table[:, None] * F_req, np.zeros(n), table > 0)):
            i = face - 1
            point[on, i], normal[:, i], force[on, i], torsion[on, i], valid[:, i] = p[on], nn, f[on], tq[on], on
        return LiftTruth(t, point, normal, force, torsion, valid, self._face_wrenches(point, normal, force, torsion), accel)

    def _face_wrenches(self, point, normal, force, torsion) -> np.ndarray:
        """Wrench of each contact on its face, in the face frame ``(N, 6, 6)``."""
        T = self.core.face_poses()
        W = np.zeros(point.shape[:1] + (6, 6))
        for i in range(6):
            R, o = T[i, :3, :3], T[i, :3, 3]
            p = np.nan_to_num(point[:, i]) - o
            m = cross_rows(p, force[:, i]) + torsion[:, i, None] * normal[:, i]
            W[:, i, :3] = force[:, i] @ R
            W[:, i, 3:] = m @ R
        return W


def _skew(p):
    """``(N, 3, 3)`` cross-product matrices of ``p (N, 3)``."""
    S = np.zeros(p.shape[:1] + (3, 3))
    S[:, 0, 1], S[:, 0, 2], S[:, 1, 2] = -p[:, 2], p[:, 1], -p[:, 0]
    S[:, 1, 0], S[:, 2, 0], S[:, 2, 1] = p[:, 2], -p[:, 1], p[:, 0]
    return S


def write_lift_recording(path, task: LiftTask, model: VirtualCube | None = None, *, seed: int = 0,
                         meta: dict | None = None) -> LiftTruth:
    """Write the SIMULATED recording of ``task`` (cube counts only, no reference) and return its truth.

    Parameters
    ----------
    path : str or Path
        The recording written (``pito-recording``, docs/devices.md).
    task : LiftTask
    model : VirtualCube, optional
        The simulated cube (default ``VirtualCube()``); its rate sets the samples.
    seed : int
        Seed of the gauge noise.
    meta : dict, optional
        More header metadata (e.g. the calibration record the recording was made with);
        ``simulated`` and ``source`` are set here.
    """
    model = model or VirtualCube()
    t = np.arange(int(round(task.duration * model.params.rate))) / model.params.rate
    truth = task.truth(t)
    counts = model.counts_from_face_wrenches(truth.face_wrenches, t, rng=np.random.default_rng([int(seed), 0x11F7]))
    head = dict(meta or {})
    head.update(simulated=True, source=f"pito_core.sim lift task ({task.n_trials} trials, mass {task.mass} kg)",
                mass_kg=task.mass, cog_m=task.cog.tolist())
    with RecordingWriter(path, head, flush_interval=1.0, fsync=False) as w:
        w.append_pito(np.arange(t.size), np.round(t * 1e6).astype(np.int64) % 2**32, t, counts)
    return truth

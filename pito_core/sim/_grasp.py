"""A free grasp: the object's mass and motion, fingers on patches, a table under face 6.

Every load is applied on a face (fingers on their patches, the table on face 6's patch),
so the free-grasp load path holds (``F_i = W_i``) and the Newton–Euler equations hold at
every instant: ``Σ_i W_i + [m g, c × m g] = [m a, c × m a + I α + ω × I ω]`` (core frame,
moments about the core centre, ``a`` the acceleration of the centre of mass, ``c`` its
position).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..frames import CubeCore, check_vectors
from ._model import VirtualCube
from ._mount import face_from_core_adjoints
from ._protocols import PATCH_HEIGHT, _check_k, _model_or_default
from ._signals import smoothstep

__all__ = ["GraspScenario", "GraspState", "GraspRun", "simulate_free_grasp", "GRAVITY", "FINGER_LAYOUTS"]

#: Gravity in the world frame, m/s² (z up).
GRAVITY = np.array([0.0, 0.0, -9.81])

#: Finger layouts: (name, face, (x, y) on the patch in the face frame, m) and opposing
#: pairs that squeeze (internal forces along the line between the two contacts).
FINGER_LAYOUTS = {
    2: ([("thumb", 3, (0.002, 0.004)), ("index", 1, (-0.003, 0.006))], [(0, 1)]),
    3: (
        [("thumb", 3, (0.002, 0.004)), ("index", 1, (-0.008, 0.009)), ("middle", 1, (0.007, -0.006))],
        [(0, 1), (0, 2)],
    ),
    4: (
        [("thumb", 3, (0.002, 0.004)), ("index", 1, (-0.004, 0.007)), ("ring", 2, (0.006, 0.002)), ("palm", 4, (-0.003, -0.004))],
        [(0, 1), (2, 3)],
    ),
    5: (
        [
            ("thumb", 3, (0.002, 0.004)),
            ("index", 1, (-0.008, 0.009)),
            ("middle", 1, (0.007, -0.006)),
            ("ring", 2, (0.006, 0.002)),
            ("palm", 4, (-0.003, -0.004)),
        ],
        [(0, 1), (0, 2), (3, 4)],
    ),
}

# timeline of one loop, s: rest on the table, touch, squeeze, lift, move, put down, release
_T_TOUCH, _T_SQUEEZE, _T_LIFT, _T_FREE, _T_DOWN, _T_PLACED, _T_RELEASE, _T_LOOP = (
    1.0, 2.0, 3.0, 3.5, 8.5, 9.0, 10.5, 12.0)


@dataclass(frozen=True)
class GraspState:
    """Truth of the grasp at N instants (core frame unless stated).

    Attributes
    ----------
    applied : ndarray, shape (N, 6, 6)
        Load applied on each face, core frame, moment about the core centre.
    face_wrenches : ndarray, shape (N, 6, 6)
        Wrench on each face, face frames (free grasp: ``F_i = W_i``).
    finger_force : ndarray, shape (N, K, 3)
        Force of each finger on its patch, core frame, N (zero when not touching).
    finger_torsion : ndarray, shape (N, K)
        Torsion of each finger about the patch normal, N·m.
    finger_active : ndarray of bool, shape (N, K)
        Finger touching its patch.
    table_wrench : ndarray, shape (N, 6)
        The table's load on face 6, core frame, about the core centre.
    gravity : ndarray, shape (N, 3)
        Gravity in the core frame, m/s².
    accel : ndarray, shape (N, 3)
        Acceleration of the centre of mass in the core frame, m/s².
    on_table : ndarray of bool, shape (N,)
        The table carries part of the load.
    """

    applied: np.ndarray
    face_wrenches: np.ndarray
    finger_force: np.ndarray
    finger_torsion: np.ndarray
    finger_active: np.ndarray
    table_wrench: np.ndarray
    gravity: np.ndarray
    accel: np.ndarray
    on_table: np.ndarray


def _rot_small(angles: np.ndarray) -> np.ndarray:
    """``(n, 3, 3)`` rotation Rz(yaw) Ry(pitch) Rx(roll) from ``(n, 3)`` [roll, pitch, yaw]."""
    r, p, y = angles[:, 0], angles[:, 1], angles[:, 2]
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    R = np.empty((angles.shape[0], 3, 3))
    R[:, 0, 0] = cy * cp
    R[:, 0, 1] = cy * sp * sr - sy * cr
    R[:, 0, 2] = cy * sp * cr + sy * sr
    R[:, 1, 0] = sy * cp
    R[:, 1, 1] = sy * sp * sr + cy * cr
    R[:, 1, 2] = sy * sp * cr - cy * sr
    R[:, 2, 0] = -sp
    R[:, 2, 1] = cp * sr
    R[:, 2, 2] = cp * cr
    return R


class GraspScenario:
    """A looping grasp on the object, as a deterministic function of time.

    One loop (12 s): the object rests on a table on face 6 (0–1 s); the fingers touch
    their patches (1–2 s), squeeze (2–3 s) and lift it (3–3.5 s); the hand moves and tilts
    it (3.5–8.5 s, ~1 m/s² and ~0.3 rad); it is put down (8.5–9 s) and released
    (9–10.5 s); rest (10.5–12 s).

    Parameters
    ----------
    mass : float
        Mass of the object, kg.
    cog : array-like, shape (3,)
        Centre of mass in the core frame, m.
    n_fingers : {2, 3, 4, 5}
        Finger layout (:data:`FINGER_LAYOUTS`).
    grip : float
        Squeezing force of each opposing pair while holding, N.
    seed : int
        Jitter of the contact points (±2 mm) and of the motion.
    core : CubeCore, optional
    contacts : sequence of (face, point (3,), normal (3,)), optional
        Contact points and outward normals in the face frames (m), one per finger of the
        layout, e.g. on curved patches; default: the layout's points on flat patches at
        :data:`PATCH_HEIGHT`.
    free_only : bool
        Skip the table: the hand holds the object in the air for the whole run (a free
        grasp from the first sample; the loop starts at the lift).
    """

    def __init__(self, mass=0.3, cog=(0.002, -0.001, -0.003), n_fingers=3, grip=6.0, seed=0, core=None,
                 contacts=None, free_only=False):
        mass = float(mass)
        if not np.isfinite(mass) or mass <= 0:
            raise ValueError(f"mass: expected a positive mass in kg, got {mass!r}")
        self.mass = mass
        self.cog = check_vectors(cog, 3, "cog").reshape(3)
        if n_fingers not in FINGER_LAYOUTS:
            raise ValueError(f"n_fingers: expected one of {tuple(FINGER_LAYOUTS)}, got {n_fingers!r}")
        if not grip > 0:
            raise ValueError(f"grip: expected a positive force in N, got {grip!r}")
        self.grip = float(grip)
        self.core = CubeCore() if core is None else core
        self.free_only = bool(free_only)
        layout, pairs = FINGER_LAYOUTS[n_fingers]
        rng = np.random.default_rng([int(seed), 0x96A5])
        self.names = [name for name, _, _ in layout]
        self.faces = np.array([f for _, f, _ in layout])
        if contacts is None:
            pts = [np.array([u, v, PATCH_HEIGHT]) + np.r_[rng.uniform(-0.002, 0.002, 2), 0.0] for _, _, (u, v) in layout]
            contacts = [(f, p, (0.0, 0.0, 1.0)) for (_, f, _), p in zip(layout, pts)]
        if len(contacts) != len(layout):
            raise ValueError(f"contacts: expected {len(layout)} contacts for {n_fingers} fingers, got {len(contacts)}")
        self.contact_faces = np.array([int(f) for f, _, _ in contacts])
        self.points_face = np.array([np.asarray(p, float) for _, p, _ in contacts])
        self.normals_face = np.array([np.asarray(n, float) / np.linalg.norm(n) for _, _, n in contacts])
        poses = self.core.face_poses()
        R = poses[self.contact_faces - 1, :3, :3]
        self.points = np.einsum("kab,kb->ka", R, self.points_face) + poses[self.contact_faces - 1, :3, 3]
        self.normals = np.einsum("kab,kb->ka", R, self.normals_face)
        self.pairs = pairs
        K = len(layout)
        # grasp map: [f_k, τ_k] -> total wrench about the core centre; torsions weighted
        # as forces at 10 mm so the minimum-norm share prefers forces
        self._lever = 0.01
        G = np.zeros((6, 4 * K))
        for k in range(K):
            p, n = self.points[k], self.normals[k]
            G[:3, 3 * k : 3 * k + 3] = np.eye(3)
            G[3:, 3 * k : 3 * k + 3] = np.array([[0, -p[2], p[1]], [p[2], 0, -p[0]], [-p[1], p[0], 0]])
            G[3:, 3 * K + k] = n * self._lever
        self._G_pinv = np.linalg.pinv(G)
        self._K = K
        self.inertia = np.eye(3) * mass * (0.06**2) / 6.0
        self._motion_phase = rng.uniform(0, 2 * np.pi, 6)
        self.table_point = poses[5, :3, 3] + poses[5, :3, 2] * PATCH_HEIGHT
        self._face_from_core = face_from_core_adjoints(self.core)  # (6, 6, 6), fixed with the core

    # ------------------------------------------------------------------ timeline
    def _phases(self, t):
        """Loop time, finger contact level, grip level, table share, motion envelope."""
        if self.free_only:
            tau = _T_FREE + np.mod(t, _T_DOWN - _T_FREE)
        else:
            tau = np.mod(t, _T_LOOP)
        touch = smoothstep((tau - _T_TOUCH) / (_T_SQUEEZE - _T_TOUCH)) * (1 - smoothstep((tau - _T_PLACED) / (_T_RELEASE - _T_PLACED)))
        grip = 0.15 + 0.85 * smoothstep((tau - _T_SQUEEZE) / (_T_LIFT - _T_SQUEEZE))
        grip = grip * (1 - 0.85 * smoothstep((tau - _T_PLACED) / (_T_RELEASE - _T_PLACED)))
        table = 1 - smoothstep((tau - _T_LIFT) / (_T_FREE - _T_LIFT)) + smoothstep((tau - _T_DOWN) / (_T_PLACED - _T_DOWN))
        table = np.clip(table, 0.0, 1.0)
        env = smoothstep((tau - _T_FREE) / 0.5) * (1 - smoothstep((tau - (_T_DOWN - 0.5)) / 0.5))
        if self.free_only:
            touch, grip, table = np.ones_like(tau), np.ones_like(tau), np.zeros_like(tau)
            env = np.ones_like(tau)
        return tau, touch, grip, table, env

    def _pose(self, t):
        """Position (n, 3) m and rotation (n, 3, 3) of the core in the world."""
        tau, _, _, table, env = self._phases(t)
        ph = self._motion_phase
        lift = 0.05 * (1 - table)
        w = 2 * np.pi * np.array([0.9, 0.7, 1.1])
        pos = np.stack([0.03 * env * np.sin(w[0] * tau + ph[0]), 0.02 * env * np.sin(w[1] * tau + ph[1]),
                        lift + 0.02 * env * np.sin(w[2] * tau + ph[2])], axis=1)
        ang = np.stack([0.25 * env * np.sin(2 * np.pi * 0.4 * tau + ph[3]), 0.3 * env * np.sin(2 * np.pi * 0.5 * tau + ph[4]),
                        0.4 * env * np.sin(2 * np.pi * 0.3 * tau + ph[5])], axis=1)
        return pos, _rot_small(ang)

    # ------------------------------------------------------------------ loads
    def state(self, t) -> GraspState:
        """The grasp's loads at times ``t (n,)`` in s (any order)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        n = t.size
        h = 2e-3
        pos = [self._pose(t + d * h) for d in (-2, -1, 0, 1, 2)]
        p_m, p0, p_p = pos[1][0], pos[2][0], pos[3][0]
        R = pos[2][1]
        a_world = (p_p - 2 * p0 + p_m) / h**2

        def omega(Rm, Rp, Rc):  # body angular velocity from R(t±h)
            dR = (Rp - Rm) / (2 * h)
            W = np.einsum("nba,nbc->nac", Rc, dR)
            return np.stack([W[:, 2, 1] - W[:, 1, 2], W[:, 0, 2] - W[:, 2, 0], W[:, 1, 0] - W[:, 0, 1]], axis=1) / 2

        w0 = omega(pos[1][1], pos[3][1], R)
        w_m = omega(pos[0][1], pos[2][1], pos[1][1])
        w_p = omega(pos[2][1], pos[4][1], pos[3][1])
        alpha = (w_p - w_m) / (2 * h)
        g_b = np.einsum("nba,b->na", R, GRAVITY)  # Rᵀ g
        a_b = np.einsum("nba,nb->na", R, a_world)  # cog acceleration, body frame
        m, c, I = self.mass, self.cog, self.inertia
        F_req = m * (a_b - g_b)
        M_cog = alpha @ I.T + np.cross(w0, w0 @ I.T)
        W_req = np.concatenate([F_req, M_cog + np.cross(c, F_req)], axis=1)
        _, touch, grip, table, _ = self._phases(t)
        if self.free_only:
            table = np.zeros(n)
        W_table = table[:, None] * W_req
        x = (W_req - W_table) @ self._G_pinv.T  # (n, 4K)
        K = self._K
        f = x[:, : 3 * K].reshape(n, K, 3)
        tors = x[:, 3 * K :] * self._lever
        for a, b in self.pairs:
            d = self.points[b] - self.points[a]
            d = d / np.linalg.norm(d)
            s = (self.grip * grip * touch)[:, None]
            f[:, a] += s * d
            f[:, b] -= s * d
        active = np.repeat((touch > 1e-9)[:, None], K, axis=1)
        applied = np.zeros((n, 6, 6))
        for k in range(K):
            j = self.contact_faces[k] - 1
            applied[:, j, :3] += f[:, k]
            applied[:, j, 3:] += np.cross(self.points[k], f[:, k]) + tors[:, k : k + 1] * self.normals[k]
        # the table supports face 6: its force at the patch centre, plus the moment it needs
        applied[:, 5] += W_table
        F = np.einsum("fab,nfb->nfa", self._face_from_core, applied)
        return GraspState(applied, F, f, tors, active, W_table, g_b, a_b, table > 1e-9)


@dataclass(frozen=True)
class GraspRun:
    """A simulated free grasp: the counts and the truth.

    Attributes
    ----------
    counts : ndarray of int32, shape (N, 36)
    time : ndarray, shape (N,)
        s since the cube's tare.
    state : GraspState
        Loads, gravity and acceleration per sample (core frame).
    mass : float
        kg.
    cog : ndarray, shape (3,)
        Centre of mass, core frame, m.
    scenario : GraspScenario
    """

    counts: np.ndarray
    time: np.ndarray
    state: GraspState
    mass: float
    cog: np.ndarray
    scenario: GraspScenario

    @property
    def face_wrenches(self) -> np.ndarray:
        """True wrench on each face ``(N, 6, 6)``, face frames, N and N·m."""
        return self.state.face_wrenches

    @property
    def weight(self) -> float:
        """``m · |g|`` in N."""
        return self.mass * float(np.linalg.norm(GRAVITY))


def simulate_free_grasp(
    k: int = 12_000,
    seed: int = 0,
    model: VirtualCube | None = None,
    *,
    mass: float = 0.3,
    cog=(0.002, -0.001, -0.003),
    n_fingers: int = 3,
    grip: float = 6.0,
    t0: float = 0.0,
    free_only: bool = False,
) -> GraspRun:
    """A free grasp (no flange): fingers hold, lift and move the object.

    Parameters
    ----------
    k : int
        Number of samples (at ``model.params.rate``; 12 000 = one 12 s loop at 1 kHz).
    seed : int
        Seed of the run (contact jitter, motion phases, noise).
    model : VirtualCube, optional
        The simulated cube (default ``VirtualCube()``).
    mass, cog, n_fingers, grip, free_only :
        See :class:`GraspScenario` (kg, m, N).
    t0 : float
        Time of the first sample, s since the cube's tare.

    Returns
    -------
    GraspRun
        Counts ``(N, 36)`` int32 and the truth; the faces carry every load
        (``F_i = W_i``), the table included (on face 6).
    """
    k = _check_k(k)
    model = _model_or_default(model)
    scen = GraspScenario(mass, cog, n_fingers, grip, seed, model.core, free_only=free_only)
    t = t0 + np.arange(k) / model.params.rate
    st = scen.state(t - t0)
    rng = np.random.default_rng([int(seed), 3])
    counts = model.counts_from_face_wrenches(st.face_wrenches, t, rng=rng)
    return GraspRun(counts, t, st, scen.mass, scen.cog.copy(), scen)

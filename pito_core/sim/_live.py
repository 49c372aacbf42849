"""Live sources: the simulated devices' signals as deterministic functions of time.

A live source answers ``counts_at(t)`` and ``reference_at(t)`` for any sample times (s
since the source started). Loads, drift and noise are functions of ``t`` alone (the
noise is keyed by the sample index ``round(t · rate)`` and the seed), so two devices
polled at different rates, or the same time asked twice, agree exactly.
"""

from __future__ import annotations

import numpy as np

from ..frames import N_GAUGES, check_face
from ._grasp import GraspScenario, GraspState
from ._model import VirtualCube
from ._mount import check_flanged_mount, core_from_face_adjoints, face_wrenches_from_applied
from ._params import FULL_SCALE_FACE, FULL_SCALE_FRAME
from ._patches import contacts_on_assembly
from ._reference import ReferenceSensor, reference_pose
from ._signals import hashed_normal, hashed_uniform, smoothstep

__all__ = ["LiveSource", "GraspLiveSource", "CalibrationLiveSource", "TwoFingerLiveSource", "default_live_source"]


def _times(t) -> np.ndarray:
    t = np.atleast_1d(np.asarray(t, dtype=float))
    if t.ndim != 1:
        raise ValueError(f"t: expected shape (n,) of times in s, got {t.shape}")
    if not np.all(np.isfinite(t)):
        raise ValueError("t: expected finite times in s")
    return t


class LiveSource:
    """Common part of the live sources (a cube, a reference, seeded noise).

    Attributes
    ----------
    model : VirtualCube
    rate : float
        The cube's sample rate, Hz (noise is keyed by ``round(t · rate)``).
    T_core_ati : ndarray, shape (4, 4)
        Pose of the reference frame in the core frame.
    counts_range : (int, int)
        ADC limits, counts.
    label : str
        What a device or screen should call this source (says "simulated").
    """

    label = "simulated cube (pito_core.sim)"

    def __init__(self, model: VirtualCube | None, seed: int, T_core_ati, reference="delta"):
        if model is None:
            model = VirtualCube()
        if not isinstance(model, VirtualCube):
            raise ValueError(f"model: expected a VirtualCube, got {type(model).__name__}")
        self.model = model
        self.seed = int(seed)
        self.rate = model.params.rate
        self.reference_sensor = ReferenceSensor(T_core_ati, reference)
        self.T_core_ati = self.reference_sensor.T_core_ati
        self.counts_range = model.counts_range

    def _index(self, t: np.ndarray) -> np.ndarray:
        return np.rint(t * self.rate).astype(np.int64)

    def _counts(self, t, F, W_frame=None, slip=None) -> np.ndarray:
        noise = hashed_normal(self.seed, self._index(t), N_GAUGES, stream=1)
        return self.model.counts_from_face_wrenches(F, t, W_frame=W_frame, frame_slip=slip, noise=noise)

    def _reference(self, t, W_core) -> np.ndarray:
        noise = hashed_normal(self.seed, self._index(t), 6, stream=2)
        return self.reference_sensor.measure(W_core, noise=noise)


class GraspLiveSource(LiveSource):
    """A hand grasping the object in a loop (the free-grasp load path), for demos and devices.

    One 12 s loop: the object rests on a table on face 6, fingers touch their patches,
    push in and squeeze, lift and move it, put it down and let go (:class:`GraspScenario`).
    The reference sensor sits under the table plate (``T_core_ati`` under face 6) and reads
    the table's load on the object (zero while lifted).

    Parameters
    ----------
    seed : int
        Noise and contact-point jitter.
    model : VirtualCube, optional
        The cube (default ``VirtualCube()``).
    n_fingers : {2, 3, 4, 5}
    mass : float
        kg.
    assembly : str, optional
        Patch assembly of ``pito_core.contact`` (e.g. "cube", "sphere", "pito_mixed") whose
        surfaces the fingers touch; default flat patches.
    reference : {"delta", "nano17"}
    hold : float, optional
        Loads held at this time of the loop, s (e.g. 0.5: the object at rest on the table, hands
        off); the gauges' noise and drift still run with time.
    """

    def __init__(self, seed: int = 0, model: VirtualCube | None = None, *, n_fingers: int = 3, mass: float = 0.3,
                 assembly: str | None = None, reference="delta", hold: float | None = None):
        model = VirtualCube() if model is None else model
        super().__init__(model, seed, reference_pose("face", 6, model.core), reference)
        contacts = None
        if assembly is not None:
            contacts = contacts_on_assembly(assembly, n_fingers, seed)
        self.assembly = assembly
        self.label = f"simulated cube (pito_core.sim): looping grasp, {n_fingers} fingers" + (
            f" on {assembly!r}" if assembly else "")
        self.scenario = GraspScenario(mass=mass, n_fingers=n_fingers, seed=seed, core=model.core, contacts=contacts)
        self.period = 12.0
        self.hold = None if hold is None else float(hold)
        if self.hold is not None:
            self.label += f", held at {self.hold:g} s of the loop"

    def truth_at(self, t) -> GraspState:
        """Loads, gravity and acceleration at times ``t (n,)`` s (see :class:`GraspState`)."""
        t = _times(t)
        return self.scenario.state(t if self.hold is None else np.full_like(t, self.hold))

    def face_wrenches_at(self, t) -> np.ndarray:
        """True wrench on each face ``(n, 6, 6)``, face frames, N and N·m."""
        return self.truth_at(t).face_wrenches

    def contacts_at(self, t) -> dict:
        """Finger contacts at times ``t (n,)``, in the face frames.

        Returns
        -------
        dict
            ``names`` (K,), ``face (K,)`` 1..6, ``point (K, 3)`` m and ``normal (K, 3)``
            (outward) on the patch surface, ``force (n, K, 3)`` N (finger on patch),
            ``torsion (n, K)`` N·m, ``active (n, K)`` bool.
        """
        st = self.truth_at(t)
        sc = self.scenario
        R = self.model.core.face_poses()[sc.contact_faces - 1, :3, :3]
        force = np.einsum("kba,nkb->nka", R, st.finger_force)  # core -> face frame
        return {
            "names": list(sc.names),
            "face": sc.contact_faces.copy(),
            "point": sc.points_face.copy(),
            "normal": sc.normals_face.copy(),
            "force": force,
            "torsion": st.finger_torsion,
            "active": st.finger_active,
        }

    def counts_at(self, t) -> np.ndarray:
        """Gauge counts ``(n, 36)`` int32 at times ``t (n,)`` s."""
        t = _times(t)
        return self._counts(t, self.truth_at(t).face_wrenches)

    def reference_at(self, t) -> np.ndarray:
        """Reference reading ``(n, 6)`` (N, N·m, reference frame): the table's load on the object."""
        t = _times(t)
        return self._reference(t, self.truth_at(t).table_wrench)


class CalibrationLiveSource(LiveSource):
    """An operator loading one face at a time under a calibration mount.

    Set :attr:`face` (or call :meth:`set_face` with the switch time, to fade the load in
    from zero) to the face being loaded (None: nobody touches the object). The load
    on that face moves between random keypoints (±15 N, ±0.1 N·m per axis, face frame)
    every ``period`` seconds and holds still for the last ``1 − ramp`` of each period, so a
    wizard can capture still, new samples. Keypoints depend on (seed, face, period index)
    only.

    Parameters
    ----------
    flange : {"frame", "frame_hole", "face"}
    connected_face : int
    seed : int
    model : VirtualCube, optional
    period : float
        s per move-and-hold.
    ramp : float
        Fraction of a period spent moving.
    reference : {"delta", "nano17"}
    """

    def __init__(self, flange: str = "face", connected_face: int = 6, seed: int = 0, model: VirtualCube | None = None,
                 *, period: float = 1.5, ramp: float = 0.5, reference="delta"):
        flange, connected_face = check_flanged_mount(flange, connected_face)
        model = VirtualCube() if model is None else model
        super().__init__(model, seed, reference_pose(flange, connected_face, model.core), reference)
        if not period > 0:
            raise ValueError(f"period: expected a positive duration in s, got {period!r}")
        if not 0 < ramp < 1:
            raise ValueError(f"ramp: expected a fraction in (0, 1), got {ramp!r}")
        self.flange = flange
        self.connected_face = connected_face
        self.label = f"simulated cube (pito_core.sim): calibration, {flange} flange on face {connected_face}"
        self.period = float(period)
        self.ramp = float(ramp)
        self._face = None
        self._t_switch = None
        self._X = core_from_face_adjoints(model.core)

    @property
    def face(self):
        """The face being loaded (1..6), or None when the object is unloaded."""
        return self._face

    @face.setter
    def face(self, value):
        self.set_face(value)

    def set_face(self, face, t=None) -> None:
        """Load ``face`` (1..6, or None to unload) from time ``t`` (s).

        With ``t`` the operator starts from zero: the load fades in over one ramp
        (``ramp · period``) after ``t``; without it the new face's load applies at once.
        """
        if face is None:
            self._face, self._t_switch = None, None
            return
        f = check_face(face, "face")
        if self.flange == "frame" and f == self.connected_face:
            raise ValueError(f"face: face {f} is connected to a 'frame' flange and cannot be loaded")
        if t is not None and not np.isfinite(float(t)):
            raise ValueError(f"t: expected a finite time in s, got {t!r}")
        self._face = f
        self._t_switch = None if t is None else float(t)

    def _keypoints(self, m: np.ndarray, face: int) -> np.ndarray:
        u = hashed_uniform(self.seed, m, 6, stream=100 + face)
        kp = (2.0 * u - 1.0) * np.asarray(FULL_SCALE_FACE)
        return np.where((m < 0)[:, None], 0.0, kp)

    def is_still(self, t) -> np.ndarray:
        """``(n,)`` bool: the load holds still at times ``t`` (hold part of a period)."""
        t = _times(t)
        return np.mod(t, self.period) >= self.ramp * self.period

    def applied_at(self, t, face=None) -> np.ndarray:
        """Load on ``face`` (default :attr:`face`) in its frame ``(n, 6)``, N and N·m; zeros if None."""
        t = _times(t)
        face = self._face if face is None else check_face(face, "face")
        if face is None:
            return np.zeros((t.size, 6))
        m = np.floor(t / self.period).astype(np.int64)
        s = smoothstep(np.mod(t, self.period) / (self.ramp * self.period))[:, None]
        a, b = self._keypoints(m - 1, face), self._keypoints(m, face)
        w = a * (1 - s) + b * s
        if self._t_switch is not None and face == self._face:
            w = w * smoothstep((t - self._t_switch) / (self.ramp * self.period))[:, None]
        return w

    def _loads(self, t):
        t = _times(t)
        n = t.size
        applied = np.zeros((n, 6, 6))
        face = self._face
        slip = None
        if face is not None:
            X = self._X[face - 1]
            applied[:, face - 1] = self.applied_at(t, face) @ X.T
        F, W_total, W_frame = face_wrenches_from_applied(applied, self.flange, self.connected_face, self.model.core)
        if W_frame is not None:
            slip = np.zeros((n, 6))
            if face is not None:
                # joint slip: within a move the play operator is clip(y_start, u − r, u + r)
                # (exact for monotone moves); y_start is carried through the last few
                # keypoints from an estimate that trails the older keypoint by the play
                r = self.model.params.frame_play
                m = np.floor(t / self.period).astype(np.int64)
                X = self._X[face - 1]
                fs = np.asarray(FULL_SCALE_FRAME)

                def U(j):
                    return (self._keypoints(j, face) @ X.T) / fs

                L = 8
                y_start = U(m - L - 1) - r * np.sign(U(m - L - 1) - U(m - L - 2))
                for j in range(L, 0, -1):
                    Uj = U(m - j)
                    y_start = np.clip(y_start, Uj - r, Uj + r)
                u = W_frame / fs
                y = np.clip(y_start, u - r, u + r)
                slip = (u - y) / r
        return t, F, W_total, W_frame, slip

    def face_wrenches_at(self, t) -> np.ndarray:
        """True wrench on each face ``(n, 6, 6)``, face frames (load paths of the mount)."""
        return self._loads(t)[1]

    def counts_at(self, t) -> np.ndarray:
        """Gauge counts ``(n, 36)`` int32 at times ``t (n,)`` s, under the current :attr:`face`."""
        t, F, _, W_frame, slip = self._loads(t)
        return self._counts(t, F, W_frame, slip)

    def reference_at(self, t) -> np.ndarray:
        """Reference reading ``(n, 6)`` (N, N·m, reference frame, tared): the total applied load."""
        t, _, W_total, _, _ = self._loads(t)
        return self._reference(t, W_total)

    def loaded_at(self, t) -> np.ndarray:
        """``(n, 6)`` bool: the loaded mask a wizard would record."""
        t = _times(t)
        out = np.zeros((t.size, 6), dtype=bool)
        if self._face is not None:
            out[:, self._face - 1] = True
        return out


def default_live_source(seed: int = 0) -> GraspLiveSource:
    """The demo's source: :class:`GraspLiveSource` on the default cube."""
    return GraspLiveSource(seed=seed)




class TwoFingerLiveSource(LiveSource):
    """Two fingers on one patch, twisting, for a demo of the single-contact flag (SIMULATED).

    The object (``mass`` kg, centre of gravity at the core centre) rests on a table on face 6;
    two fingers touch face 1's patch 30 mm apart (face 1's y, the core's vertical), each
    pushing ``push`` N in and ``shear`` N along face 1's x, in opposite directions — a twist
    of ``2 · 0.015 · shear`` N·m about face 1's normal, beyond what one fingertip's friction
    gives (``|τ| ≤ μ e f_n``, ``pito_core.contact``); a thumb on face 3 pushes back ``2 · push`` N.
    The table (under face 6, where the reference sensor reads it) balances the rest. The loads
    swell in and out over ``period`` s (between 40 % and 100 %).
    """

    def __init__(self, seed: int = 0, model: VirtualCube | None = None, *, mass: float = 0.3, push: float = 2.5,
                 shear: float = 1.5, period: float = 6.0, reference="delta"):
        model = VirtualCube() if model is None else model
        super().__init__(model, seed, reference_pose("face", 6, model.core), reference)
        self.label = "simulated cube (pito_core.sim): two fingers twisting on face 1's patch"
        self.mass, self.period = float(mass), float(period)
        h = 0.003  # m: the flat patch's surface above the face
        pts = np.array([[0.0, 0.015, h], [0.0, -0.015, h]])  # face 1's frame
        fs = np.array([[shear, 0.0, -push], [-shear, 0.0, -push]])
        W = np.zeros((6, 6))
        W[0] = np.r_[fs.sum(axis=0), np.cross(pts, fs).sum(axis=0)]
        W[2] = np.r_[0.0, 0.0, -2 * push, 0.0, 0.0, 0.0]  # the thumb at face 3's centre
        X = core_from_face_adjoints(model.core)
        self._unit = W
        self._X_face6 = np.linalg.inv(X[5])
        self._X = X

    def face_wrenches_at(self, t) -> np.ndarray:
        """True wrench on each face ``(n, 6, 6)``, face frames, N and N·m."""
        return self._loads(_times(t))[0]

    def _loads(self, t):
        s = 0.7 + 0.3 * np.cos(2 * np.pi * t / self.period)  # (n,) 0.4..1.0
        W = s[:, None, None] * self._unit  # fingers and thumb, face frames
        core = np.einsum("kij,nkj->ni", self._X, W)  # their sum in the core frame, about the core centre
        gravity = np.r_[0.0, 0.0, -9.81 * self.mass, 0.0, 0.0, 0.0]
        table = -(core + gravity)  # (n, 6) the table's load on the object, core frame
        W = W.copy()
        W[:, 5] = table @ self._X_face6.T
        return W, table

    def counts_at(self, t) -> np.ndarray:
        """Gauge counts ``(n, 36)`` int32 at times ``t (n,)`` s."""
        t = _times(t)
        return self._counts(t, self._loads(t)[0])

    def reference_at(self, t) -> np.ndarray:
        """Reference reading ``(n, 6)`` (N, N·m, reference frame): the table's load on the object."""
        t = _times(t)
        return self._reference(t, self._loads(t)[1])

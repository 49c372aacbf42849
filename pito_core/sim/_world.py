"""The demo's simulated world: one live source the two simulated devices read, steered by scenario.

:class:`DemoWorld` holds the virtual cube and its two scenarios — ``grasp`` (a hand grasps,
lifts and moves the object: the live view) and ``calibration`` (the cube on a flange, a
simulated operator loading one face at a time: the wizard) — and switches between them on
the *simulated* clock, so the cube and the reference never disagree about a sample. It runs
inside the simulated-devices process (:mod:`pito_core.sim._process`) and is steered through
that process's control channel.
"""

from __future__ import annotations

import time

import numpy as np

from ._live import CalibrationLiveSource, GraspLiveSource, TwoFingerLiveSource
from ._model import VirtualCube
from ._mount import check_mount

__all__ = ["DemoWorld", "SwitchedLiveSource", "SCENARIOS"]

#: Scenarios of :class:`DemoWorld`: the grasp loop, the object at rest on the table (hands off:
#: a tare at rest can be taken and undone), two fingers twisting on one patch (a contact one
#: fingertip cannot explain: the single-contact flag), the cube on a calibration flange.
SCENARIOS = ("grasp", "rest", "two_fingers", "calibration")

#: Loop time (s) the ``rest`` scenario holds: the object on the table before the fingers touch.
REST_HOLD = 0.5


class SwitchedLiveSource:
    """A live source switched on the *simulated* clock.

    The two simulated devices compute their samples in their own threads, sometimes late
    (a busy CPU) and then for past times. A switch (scenario, face being loaded) therefore
    takes effect from a simulated time on: a sample of an earlier time still comes from the
    source that was active then, so the cube and the reference never disagree about it.

    Parameters
    ----------
    source : live source
        Active from the start.
    clock : callable
        ``clock() -> float``: the current simulated time, s.
    """

    def __init__(self, source, clock):
        self.clock = clock
        self._schedule = [(-np.inf, source)]  # (from time s, source), in order

    @property
    def active(self):
        return self._schedule[-1][1]

    @active.setter
    def active(self, source):
        now = self.clock()
        self._schedule = [seg for seg in self._schedule if seg[0] < now][-4:] + [(now, source)]

    def _split(self, t, method: str):
        t = np.atleast_1d(np.asarray(t, dtype=float))
        sched = self._schedule
        if t.size == 0 or t.min() >= sched[-1][0]:
            return getattr(sched[-1][1], method)(t)
        starts = np.array([s for s, _ in sched])
        which = np.searchsorted(starts, t, side="right") - 1
        out = None
        for k in np.unique(which):
            m = which == k
            part = getattr(sched[k][1], method)(t[m])
            if out is None:
                out = np.empty((t.size,) + part.shape[1:], dtype=part.dtype)
            out[m] = part
        return out

    def counts_at(self, t):
        """Gauge counts ``(n, 36)`` at simulated times ``t (n,)`` s, from the source active then."""
        return self._split(t, "counts_at")

    def reference_at(self, t):
        """Reference wrench ``(n, 6)`` (N, N·m) at simulated times ``t (n,)`` s."""
        return self._split(t, "reference_at")


class DemoWorld:
    """The virtual cube under the demo's two scenarios (see module docstring).

    Parameters
    ----------
    seed : int
        Noise, contact jitter and operator keypoints.
    speed : float
        Simulated seconds per wall second (the devices' clock).
    period : float
        Seconds per move-and-hold of the simulated operator.
    epoch : float, optional
        ``time.monotonic()`` at simulated time 0 (shared with the simulated devices).
    """

    def __init__(self, seed: int = 0, speed: float = 1.0, period: float = 1.5, epoch: float | None = None):
        self.seed = int(seed)
        self.speed = float(speed)
        self.period = float(period)
        self.epoch = time.monotonic() if epoch is None else float(epoch)
        self.model = VirtualCube()
        self.assembly_name = None
        self.grasp = GraspLiveSource(seed=self.seed, model=self.model)
        self.rest = GraspLiveSource(seed=self.seed, model=self.model, hold=REST_HOLD)
        self.two_fingers = TwoFingerLiveSource(seed=self.seed, model=self.model)
        self.flange, self.connected_face = "face", 6
        self.operator_face = None
        self._cal_sources: dict = {}
        self.calibration = self._calibration_source(None)
        self.source = SwitchedLiveSource(self.grasp, self.sim_time)
        self.scenario = "grasp"

    def sim_time(self) -> float:
        """The simulated devices' clock, s (the same for the cube and the reference)."""
        return (time.monotonic() - self.epoch) * self.speed

    def _calibration_source(self, face):
        key = (self.flange, self.connected_face, face)
        if key not in self._cal_sources:
            src = CalibrationLiveSource(self.flange, self.connected_face, seed=self.seed, model=self.model,
                                        period=self.period)
            src.face = face
            self._cal_sources[key] = src
        return self._cal_sources[key]

    def _scenario_source(self, name: str):
        return {"grasp": self.grasp, "rest": self.rest, "two_fingers": self.two_fingers}.get(name, self.calibration)

    def set_scenario(self, name: str) -> None:
        """One of :data:`SCENARIOS`, from the current simulated time on."""
        if name not in SCENARIOS:
            raise ValueError(f"scenario: expected one of {SCENARIOS}, got {name!r}")
        self.scenario = name
        self.source.active = self._scenario_source(name)

    def set_mount(self, flange: str, connected_face: int) -> None:
        """The calibration mount: ``flange`` ('frame', 'frame_hole', 'face') on ``connected_face`` 1..6."""
        if (flange, connected_face) == (self.flange, self.connected_face):
            return
        flange, connected_face = check_mount(flange, connected_face)
        self.flange, self.connected_face = flange, connected_face
        face = self.operator_face
        if flange == "frame" and face == connected_face:
            face = None
        self.set_operator_face(face)

    def set_operator_face(self, face) -> None:
        """The simulated operator loads ``face`` (1..6; None: hands off), from the current simulated time on."""
        self.operator_face = None if face is None else int(face)
        self.calibration = self._calibration_source(self.operator_face)
        if self.scenario == "calibration":
            self.source.active = self.calibration

    def set_assembly(self, name: str | None) -> None:
        """Fingers of the grasp touch the patches of library assembly ``name`` (None: flat patches).

        Raises
        ------
        ValueError
            ``name`` is not an assembly of the patch library.
        """
        if name == self.assembly_name:
            return
        self.grasp = GraspLiveSource(seed=self.seed, model=self.model, assembly=name)
        self.rest = GraspLiveSource(seed=self.seed, model=self.model, assembly=name, hold=REST_HOLD)
        self.assembly_name = name
        if self.scenario in ("grasp", "rest"):
            self.source.active = self._scenario_source(self.scenario)

    def state(self) -> dict:
        """What the world is doing (JSON-serialisable)."""
        return {"scenario": self.scenario, "flange": self.flange, "connected_face": self.connected_face,
                "operator_face": self.operator_face, "assembly": self.assembly_name, "sim_time": self.sim_time(),
                "speed": self.speed, "seed": self.seed, "period": self.period}

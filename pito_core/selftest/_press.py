"""The units-and-signs press test: does the calibration read what the operator did?

The operator, guided step by step, (1) presses face i along its normal, into the cube, then
(2) twists it counter-clockwise seen from outside the face (a torque along the outward
normal). With the calibration, each step must read a wrench on face i whose largest force
(press) or torque (twist) component is along the face's normal, with the expected sign:
press → ``fz < 0`` in the face frame, twist → ``tz > 0`` (docs/conventions.md: z is the outward
normal). A wrong sign names a flipped axis; a different dominant axis names swapped axes.
Pure numpy; no timing, no GUI (the app's dialog is ``app/press_test.py``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..frames import N_GAUGES, WRENCH_COMPONENTS, invert_pose

__all__ = ["PressStep", "StepCheck", "PressTestResult", "PRESS_PROTOCOL", "check_press_test"]

AXES = WRENCH_COMPONENTS


@dataclass(frozen=True)
class PressStep:
    """One guided step: load ``face`` so that its wrench (face frame) points along ``direction``.

    ``direction`` is a (6,) unit vector in ``[fx, fy, fz, tx, ty, tz]`` with one non-zero entry.
    """

    face: int
    action: str  # "press" or "twist" (or "shear x" / "shear y")
    direction: tuple
    instruction: str


def _protocol() -> tuple:
    steps = []
    for f in range(1, 7):
        steps.append(PressStep(f, "press", (0, 0, -1, 0, 0, 0), f"Press face {f} straight in along its normal (a few N)."))
        steps.append(PressStep(f, "twist", (0, 0, 0, 0, 0, 1),
                               f"Twist face {f} counter-clockwise, seen from outside the face (a few N·cm)."))
    return tuple(steps)


#: The guided protocol: for each face 1..6, a press along the normal then a twist about it.
PRESS_PROTOCOL = _protocol()


@dataclass(frozen=True)
class StepCheck:
    """What one step read and what it means.

    Attributes
    ----------
    step : PressStep
    measured : ndarray (6,)
        Median wrench of face ``step.face`` over the step's loaded samples (face frame, N and N·m),
        relative to the rest before the test.
    axis_expected, axis_measured : str
        The expected and the dominant component (among forces for a press, torques for a twist).
    ok : bool
    finding : str
        One sentence: "ok", or which axis is flipped / swapped, or "too weak".
    """

    step: PressStep
    measured: np.ndarray
    axis_expected: str
    axis_measured: str
    ok: bool
    finding: str


@dataclass
class PressTestResult:
    checks: list = field(default_factory=list)

    @property
    def passed(self) -> bool:
        return bool(self.checks) and all(c.ok for c in self.checks)

    @property
    def findings(self) -> list:
        """The failed steps' sentences (empty when the test passed)."""
        return [c.finding for c in self.checks if not c.ok]

    def summary(self) -> str:
        if self.passed:
            return f"press test passed: {len(self.checks)} steps read the expected axis and sign"
        return "press test FAILED: " + "; ".join(self.findings)


def _face_wrench(cal, counts, rest, face: int) -> np.ndarray:
    """(N, 6) face wrench in the face frame (N, N·m), from counts and the rest counts."""
    W = cal.wrenches(np.atleast_2d(np.asarray(counts, dtype=float)), offset=np.asarray(rest, dtype=float))
    w = W[:, face - 1, :]
    if cal.output_frame == "reference":  # rotate back into the face frame (forces and torques alike)
        R = (invert_pose(cal.T_core_ati) @ cal.core.face_pose(face))[:3, :3]
        w = np.concatenate([w[:, :3] @ R, w[:, 3:] @ R], axis=1)  # (Rᵀ v) for each row
    return w


def check_press_test(cal, rest_counts, step_counts, steps=PRESS_PROTOCOL, *, min_force: float = 1.0,
                     min_torque: float = 0.02, dominance: float = 1.5) -> PressTestResult:
    """Check a calibration's signs and axes against a guided press test.

    Parameters
    ----------
    cal : Calibration
    rest_counts : array-like (M, 36) or (36,)
        Counts at rest just before the test (their mean is the offset).
    step_counts : sequence of array-like (N_k, 36)
        Counts recorded during each step of ``steps`` (same order).
    steps : sequence of PressStep
        Default :data:`PRESS_PROTOCOL`.
    min_force : float
        N; a press reading less on face i is "too weak" (the operator did not press, or the
        face has no output). Default 1 N.
    min_torque : float
        N·m, likewise for a twist; default 0.02 N·m.
    dominance : float
        The expected component must exceed every other force (torque) component by this
        factor to count as dominant, default 1.5.

    Returns
    -------
    PressTestResult
        ``.passed``, ``.findings`` (e.g. "face 3: fz is flipped: the press read fz = +4.1 N, expected < 0").
    """
    rest = np.atleast_2d(np.asarray(rest_counts, dtype=float))
    if rest.shape[1:] != (N_GAUGES,):
        raise ValueError(f"rest_counts: expected shape (M, {N_GAUGES}), got {rest.shape}")
    if len(step_counts) != len(steps):
        raise ValueError(f"step_counts: expected {len(steps)} steps (one per step of the protocol), got {len(step_counts)}")
    offset = rest.mean(axis=0)
    result = PressTestResult()
    for step, counts in zip(steps, step_counts):
        c = np.atleast_2d(np.asarray(counts, dtype=float))
        if c.ndim != 2 or c.shape[1] != N_GAUGES or c.shape[0] == 0:
            raise ValueError(f"step_counts (face {step.face}, {step.action}): expected shape (N>0, {N_GAUGES}), got {c.shape}")
        d = np.asarray(step.direction, dtype=float)
        k = int(np.flatnonzero(d)[0])
        part = slice(0, 3) if k < 3 else slice(3, 6)
        unit, floor = ("N", min_force) if k < 3 else ("N·m", min_torque)
        w = _face_wrench(cal, c, offset, step.face)
        if not np.all(np.isfinite(w)):
            result.checks.append(StepCheck(step, np.full(6, np.nan), AXES[k], "-", False,
                                           f"face {step.face}: the calibration has no output for this face"))
            continue
        mag = np.linalg.norm(w[:, part], axis=1)
        loaded = mag >= 0.5 * mag.max() if mag.size else mag
        m = np.median(w[loaded], axis=0)
        comp = m[part]
        j = int(np.argmax(np.abs(comp))) + part.start
        others = np.delete(np.abs(comp), k - part.start)
        if np.abs(m[j]) < floor:
            ok, finding = False, (f"face {step.face} ({step.action}): too weak to judge, largest {AXES[j]} = "
                                  f"{m[j]:+.3g} {unit} (need ≥ {floor:g} {unit}); repeat the step")
        elif j != k or (others.size and abs(m[k]) < dominance * others.max()):
            ok, finding = False, (f"face {step.face} ({step.action}): axes swapped: the {step.action} along "
                                  f"{AXES[k]} reads mostly on {AXES[j]} ({m[j]:+.3g} {unit}; {AXES[k]} = {m[k]:+.3g} {unit})")
        elif np.sign(m[k]) != np.sign(d[k]):
            ok, finding = False, (f"face {step.face}: {AXES[k]} is flipped: the {step.action} read {AXES[k]} = "
                                  f"{m[k]:+.3g} {unit}, expected {'< 0' if d[k] < 0 else '> 0'}")
        else:
            ok, finding = True, f"face {step.face} ({step.action}): ok, {AXES[k]} = {m[k]:+.3g} {unit}"
        result.checks.append(StepCheck(step, m, AXES[k], AXES[j], ok, finding))
    return result

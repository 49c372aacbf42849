"""The simulated reference: an ATI Delta or Nano17 under the flange, in its own frame."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..frames import CubeCore, check_face, check_pose, wrench_adjoint

__all__ = ["ReferenceSpec", "REFERENCE_PRESETS", "ReferenceSensor", "reference_pose", "FLANGE_HEIGHT"]


@dataclass(frozen=True)
class ReferenceSpec:
    """Data-sheet figures of a 6-axis reference sensor (``[fx, fy, fz, tx, ty, tz]`` order).

    Attributes
    ----------
    name : str
    range : tuple of 6 float
        Sensing range, N and N·m (readings saturate beyond it).
    resolution : tuple of 6 float
        Data-sheet resolution, N and N·m; the simulated noise is Gaussian with σ = half of it.
    step : tuple of 6 float
        Output quantisation (1 / counts-per-unit of the transducer's output), N and N·m.
    """

    name: str
    range: tuple
    resolution: tuple
    step: tuple


#: ATI Delta SI-165-15 (the PITO paper's reference) and Nano17 SI-25-0.25 (data-sheet values).
REFERENCE_PRESETS = {
    "delta": ReferenceSpec(
        "ATI Delta SI-165-15",
        (165.0, 165.0, 495.0, 15.0, 15.0, 15.0),
        (1 / 32, 1 / 32, 1 / 16, 1 / 1333, 1 / 1333, 1 / 1333),
        (1 / 1024, 1 / 1024, 1 / 1024, 1 / 40000, 1 / 40000, 1 / 40000),
    ),
    "nano17": ReferenceSpec(
        "ATI Nano17 SI-25-0.25",
        (25.0, 25.0, 35.0, 0.25, 0.25, 0.25),
        (1 / 160, 1 / 160, 1 / 160, 1 / 32000, 1 / 32000, 1 / 32000),
        (1 / 6400, 1 / 6400, 1 / 6400, 1 / 1_000_000, 1 / 1_000_000, 1 / 1_000_000),
    ),
}

#: Distance from the face (or frame) surface to the reference's sensing origin, m, per flange.
FLANGE_HEIGHT = {"frame": 0.012, "frame_hole": 0.012, "face": 0.008}


def reference_pose(flange: str, connected_face: int, core: CubeCore | None = None) -> np.ndarray:
    """``T_core_ati (4, 4)``: the reference's frame S_A under a flange on ``connected_face``.

    The origin is on the connected face's outward normal, ``edge/2 + FLANGE_HEIGHT[flange]``
    from the core centre; z points back toward the cube (−normal), x is the connected face's
    x axis and y is minus its y axis (a half turn about the face's x axis).
    """
    if flange not in FLANGE_HEIGHT:
        raise ValueError(f"flange: expected one of {tuple(FLANGE_HEIGHT)}, got {flange!r}")
    c = check_face(connected_face, "connected_face")
    core = CubeCore() if core is None else core
    T_face = core.face_pose(c)
    T = np.eye(4)
    T[:3, 0] = T_face[:3, 0]
    T[:3, 1] = -T_face[:3, 1]
    T[:3, 2] = -T_face[:3, 2]
    T[:3, 3] = T_face[:3, 2] * (core.edge / 2 + FLANGE_HEIGHT[flange])
    return T


class ReferenceSensor:
    """A tared reference sensor reading the total applied load in its own frame.

    Parameters
    ----------
    T_core_ati : array-like, shape (4, 4)
        Pose of the sensor's frame in the core frame.
    model : {"delta", "nano17"} or ReferenceSpec
        Data sheet (default the ATI Delta).
    """

    def __init__(self, T_core_ati, model="delta"):
        self.T_core_ati = check_pose(T_core_ati, "T_core_ati")
        if isinstance(model, str):
            if model not in REFERENCE_PRESETS:
                raise ValueError(f"model: expected one of {tuple(REFERENCE_PRESETS)}, got {model!r}")
            model = REFERENCE_PRESETS[model]
        if not isinstance(model, ReferenceSpec):
            raise ValueError(f"model: expected a preset name or a ReferenceSpec, got {type(model).__name__}")
        self.spec = model
        self._X = wrench_adjoint(self.T_core_ati)

    def __repr__(self) -> str:
        return f"ReferenceSensor({self.spec.name!r})"

    def ideal(self, W_core) -> np.ndarray:
        """The load ``(N, 6)`` in the sensor's frame, noise free (N, N·m)."""
        return np.asarray(W_core, dtype=float) @ self._X.T

    def measure(self, W_core, *, noise=None, rng=None) -> np.ndarray:
        """Reading ``(N, 6)`` of the total applied load ``W_core (N, 6)`` (core frame, N, N·m).

        Adds Gaussian noise (σ = resolution / 2; ``noise`` gives standard-normal draws
        ``(N, 6)``, else ``rng``), quantises to the output step and saturates at the range.
        """
        ideal = self.ideal(W_core)
        if noise is None:
            rng = np.random.default_rng(0xA71) if rng is None else rng
            noise = rng.standard_normal(ideal.shape)
        res = np.asarray(self.spec.resolution)
        step = np.asarray(self.spec.step)
        rg = np.asarray(self.spec.range)
        out = ideal + 0.5 * res * np.asarray(noise)
        out = np.rint(out / step) * step
        return np.clip(out, -rg, rg)

"""The simulated cube and reference: stands in for the hardware in tests, demo mode and benchmarks.

Nothing here is measured: every array comes from a seeded physical model
(docs/simulator.md). ``pito_core.sim`` imports the session *format* only, never the
calibration code.
"""

from typing import TYPE_CHECKING

from .._lazy import attach

if TYPE_CHECKING:  # re-exported, each loaded on first use (pito_core/_lazy.py)
    from ._grasp import FINGER_LAYOUTS, GRAVITY, GraspRun, GraspScenario, GraspState, simulate_free_grasp
    from ._lift import LIFT_HEIGHT, LIFT_TIMELINE, LIFT_TRIAL_S, LiftTask, LiftTruth, write_lift_recording
    from ._handfed import IdleDevice, push_samples
    from ._live import CalibrationLiveSource, GraspLiveSource, LiveSource, default_live_source
    from ._model import VirtualCube, hub_sensitivity
    from ._mount import MOUNTS, face_wrenches_from_applied
    from ._params import FULL_SCALE_FACE, FULL_SCALE_FRAME, SimParams
    from ._protocols import (
        PATCH_HEIGHT,
        PATCH_SIZE,
        SQUEEZE_PAIRS,
        TOUCH_POINTS,
        SimTruth,
        default_faces,
        simulate_calibration,
        simulate_squeeze,
    )
    from ._random_sensor import RandomSensor, random_sensor, random_sensor_session
    from ._reference import FLANGE_HEIGHT, REFERENCE_PRESETS, ReferenceSensor, ReferenceSpec, reference_pose
    from ._signals import KeypointTrajectory, play_operator
    from ._touches import TouchTruth, simulate_touches
    from ._world import SCENARIOS, DemoWorld, SwitchedLiveSource
    from ._launch import DevicesLaunch
    from ._process import SimulatedDevices, SimulatorError, run_devices
    from ._transport import open_simulated_devices
    from ._transport_netft import SimulatedNetFT
    from ._transport_pito import SimulatedPitoPort
    from ._transport_source import Source, TestSignalSource, default_simulated_source

__getattr__, __dir__ = attach(__name__, __file__)

__all__ = [
    "LIFT_HEIGHT",
    "LIFT_TIMELINE",
    "LIFT_TRIAL_S",
    "LiftTask",
    "LiftTruth",
    "write_lift_recording",
    "RandomSensor",
    "random_sensor",
    "random_sensor_session",
    "DemoWorld",
    "SCENARIOS",
    "DevicesLaunch",
    "SimulatedDevices",
    "SimulatorError",
    "SwitchedLiveSource",
    "run_devices",
    "SimulatedNetFT",
    "SimulatedPitoPort",
    "Source",
    "TestSignalSource",
    "default_simulated_source",
    "open_simulated_devices",
    "CalibrationLiveSource",
    "FINGER_LAYOUTS",
    "GraspLiveSource",
    "LiveSource",
    "default_live_source",
    "FLANGE_HEIGHT",
    "FULL_SCALE_FACE",
    "FULL_SCALE_FRAME",
    "GRAVITY",
    "GraspRun",
    "GraspScenario",
    "GraspState",
    "IdleDevice",
    "KeypointTrajectory",
    "MOUNTS",
    "PATCH_HEIGHT",
    "PATCH_SIZE",
    "REFERENCE_PRESETS",
    "ReferenceSensor",
    "ReferenceSpec",
    "SQUEEZE_PAIRS",
    "SimParams",
    "SimTruth",
    "TOUCH_POINTS",
    "TouchTruth",
    "VirtualCube",
    "default_faces",
    "face_wrenches_from_applied",
    "hub_sensitivity",
    "play_operator",
    "push_samples",
    "reference_pose",
    "simulate_calibration",
    "simulate_free_grasp",
    "simulate_squeeze",
    "simulate_touches",
]

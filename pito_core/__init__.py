"""pito: calibration, intrinsic contact sensing and recording for the PITO cube (headless core).

The most used public names are re-exported here: ``transform_wrench``, ``CubeCore``,
``CalibrationSession``, ``calibrate``, ``Calibration``, ``load_calibration``.
"""

from .calibration import Calibration, CalibrationSession, Calibrator, calibrate, load_calibration
from .frames import CubeCore, transform_wrench

from ._version import __version__

__all__ = [
    "Calibration",
    "CalibrationSession",
    "Calibrator",
    "CubeCore",
    "calibrate",
    "load_calibration",
    "transform_wrench",
    "__version__",
]

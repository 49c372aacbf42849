"""pito: calibration, intrinsic contact sensing and recording for the PITO cube (headless core).

The most used public names are re-exported here: ``transform_wrench``, ``CubeCore``,
``CalibrationSession``, ``calibrate``, ``Calibration``, ``load_calibration``. They load on first
use, as every package's re-exports (:mod:`pito_core._lazy`): ``import pito_core.sim`` or
``import pito_core.devices`` does not pay for the calibration code and scipy, so the demo's
device processes start sooner (docs/app.md, "Start-up").
"""

from typing import TYPE_CHECKING

from ._lazy import attach
from ._version import __version__

if TYPE_CHECKING:  # re-exported, each loaded on first use (pito_core/_lazy.py)
    from .calibration import Calibration, CalibrationSession, Calibrator, calibrate, load_calibration
    from .frames import CubeCore, transform_wrench

__getattr__, __dir__ = attach(__name__, __file__)

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

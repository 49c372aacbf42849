"""Calibration: sessions, the method table, the least-squares core, Calibration, evaluation."""

from ._calibration import Calibration, load_calibration
from ._evaluate import (
    DEFAULT_FORCE_THRESHOLD,
    DEFAULT_TORQUE_THRESHOLD,
    Equilibrium,
    Evaluation,
    equilibrium,
    evaluate,
    identify_loaded_faces,
    inverse_condition_table,
)
from ._fit import (
    AXES,
    NET_LOAD_MEASURED,
    NET_LOAD_PRIOR,
    NET_LOAD_UNIDENTIFIED,
    PRIORS,
    Calibrator,
    ExcitationError,
    RankDeficientError,
    RankDeficientWarning,
    calibrate,
    session_offsets,
)
from ._uncertainty import CalibrationCovariance, CovarianceGroup
from ._cv import MODELS, ModelChoice
from ._poly import PolyCorrection
from ._sensor import SensorFit, fit_sensor
from ._methods import METHODS, MethodSpec, get_method
from ._session import DEFAULT_COUNTS_RANGE, FLANGES, N_GAUGES, CalibrationSession, SessionBlock

__all__ = [
    "MODELS",
    "ModelChoice",
    "PolyCorrection",
    "SensorFit",
    "fit_sensor",
    "ExcitationError",
    "RankDeficientError",
    "DEFAULT_FORCE_THRESHOLD",
    "DEFAULT_TORQUE_THRESHOLD",
    "Equilibrium",
    "Evaluation",
    "equilibrium",
    "evaluate",
    "identify_loaded_faces",
    "inverse_condition_table",
    "AXES",
    "NET_LOAD_MEASURED",
    "NET_LOAD_PRIOR",
    "NET_LOAD_UNIDENTIFIED",
    "PRIORS",
    "CalibrationCovariance",
    "CovarianceGroup",
    "Calibration",
    "CalibrationSession",
    "Calibrator",
    "DEFAULT_COUNTS_RANGE",
    "FLANGES",
    "METHODS",
    "MethodSpec",
    "N_GAUGES",
    "RankDeficientWarning",
    "SessionBlock",
    "calibrate",
    "get_method",
    "load_calibration",
    "session_offsets",
]

"""Calibration: the method table, the least-squares core, Calibration, evaluation.

Sessions are :mod:`pito_core.io`'s (``CalibrationSession`` is re-exported here).
"""

from typing import TYPE_CHECKING

from .._lazy import attach

if TYPE_CHECKING:  # re-exported, each loaded on first use (pito_core/_lazy.py)
    from ._calibration import Calibration, load_calibration
    from ._coverage import NOT_MEASURED_TEXT, CompletingMount, Coverage, completing_mount, measured_directions
    from ._equilibrium import Equilibrium, equilibrium
    from ._evaluate import Evaluation, evaluate
    from ._interval import UNCERTAINTY_WORDS
    from ._metrics import DEFAULT_FORCE_THRESHOLD, DEFAULT_TORQUE_THRESHOLD, identify_loaded_faces, inverse_condition_table
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
    from ._error import CalibrationCovariance, CovarianceGroup, NoisyReferenceWarning
    from ._lstsq import GRAM_KAPPA_MAX, GramQR, LstsqResult, StreamedQR
    from ._cv import MODELS, ModelChoice, segment_ids
    from ._poly import PolyCorrection
    from ._sensor import SensorFit, fit_sensor
    from ._methods import METHODS, MethodSpec, get_method
    from ._targets import MountGeometry, block_targets
    from ..io import (  # the session format and its one builder (io), re-exported
        DEFAULT_COUNTS_RANGE, FLANGES, CalibrationSession, SessionBlock, saturated_samples, session_from_arrays,
    )
    from ._validation import ValidationFigures, confirm_model, validation_figures
    from ._fit_and_evaluate import HOLDOUT, HOLDOUT_BLOCK, FitResult, fit_and_evaluate

__getattr__, __dir__ = attach(__name__, __file__)

__all__ = [
    "FitResult",
    "HOLDOUT",
    "HOLDOUT_BLOCK",
    "fit_and_evaluate",
    "ValidationFigures",
    "confirm_model",
    "validation_figures",
    "saturated_samples",
    "session_from_arrays",
    "NOT_MEASURED_TEXT",
    "CompletingMount",
    "Coverage",
    "completing_mount",
    "measured_directions",
    "MODELS",
    "ModelChoice",
    "segment_ids",
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
    "UNCERTAINTY_WORDS",
    "LstsqResult",
    "StreamedQR",
    "GramQR",
    "GRAM_KAPPA_MAX",
    "MountGeometry",
    "block_targets",
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
    "RankDeficientWarning",
    "NoisyReferenceWarning",
    "SessionBlock",
    "calibrate",
    "get_method",
    "load_calibration",
    "session_offsets",
]

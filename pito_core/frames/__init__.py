"""Poses, wrench transforms and the cube's geometry (imports nothing of ours)."""

from typing import TYPE_CHECKING

from .._lazy import attach

if TYPE_CHECKING:  # re-exported, each loaded on first use (pito_core/_lazy.py)
    from ._checks import ROTATION_TOL, check_face, check_pose, check_vectors
    from ._colors import FACE_COLORS
    from ._cube import CUBE_ADC_LIMIT, DEFAULT_EDGE, FACE_NORMALS, FACES, N_GAUGES, OPPOSITE_FACE, CubeCore
    from ._transforms import (
        WRENCH_COMPONENTS,
        WRENCH_UNITS,
        cross_rows,
        invert_pose,
        pose_from_rotation_translation,
        rotation_from_x,
        transform_directions,
        transform_points,
        transform_twist,
        transform_wrench,
        wrench_adjoint,
    )

__getattr__, __dir__ = attach(__name__, __file__)

__all__ = [
    "FACE_COLORS",
    "CUBE_ADC_LIMIT",
    "CubeCore",
    "DEFAULT_EDGE",
    "FACES",
    "FACE_NORMALS",
    "N_GAUGES",
    "OPPOSITE_FACE",
    "ROTATION_TOL",
    "WRENCH_COMPONENTS",
    "WRENCH_UNITS",
    "check_face",
    "check_pose",
    "check_vectors",
    "cross_rows",
    "invert_pose",
    "pose_from_rotation_translation",
    "rotation_from_x",
    "transform_directions",
    "transform_points",
    "transform_twist",
    "transform_wrench",
    "wrench_adjoint",
]

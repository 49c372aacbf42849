"""The calibration model in words, for ``pito calibrate`` and ``pito evaluate``."""

from __future__ import annotations

__all__ = ["print_model"]

_WORDS = {"linear": "papers' linear fit", "poly": "linear + correction", "chosen": "chosen mix"}


def print_model(model, output_faces) -> None:
    """The model in use, why, where the correction is used, and each candidate's cross-validated RMSE."""
    print(f"model: {model.name} — {model.reason}")
    groups = model.corrected(output_faces)
    if model.name != "linear":
        names = ", ".join(f"face {f} {part}" for f, part in groups)
        print(f"  correction used on {len(groups)} of {2 * len(output_faces)} output groups: {names}")
    for key, (force, torque) in model.cv_rms().items():
        print(f"  cross-validated RMSE, {_WORDS[key]:19s}: forces {force:.4g} N, torques {torque:.4g} N·m")

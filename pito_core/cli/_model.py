"""The calibration model in words, for ``pito calibrate`` and ``pito evaluate``."""

from __future__ import annotations

__all__ = ["print_model"]


def print_model(model) -> None:
    """The model in use, why, and the cross-validated RMSE of both candidates (N, N·m)."""
    print(f"model: {model.name} — {model.reason}")
    if model.cv_rmse:
        for key in ("linear", "poly"):
            r = model.cv_rmse.get(key) or []
            force = [v for i, v in enumerate(r) if i % 6 < 3]
            torque = [v for i, v in enumerate(r) if i % 6 >= 3]
            if r:
                print(f"  cross-validated RMSE, {key:6s}: forces {_rms(force):.4g} N, torques {_rms(torque):.4g} N·m")


def _rms(v) -> float:
    return float(sum(x * x for x in v) / max(len(v), 1)) ** 0.5

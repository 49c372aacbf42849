"""SIMULATED multi-axis sensors of four response forms, as ``pito_bench._sensors`` data sets.

Each is ``m`` channels reading a wrench through a random sensitivity and one response per channel
(``FORMS``): linear; saturating (``tanh``, 10 % short at full scale); quadratic (an even bend, +10 %
at full scale); cubic (stiffening, +10 %). Every group is one loading direction held at random
magnitudes up to its level (1–4 quarters of full scale): ``dirs`` loading directions (rays from zero
load, as a real data set's poses or loadings), so "beyond range" (levels 3–4 after 1–2) tests loads
twice the trained ones.
No measured data: for the bench's rule checks only.
"""

from __future__ import annotations

import numpy as np

from pito_bench._sensors import Dataset

FS = np.array([20.0, 20.0, 40.0, 0.5, 0.5, 0.3])  # full scale, N and N·m
FORMS = ("linear", "saturation", "quadratic", "cubic")
#: Response change at full scale (fraction of the linear reading).
STRENGTH = 0.1


def _response(form: str, lin: np.ndarray, full: np.ndarray) -> np.ndarray:
    x = lin / full
    if form == "linear":
        return lin
    if form == "saturation":
        s = 1.0 / np.sqrt(3 * STRENGTH)  # tanh(x/s)·s ≈ x − x³/(3 s²): 10 % short at x = 1
        return full * s * np.tanh(x / s)
    if form == "quadratic":
        return lin + STRENGTH * full * x**2
    if form == "cubic":
        return lin + STRENGTH * full * x**3
    raise ValueError(f"form: expected one of {FORMS}, got {form!r}")


def simulated_sensor(form: str, seed: int = 0, m: int = 8, n_groups: int = 12, dirs: int = 2, per: int = 12,
                     noise: float = 2e-3) -> Dataset:
    """A SIMULATED sensor of response ``form``: ``n_groups`` groups of ``dirs`` loading directions × ``per``
    samples each.

    ``noise``: gauge noise, fraction of each channel's full-scale reading.
    """
    rng = np.random.default_rng(seed)
    S = rng.normal(size=(m, 6)) / FS  # channel (unit full scale) per N, N·m
    full = np.abs(S) @ FS / 2  # a channel's reading at a typical full-scale load
    level = np.arange(n_groups) % 4 + 1.0
    d = rng.normal(size=(n_groups, dirs, 1, 6))
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    mag = rng.uniform(0.1, 1.0, size=(n_groups, dirs, per, 1)) * (level[:, None, None, None] / 4)
    W = (d * mag).reshape(-1, 6) * FS * np.sqrt(6)
    W += rng.normal(scale=0.01, size=W.shape) * FS  # the load wanders within a group
    lin = W @ S.T
    c = 1e4 * (_response(form, lin, full) + rng.normal(size=lin.shape) * noise * full) + 5e3
    return Dataset(name=f"SIMULATED {form} (seed {seed})", channels=c, target=W,
                   group=np.repeat(np.arange(n_groups), dirs * per), target_names=["fx", "fy", "fz", "tx", "ty", "tz"],
                   units=["N", "N", "N", "N·m", "N·m", "N·m"], source="SIMULATED (tests/bench/sim_sensors.py)",
                   license="n/a (simulated)", level=np.repeat(level, dirs * per), level_name="load level (quarters)")

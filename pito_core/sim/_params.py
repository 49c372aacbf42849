"""Default parameters of the simulated cube, in one place (see docs/simulator.md)."""

from __future__ import annotations

from dataclasses import asdict, dataclass, fields

import numpy as np

from .. import defaults

__all__ = ["SimParams", "FULL_SCALE_FACE", "FULL_SCALE_FRAME"]

#: Calibration load range of one face, face frame: ``[fx, fy, fz, tx, ty, tz]`` in N and N·m
#: (the papers' protocol: forces within ±15 N, torques within ±0.1 N·m).
FULL_SCALE_FACE = defaults.FULL_SCALE_FACE

#: Scale of the total load through the frame's screw joints, core frame (N, N·m): moments
#: about the core centre reach ~0.4 N·m for a 15 N force on a face of a 50 mm cube.
FULL_SCALE_FRAME = defaults.FULL_SCALE_FRAME


@dataclass(frozen=True)
class SimParams:
    """Every physical parameter of the simulated cube (defaults = the default simulator).

    Gauge counts of face i are, for a sample at time t (see docs/simulator.md)::

        counts = Σ_j M_ij F_j + offset + drift · T(t) + frame_term(W_frame) + noise

    rounded to integers and clipped to the ADC range. ``M_ii`` is the 3-spoke hub
    sensitivity of face i, ``M_ij`` (i ≠ j) the inter-face coupling.

    Attributes
    ----------
    edge : float
        Edge of the core, m.
    rate : float
        Sample rate of the cube's acquisition, Hz.
    spoke_radius : float
        Distance from the hub centre to the strain gauges' spoke tips, m.
    spoke_gain : float
        Out-of-plane bending gauge sensitivity, counts per N of spoke force.
    inplane_ratio : float
        In-plane (tangential) gauge sensitivity relative to out-of-plane (spokes are
        stiffer in their plane), dimensionless.
    radial_crosstalk : float
        Tangential gauges' sensitivity to the spoke's axial (radial) force, relative.
    gain_spread : float
        Log-normal spread (σ of log) of each gauge's gain, dimensionless.
    misalignment : float
        Size of the random full 6×6 mixing of each hub (gauge placement errors), relative.
    coupling_adjacent, coupling_opposite : float
        Inter-face coupling: a full-scale load on face j reads on face i's gauges as a
        random load of this relative size (adjacent faces / opposite faces).
    offset_std : float
        Spread of the zero-load offsets, counts.
    noise_std : float
        Gaussian noise of each gauge, counts (before rounding).
    adc_bits : int
        Signed ADC resolution; counts are clipped to ``[-2**(b-1), 2**(b-1) - 1]``.
    drift_std : float
        Spread of each gauge's temperature coefficient, counts per K.
    temperature_amplitude : float
        Amplitude of the slow temperature swing around the tare temperature, K.
    temperature_periods : tuple of float
        Periods of the temperature swing's components, s.
    element_nonlinearity : float
        Quadratic response of each hub to its own load (every mount), relative to a
        gauge's full-scale signal.
    frame_nonlinearity : float
        Quadratic response of the gauges to the load through the frame's screw joints
        (flange on the frame only), relative to a gauge's full-scale signal.
    frame_hysteresis : float
        Amplitude of the screw joints' slip (play-operator hysteresis), relative to a
        gauge's full-scale signal.
    frame_play : float
        Width of the screw joints' play (half-width of the hysteresis loop) in units of
        the frame's full-scale load (``FULL_SCALE_FRAME``), dimensionless.
    """

    edge: float = 0.05
    rate: float = 1000.0
    spoke_radius: float = 0.012
    spoke_gain: float = 4.0e4
    inplane_ratio: float = 0.2
    radial_crosstalk: float = 0.05
    gain_spread: float = 0.15
    misalignment: float = 0.05
    coupling_adjacent: float = 0.05
    coupling_opposite: float = 0.02
    offset_std: float = 1.0e5
    noise_std: float = 40.0
    adc_bits: int = 24
    drift_std: float = 600.0
    temperature_amplitude: float = 0.4
    temperature_periods: tuple = (900.0, 2300.0, 5300.0)
    element_nonlinearity: float = 0.015
    frame_nonlinearity: float = 0.015
    frame_hysteresis: float = 0.01
    frame_play: float = 0.08

    def __post_init__(self):
        for f in fields(self):
            v = getattr(self, f.name)
            if f.name == "temperature_periods":
                arr = np.asarray(v, dtype=float)
                if arr.ndim != 1 or arr.size == 0 or not np.all(arr > 0):
                    raise ValueError(f"temperature_periods: expected positive periods in s, got {v!r}")
                object.__setattr__(self, f.name, tuple(float(x) for x in arr))
                continue
            if f.name == "adc_bits":
                if int(v) != v or not 2 <= int(v) <= 32:
                    raise ValueError(f"adc_bits: expected an integer in 2..32, got {v!r}")
                continue
            if not np.isfinite(v) or v < 0:
                raise ValueError(f"{f.name}: expected a finite value >= 0, got {v!r}")
        for name in ("edge", "rate", "spoke_radius", "spoke_gain", "inplane_ratio", "frame_play"):
            if getattr(self, name) <= 0:
                raise ValueError(f"{name}: expected a positive value, got {getattr(self, name)!r}")

    @property
    def counts_range(self) -> tuple[int, int]:
        """ADC limits ``(lo, hi)``, counts: values at or beyond them are saturated."""
        return (-(2 ** (self.adc_bits - 1)), 2 ** (self.adc_bits - 1) - 1)

    def to_dict(self) -> dict:
        """JSON-serialisable parameters (for session metadata)."""
        d = asdict(self)
        d["temperature_periods"] = list(self.temperature_periods)
        return d

"""Per-sample grasp series of a whole recording: the input of the phase metrics and figures."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.signal import butter, sosfiltfilt

from ._grasp import grasp_decomposition, net_wrench, normal_tangential
from ._segment import AnalysisSettings, contact_runs

__all__ = ["ContactArrays", "GraspSeries", "grasp_series", "smooth_paths"]


@dataclass
class ContactArrays:
    """Contacts of a recording, core frame (face i at index ``i − 1``).

    Attributes
    ----------
    time : ndarray, shape (N,)
        s.
    point, normal, force : ndarray, shape (N, 6, 3)
        Contact point (m, NaN where none), outward unit normal, force on the object (N).
    torsion : ndarray, shape (N, 6)
        N·m.
    valid : ndarray of bool, shape (N, 6)
    single_contact : ndarray of bool, shape (N, 6), or None
        The contact's plausibility flag (a single contact explains the face wrench); None
        when the contacts carry none (the phases' ``plausible`` is then unknown).
    """

    time: np.ndarray
    point: np.ndarray
    normal: np.ndarray
    force: np.ndarray
    torsion: np.ndarray
    valid: np.ndarray
    single_contact: np.ndarray | None = None

    def __post_init__(self):
        n = np.asarray(self.time).shape[0]
        for name, shape in (("point", (n, 6, 3)), ("normal", (n, 6, 3)), ("force", (n, 6, 3)), ("torsion", (n, 6)),
                            ("valid", (n, 6)), ("single_contact", (n, 6))):
            v = getattr(self, name)
            if v is None:
                continue
            v = np.asarray(v, bool if name in ("valid", "single_contact") else float)
            if v.shape != shape:
                raise ValueError(f"{name}: expected shape {shape}, got {v.shape}")
            setattr(self, name, v)
        self.time = np.asarray(self.time, float)
        if n > 1 and not (np.diff(self.time) > 0).all():
            raise ValueError("time: expected strictly increasing sample times, s")


@dataclass
class GraspSeries:
    """Per-sample quantities (N samples; face i at index ``i − 1``), SI units.

    ``on (N, 6)`` patches in contact (debounced); ``f_n``/``f_t (N, 6)`` normal and
    tangential force, N; ``f_manip``/``f_int (N, 6, 3)`` grasp-matrix split, N;
    ``net_force``/``net_moment (N, 3)`` N, N·m about the centre of mass; ``path (N, 6, 3)``
    low-pass filtered contact points, m (NaN where not in contact).
    """

    time: np.ndarray
    on: np.ndarray
    f_n: np.ndarray
    f_t: np.ndarray
    f_manip: np.ndarray
    f_int: np.ndarray
    net_force: np.ndarray
    net_moment: np.ndarray
    path: np.ndarray
    single: np.ndarray | None


def smooth_paths(time, point, on, cutoff: float) -> np.ndarray:
    """Zero-phase Butterworth low-pass (order 2, ``cutoff`` Hz) of each contact run of ``point (N, 6, 3)``, m."""
    out = np.full(point.shape, np.nan)
    dt = np.median(np.diff(time)) if time.size > 1 else 1.0
    fs = 1.0 / dt
    sos = butter(2, cutoff, fs=fs, output="sos") if 0 < cutoff < fs / 2 else None
    for i in range(point.shape[1]):
        edges = np.flatnonzero(np.diff(np.r_[0, on[:, i].astype(np.int8), 0]))
        for a, b in zip(edges[::2], edges[1::2]):
            seg = point[a:b, i]
            good = np.isfinite(seg).all(axis=1)
            if not good.all():  # a contact the solver lost inside the run: hold the last point
                idx = np.maximum.accumulate(np.where(good, np.arange(b - a), 0))
                seg = seg[idx] if good.any() else seg
            if sos is not None and b - a > 15 and np.isfinite(seg).all():
                seg = sosfiltfilt(sos, seg, axis=0, padlen=min(3 * 5, b - a - 1))
            out[a:b, i] = seg
    return out


def grasp_series(c: ContactArrays, settings: AnalysisSettings, cog=(0.0, 0.0, 0.0)) -> GraspSeries:
    """The per-sample quantities of contacts ``c`` (see :class:`GraspSeries`)."""
    f_n, _ = normal_tangential(c.force, c.normal, c.valid)
    on = np.stack([contact_runs(c.valid[:, i] & (f_n[:, i] > settings.contact_force), c.time, settings.min_contact)
                   for i in range(6)], axis=1) & c.valid
    f_n, f_t = normal_tangential(c.force, c.normal, on)
    f_manip, f_int = grasp_decomposition(c.point, c.force, on, cog)
    F, M = net_wrench(c.point, c.force, c.torsion, c.normal, on, cog)
    path = smooth_paths(c.time, c.point, on, settings.path_cutoff)
    return GraspSeries(c.time, on, f_n, f_t, f_manip, f_int, F, M, path, c.single_contact)

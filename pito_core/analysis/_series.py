"""Per-sample grasp series of a whole recording: the input of the phase metrics and figures.

Their input is the pipeline's own contact record, a core-frame
:class:`~pito_core.contact.ContactEstimate` of ``(N, 6, …)`` fields, beside its sample times.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy.signal import butter, sosfiltfilt

from ..contact import ContactEstimate
from ._grasp import _net, _normal_tangential, _split, finite
from ._segment import AnalysisSettings, contact_runs

__all__ = ["GraspSeries", "check_contacts", "grasp_series", "smooth_paths"]

#: A trial's figure spans the trial and this margin on both sides, s.
FIGURE_PAD_S = 0.3
#: Most points drawn per curve of a figure (the series is decimated to this for the figure
#: only): about the axes' width in pixels at the default dpi.
FIGURE_POINTS = 800


def check_contacts(time, contacts: ContactEstimate) -> tuple[np.ndarray, ContactEstimate]:
    """``(time, contacts)`` checked for the analysis: N increasing times and N samples of six faces.

    Parameters
    ----------
    time : array-like, shape (N,)
        Sample times, s, strictly increasing.
    contacts : ContactEstimate
        Core frame (``frame == "core"``), face i at index ``i − 1``: ``point``, ``normal``,
        ``force`` (N, 6, 3) (m, unit, N), ``torsion`` (N, 6) N·m, ``valid`` (N, 6); its
        ``single_contact`` (N, 6) or None (the phases' ``plausible`` is then unknown).

    Returns
    -------
    time : ndarray of float, shape (N,)
    contacts : ContactEstimate
        The same record, with those fields as float (``valid``, ``single_contact``: bool)
        arrays (not copied when they already are).

    Raises
    ------
    ValueError
        A field of another shape, a frame other than ``"core"``, or times not increasing
        (the error names the field).
    """
    if not isinstance(contacts, ContactEstimate):
        raise TypeError(f"contacts: expected a ContactEstimate, got {type(contacts).__name__}")
    if contacts.frame != "core":
        raise ValueError(f"contacts.frame: expected 'core' (six faces per sample, e.g. Pipeline.contacts), "
                         f"got {contacts.frame!r}")
    time = np.asarray(time, float)
    if time.ndim != 1:
        raise ValueError(f"time: expected shape (N,), got {time.shape}")
    n = time.shape[0]
    checked = {}
    for name, shape in (("point", (n, 6, 3)), ("normal", (n, 6, 3)), ("force", (n, 6, 3)), ("torsion", (n, 6)),
                        ("valid", (n, 6)), ("single_contact", (n, 6))):
        v = getattr(contacts, name)
        if v is None and name == "single_contact":
            continue
        v = np.asarray(v, bool if name in ("valid", "single_contact") else float)
        if v.shape != shape:
            raise ValueError(f"contacts.{name}: expected shape {shape}, got {v.shape}")
        checked[name] = v
    if n > 1 and not (np.diff(time) > 0).all():
        raise ValueError("time: expected strictly increasing sample times, s")
    return time, replace(contacts, **checked)


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
    #: The samples are already those a figure draws (a long recording's, :mod:`._stream`; floats float32).
    decimated: bool = False


def sample_rate(time) -> float:
    """Hz: 1 / the median sample interval of ``time`` (s), 1 for fewer than two samples."""
    return 1.0 / (np.median(np.diff(time)) if time.size > 1 else 1.0)


def smooth_paths(time, point, on, cutoff: float, fs: float | None = None) -> np.ndarray:
    """Zero-phase Butterworth low-pass (order 2, ``cutoff`` Hz) of each contact run of ``point (N, 6, 3)``, m.

    ``fs``: the sampling rate, Hz (default :func:`sample_rate` of ``time``; a part of a
    recording passes the whole one's).
    """
    out = np.full(point.shape, np.nan)
    fs = sample_rate(time) if fs is None else fs
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


def grasp_series(time, contacts: ContactEstimate, settings: AnalysisSettings, cog=(0.0, 0.0, 0.0)) -> GraspSeries:
    """The per-sample quantities (:class:`GraspSeries`) of ``contacts`` at ``time`` s (:func:`check_contacts`)."""
    time, c = check_contacts(time, contacts)
    force, normal = finite(c.force), finite(c.normal)
    on = contact_state(time, raw_contacts(force, normal, c.valid, settings), c.valid, settings)
    return series_of(time, c, on, settings, cog, force=force, normal=normal)


def raw_contacts(force, normal, valid, settings: AnalysisSettings) -> np.ndarray:
    """``(N, 6)`` bool: valid contacts pushing in harder than ``contact_force`` (finite ``force``, ``normal``)."""
    return valid & (-np.einsum("nkj,nkj->nk", force, normal) > settings.contact_force)  # normal_tangential's f_n


def contact_state(time, raw, valid, settings: AnalysisSettings) -> np.ndarray:
    """``(N, 6)`` bool: :func:`raw_contacts` debounced (:func:`~pito_core.analysis.contact_runs`), still valid."""
    return np.stack([contact_runs(raw[:, i], time, settings.min_contact) for i in range(6)], axis=1) & valid


def series_of(time, c: ContactEstimate, on, settings: AnalysisSettings, cog=(0.0, 0.0, 0.0), *, fs=None, force=None,
              normal=None) -> GraspSeries:
    """The :class:`GraspSeries` of checked contacts ``c`` with the contact state ``on (N, 6)`` given.

    ``fs`` as :func:`smooth_paths`; ``force``, ``normal``: ``finite`` of ``c``'s when already made.
    """
    force = finite(c.force) if force is None else force
    normal = finite(c.normal) if normal is None else normal
    point = finite(c.point)
    a = on[..., None]
    f = np.where(a, force, 0.0)
    f_n, f_t = _normal_tangential(f, normal)
    f_manip, f_int = _split(np.where(a, point, 0.0), f, on)
    F, M = _net(point, f, finite(c.torsion), normal, on, cog)
    path = smooth_paths(time, c.point, on, settings.path_cutoff, fs)
    return GraspSeries(time, on, f_n, f_t, f_manip, f_int, F, M, path, c.single_contact)

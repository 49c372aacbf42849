"""One recording (or one run of contacts) → :class:`GraspAnalysis`: trials, tidy tables, series.

pandas is an optional dependency (``pip install "pito[analysis]"``): the tables need it,
:func:`analyze_contacts` raises :class:`ImportError` saying so when it is missing.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..contact import ContactEstimate
from ..interop import ExportData, export_data
from ._metrics import PATCH_COLUMNS, PHASE_COLUMNS, phase_rows
from ._optional import require
from ._segment import PHASES, AnalysisSettings, trials_from_contacts
from ._series import GraspSeries, grasp_series
from ._stream import BLOCK, STREAM_SAMPLES, RecordingContacts, analyze_long

__all__ = ["GraspAnalysis", "analyze_contacts", "analyze_data", "analyze_recording", "recording_contacts",
           "require_pandas"]


def require_pandas():
    """The ``pandas`` module, or an ImportError naming the extra to install."""
    return require("pandas", "pito_core.analysis")


@dataclass
class GraspAnalysis:
    """The analysis of one recording.

    Attributes
    ----------
    phases : pandas.DataFrame
        One row per trial × phase (columns :data:`~pito_core.analysis.PHASE_COLUMNS`).
    patches : pandas.DataFrame
        One row per trial × phase × patch in contact (:data:`~pito_core.analysis.PATCH_COLUMNS`).
    trials : list of Trial
    series : GraspSeries
        Per-sample quantities behind the tables (figures).
    settings : AnalysisSettings
    meta : dict
        ``source``, ``simulated``, ``note`` (calibration), ``mass_kg``, ``n_samples``.
    """

    phases: object
    patches: object
    trials: list
    series: GraspSeries
    settings: AnalysisSettings
    meta: dict = field(default_factory=dict)

    @property
    def simulated(self) -> bool:
        return bool(self.meta.get("simulated", False))


def _tables(phase_list, patch_list, simulated: bool):
    pd = require_pandas()
    phases = pd.DataFrame(phase_list, columns=list(PHASE_COLUMNS))
    patches = pd.DataFrame(patch_list, columns=list(PATCH_COLUMNS))
    for df in (phases, patches):
        df["phase"] = pd.Categorical(df["phase"], categories=PHASES, ordered=True)
        df["plausible"] = df["plausible"].astype("boolean")
        df["simulated"] = simulated
    patches["face"] = pd.Categorical(patches["face"], categories=range(1, 7))
    patches["role"] = pd.Categorical(patches["role"], categories=("finger", "base"))
    return phases, patches


def analyze_contacts(time, contacts: ContactEstimate, settings: AnalysisSettings | None = None, *,
                     cog=(0.0, 0.0, 0.0), mass: float | None = None, meta: dict | None = None) -> GraspAnalysis:
    """Trials, phases and metrics of a run of contacts (any source: a recording, a simulation, by hand).

    Parameters
    ----------
    time : array-like, shape (N,)
        Sample times, s, strictly increasing.
    contacts : ContactEstimate
        Core frame, fields ``(N, 6, …)`` (face i at index ``i − 1``), as
        :meth:`~pito_core.pipeline.Pipeline.contacts` gives them; shapes and units in
        :func:`~pito_core.analysis.check_contacts`.
    settings : AnalysisSettings, optional
    cog : array-like, shape (3,)
        Centre of mass of the object, core frame, m (moments of the residual).
    mass : float, optional
        kg (``settings.mass`` wins); None: the force residual is NaN.
    meta : dict, optional
        Kept in ``GraspAnalysis.meta`` (``simulated`` labels the tables).
    """
    s = settings or AnalysisSettings()
    mass = s.mass if s.mass is not None else mass
    g = grasp_series(time, contacts, s, cog)
    trials = trials_from_contacts(g.time, g.on, s)
    phase_list, patch_list = phase_rows(g, trials, s, mass)
    meta = dict(meta or {})
    meta.setdefault("simulated", False)
    meta.update(mass_kg=mass, n_samples=int(g.time.size), n_trials=len(trials))
    phases, patches = _tables(phase_list, patch_list, bool(meta["simulated"]))
    return GraspAnalysis(phases, patches, trials, g, s, meta)


def _data_contacts(data: ExportData, source):
    """``(time, contacts, meta)`` of a recording run through the pipeline (see :func:`recording_contacts`)."""
    if data.calibration is None:
        raise ValueError(f"calibration: {source} has none embedded; give one (--calibration FILE)")
    obj = data.assembly or {}
    mass = data.meta.get("mass_kg") or obj.get("mass_kg")
    cog = data.meta.get("cog_m") or obj.get("center_of_gravity_m")
    meta = {"source": str(source), "simulated": data.simulated, "note": data.note, "assembly": obj.get("name"),
            "mass_kg": mass, "cog_m": None if cog is None else np.asarray(cog, float).tolist()}
    return data.time, data.contacts, meta


def recording_contacts(path, calibration=None, assembly=None, *, calibration_source=None, recover=False,
                       progress=None):
    """A recording's contacts through the one pipeline: the contacts of :func:`~pito_core.interop.export_data`.

    Returns ``(time (N,) s, ContactEstimate (N, 6, …), meta)``: ``meta`` has ``source``,
    ``simulated``, ``note`` (which calibration), ``assembly``, ``mass_kg`` and ``cog_m`` (from
    the recording or its assembly). ``progress(fraction, text)`` as for ``export_data``.
    Raises ValueError when neither the recording nor the caller gives a calibration.
    """
    data = export_data(path, calibration, assembly, calibration_source=calibration_source, progress=progress,
                       recover=recover)
    return _data_contacts(data, path)


def analyze_recording(path, calibration=None, assembly=None, settings: AnalysisSettings | None = None, *,
                      calibration_source=None, recover=False, progress=None) -> GraspAnalysis:
    """:func:`analyze_contacts` of a recording's contacts (:func:`recording_contacts`).

    The pipeline's contacts are kept, block by block, without its other outputs (counts,
    wrenches, covariances); a recording of more than ``STREAM_SAMPLES`` samples is analysed
    in bounded memory (:mod:`._stream`: the same tables, ``series`` only the figures'
    samples). :func:`analyze_data` analyses an :class:`~pito_core.interop.ExportData` kept
    for an export.
    """
    rc = RecordingContacts(path, calibration, assembly, calibration_source=calibration_source, recover=recover)
    if rc.n <= STREAM_SAMPLES:
        parts = []
        for c in rc.blocks():
            parts.append(c)
            if progress is not None:
                progress(0.1 + 0.6 * min(1.0, len(parts) * BLOCK / max(rc.n, 1)), "contacts")
        contacts = ContactEstimate.concatenate(parts) if parts else rc.pipe.contacts(np.zeros((0, 6, 6)))
        return _analyze(rc.time, contacts, rc.meta, settings)
    s = settings or AnalysisSettings()
    meta = dict(rc.meta)
    cog = meta["cog_m"] if meta["cog_m"] is not None else (0.0, 0.0, 0.0)
    mass = s.mass if s.mass is not None else meta["mass_kg"]
    trials, phase_list, patch_list, series = analyze_long(rc, s, cog, mass)
    meta.update(mass_kg=mass, n_samples=rc.n, n_trials=len(trials))
    phases, patches = _tables(phase_list, patch_list, bool(meta["simulated"]))
    return GraspAnalysis(phases, patches, trials, series, s, meta)


def analyze_data(data: ExportData, settings: AnalysisSettings | None = None, *,
                 source: str = "the recording") -> GraspAnalysis:
    """:func:`analyze_contacts` of a recording run through the pipeline (:func:`~pito_core.interop.export_data`).

    ``source`` (its path) names it in ``meta`` and in errors.
    """
    return _analyze(*_data_contacts(data, source), settings)


def _analyze(time, contacts, meta, settings) -> GraspAnalysis:
    cog = meta["cog_m"] if meta["cog_m"] is not None else (0.0, 0.0, 0.0)
    return analyze_contacts(time, contacts, settings, cog=cog, mass=meta["mass_kg"], meta=meta)

"""One recording (or one set of contact arrays) → :class:`GraspAnalysis`: trials, tidy tables, series.

pandas is an optional dependency (``pip install "pito[analysis]"``): the tables need it,
:func:`analyze_contacts` raises :class:`ImportError` saying so when it is missing.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..interop import recording_calibration
from ..io import read_recording
from ..pipeline import replay_recording
from ._metrics import PATCH_COLUMNS, PHASE_COLUMNS, phase_rows
from ._optional import require
from ._segment import PHASES, AnalysisSettings, trials_from_contacts
from ._series import ContactArrays, GraspSeries, grasp_series

__all__ = ["GraspAnalysis", "analyze_contacts", "analyze_recording", "recording_contacts", "require_pandas"]

#: Samples per block when the contacts of a recording are solved (bounds the memory).
BLOCK = 20_000


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


def analyze_contacts(contacts: ContactArrays, settings: AnalysisSettings | None = None, *, cog=(0.0, 0.0, 0.0),
                     mass: float | None = None, meta: dict | None = None) -> GraspAnalysis:
    """Trials, phases and metrics of contact arrays (any source: a recording, a simulation, by hand).

    Parameters
    ----------
    contacts : ContactArrays
        Core frame; see :class:`ContactArrays` for shapes and units.
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
    g = grasp_series(contacts, s, cog)
    trials = trials_from_contacts(g.time, g.on, s)
    phase_list, patch_list = phase_rows(g, trials, s, mass)
    meta = dict(meta or {})
    meta.setdefault("simulated", False)
    meta.update(mass_kg=mass, n_samples=int(g.time.size), n_trials=len(trials))
    phases, patches = _tables(phase_list, patch_list, bool(meta["simulated"]))
    return GraspAnalysis(phases, patches, trials, g, s, meta)


def recording_contacts(path, calibration=None, assembly=None, *, calibration_source=None, recover=False,
                       progress=None):
    """A recording's contacts through the one pipeline (:func:`~pito_core.pipeline.replay_recording`).

    Returns ``(ContactArrays, meta)``: ``meta`` has ``source``, ``simulated``, ``note`` (which
    calibration), ``assembly``, ``mass_kg`` and ``cog_m`` (from the recording or its assembly).
    Raises ValueError when neither the recording nor the caller gives a calibration.
    """
    rec = read_recording(path, recover=recover)
    cal, note = recording_calibration(rec.meta, calibration, calibration_source)
    if cal is None:
        raise ValueError(f"calibration: {path} has none embedded; give one (--calibration FILE)")
    if assembly is None:
        assembly = (rec.meta.get("assembly") or {}).get("name") or "cube"
    bundle, pipe = replay_recording(rec, cal, assembly)
    W = np.asarray(bundle.face_wrenches, float)
    parts = []
    for a in range(0, len(W), BLOCK):
        parts.append(pipe.contacts(W[a:a + BLOCK]))
        if progress is not None:
            progress(min(1.0, (a + BLOCK) / max(len(W), 1)), "contacts")
    cat = {k: np.concatenate([getattr(p, k) for p in parts]) if parts else np.zeros((0, 6, 3))
           for k in ("point", "normal", "force")}
    flags = [getattr(p, "single_contact", None) for p in parts]
    single = np.concatenate(flags) if parts and all(f is not None for f in flags) else None
    contacts = ContactArrays(np.asarray(bundle.time, float) - (bundle.time[0] if len(bundle.time) else 0.0),
                             cat["point"], cat["normal"], cat["force"],
                             np.concatenate([p.torsion for p in parts]) if parts else np.zeros((0, 6)),
                             np.concatenate([p.valid for p in parts]) if parts else np.zeros((0, 6), bool), single)
    obj = pipe.assembly
    mass = rec.meta.get("mass_kg") or getattr(obj, "mass", None)
    cog = rec.meta.get("cog_m") or getattr(obj, "center_of_gravity", None)
    meta = {"source": str(path), "simulated": rec.simulated, "note": note, "assembly": getattr(obj, "name", assembly),
            "mass_kg": mass, "cog_m": None if cog is None else np.asarray(cog, float).tolist()}
    return contacts, meta


def analyze_recording(path, calibration=None, assembly=None, settings: AnalysisSettings | None = None, *,
                      calibration_source=None, recover=False, progress=None) -> GraspAnalysis:
    """:func:`analyze_contacts` of a recording's contacts (:func:`recording_contacts`)."""
    contacts, meta = recording_contacts(path, calibration, assembly, calibration_source=calibration_source,
                                        recover=recover, progress=progress)
    cog = meta["cog_m"] if meta["cog_m"] is not None else (0.0, 0.0, 0.0)
    return analyze_contacts(contacts, settings, cog=cog, mass=meta["mass_kg"], meta=meta)

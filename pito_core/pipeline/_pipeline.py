"""The one live pipeline: new samples → pairing → tare → calibration → face wrenches → contacts.

:class:`Pipeline` is called by every path that turns device samples into loads: the app's
acquisition worker, ``pito record``, replay (``pito replay``, the app's timeline),
``pito bench``; :meth:`Acquisition.to_session` pairs by the same rule
(:mod:`pito_core.devices._clock`). It holds no thread and no Qt: a caller hands it the new
rows of both streams (:class:`~pito_core.pipeline.AcquisitionReader` reads them from the
acquisition's ring buffers by cursor; :class:`~pito_core.pipeline.RecordingReader` from a
recording) and gets one :class:`LiveBundle`.

The cube's side runs as each cube sample arrives: tare, calibration, face wrenches, and the
contacts of the newest samples. The pairing rule only decides when a sample's *record* (with
its reference) is complete, so the reference device never holds back what the live view shows
(a cube sample waits up to one reference packet, ~10 ms, for its reference).

Work per call is proportional to the new samples: the reference history and the tails kept
for the tare and the smoothing are fixed-size rings read as contiguous views.
"""

from __future__ import annotations

import time
import numpy as np

from ..contact import Assembly, ContactEstimate, load_assembly, solve_object
from ..defaults import SHOW_CONTACT_FORCE_N
from ..devices import Ring, TareRefused, check_tare, pair_reference, tare_event
from ..frames import CUBE_ADC_LIMIT, N_GAUGES, CubeCore
from ._bundle import LiveBundle, face_sums

__all__ = ["Pipeline"]


class Pipeline:
    """New samples of both devices → one :class:`LiveBundle` (module docstring).

    Parameters
    ----------
    calibration : Calibration, optional
        Applied to every new cube sample (face wrenches); none: no wrenches, no contacts.
    assembly : Assembly or str, optional
        The patched object (or a library name); none: the bare cube's flat faces.
    core : CubeCore, optional
    has_reference : bool
        A reference device is connected: a cube sample's record (``LiveBundle.time``,
        ``counts``, ``reference``, ``face_wrenches``) waits for the reference record after it
        (pairing rule); without one every record passes at once with NaN reference. Its face
        wrenches and the contacts are made when it arrives, with the tare and calibration in
        force then (``LiveBundle.arrived_time``, ``contacts_time``).
    force_threshold : float
        Force below which a face shows no contact, N (default :data:`pito_core.defaults.SHOW_CONTACT_FORCE_N`).
    wrench_cov : array-like, shape (6, 6) or (6, 6, 6), or "calibration", optional
        Face-wrench noise covariance (N², N²·m, N²·m²) for the contacts' point covariance;
        ``"calibration"``: each face's covariance from the calibration at the latest counts
        (``Calibration.wrenches(..., return_cov=True)``: fit and gauge noise), or none when the
        calibration carries no covariance.
    smooth : int
        The latest face wrenches are the mean of this many newest samples (noise).
    reference_history : float
        Seconds of reference records kept for pairing (at ``rate_hz``).
    max_wait : float
        Seconds (sample time) a cube sample waits for the reference before it passes with
        NaN (a reference that stopped).
    rate_hz : float
        Nominal sample rate, Hz (sizes the histories).
    sample_contacts : bool
        Also solve the contacts of every arrived sample (``LiveBundle.arrived_contacts``: the
        live streams' contacts, one per sample), not only of the latest wrenches
        (:meth:`set_sample_contacts` turns it on and off).

    Attributes
    ----------
    counts_offset : ndarray, shape (36,) or None
        Tare of the counts (None: the calibration's own offset).
    reference_bias : ndarray, shape (6,)
        Tare of the reference, N and N·m.
    cog : ndarray, shape (3,)
        The object's centre of gravity in the core frame, m (for ``sum_torque``).
    """

    def __init__(self, calibration=None, assembly=None, *, core: CubeCore | None = None, has_reference: bool = True,
                 force_threshold: float = SHOW_CONTACT_FORCE_N, wrench_cov=None, smooth: int = 5,
                 reference_history: float = 4.0, max_wait: float = 1.0, rate_hz: float = 1000.0,
                 sample_contacts: bool = False):
        if int(smooth) < 1:
            raise ValueError(f"smooth: expected >= 1 samples, got {smooth!r}")
        if not force_threshold >= 0:
            raise ValueError(f"force_threshold: expected >= 0 N, got {force_threshold!r}")
        self.core = core or CubeCore()
        self.has_reference = bool(has_reference)
        self.force_threshold = float(force_threshold)
        self.smooth = int(smooth)
        self.max_wait = float(max_wait)
        self.sample_contacts = bool(sample_contacts)
        self.calibration = None
        self.coverage = None
        self._tare_history: list = []  # (counts_offset, reference_bias) before each tare, for undo_tare
        self._tare_event = None
        self.counts_offset = None
        self.reference_bias = np.zeros(6)
        self.cog = np.zeros(3)
        self.assembly = None
        self.wrench_cov = None
        # rings read as views of their last rows (contiguous): the work per call follows the new samples
        self._ref = Ring(int(reference_history * rate_hz) + 1,
                         {"time": (np.float64, ()), "wrench": (np.float64, (6,))}, contiguous=True)
        self._tail = Ring(int(2.0 * rate_hz) + 1, {"time": (np.float64, ()), "counts": (np.float64, (N_GAUGES,)),
                                                   "reference": (np.float64, (6,))}, contiguous=True)
        # the newest arrived samples behind the latest wrenches (smoothing, covariance, ADC limit)
        self._wtail = Ring(self.smooth, {"w": (np.float64, (6, 6)), "counts": (np.float64, (N_GAUGES,))},
                           contiguous=True)
        self._pending: dict | None = None
        self.last_tick: int | None = None
        self.samples = 0
        self.set_calibration(calibration)
        self.set_assembly(assembly, wrench_cov)

    # ------------------------------------------------------------ settings
    def set_calibration(self, calibration) -> None:
        """Use ``calibration`` (None: none) with its own offset until the next :meth:`tare`.

        Samples still waiting for their reference are given it too (their face wrenches are
        made again), so every record passed after this call has the new calibration.
        """
        self.calibration = calibration
        self._tare_history.clear()  # a new calibration starts from its own zero
        self._tare_event = None
        # readings the calibration does not measure are NaN from here on: never a silent 0 that reads as "no load"
        self.coverage = getattr(calibration, "coverage", None)  # (duck-typed calibrations without one: unmasked)
        self.counts_offset = None
        self._wtail.clear()
        rows = self._pending
        if rows is not None:
            rows.pop("w", None)
            if calibration is not None:
                rows["w"] = self._masked(calibration.wrenches(rows["counts"]))

    def set_assembly(self, assembly, wrench_cov=None) -> None:
        """The object whose patches carry the contacts (an ``Assembly``, a library name, or None: the bare cube)."""
        if isinstance(assembly, str):
            assembly = load_assembly(assembly)
        if assembly is not None and not isinstance(assembly, Assembly):
            raise ValueError(f"assembly: expected an Assembly, a library name or None, got {type(assembly).__name__}")
        self.assembly = assembly
        if isinstance(wrench_cov, str):
            if wrench_cov != "calibration":
                raise ValueError(f"wrench_cov: expected an array, 'calibration' or None, got {wrench_cov!r}")
            self.wrench_cov = wrench_cov
        else:
            self.wrench_cov = None if wrench_cov is None else np.asarray(wrench_cov, dtype=float)
        c = getattr(assembly, "center_of_gravity", None)
        self.cog = np.zeros(3) if c is None else np.asarray(c, dtype=float)

    def set_sample_contacts(self, on: bool) -> None:
        """Solve the contacts of every arrived sample too (``LiveBundle.arrived_contacts``), or stop."""
        self.sample_contacts = bool(on)

    # ------------------------------------------------------------ tare
    def tare(self, duration: float = 0.5, *, check: bool = False, support=None) -> dict:
        """Zero the face wrenches and the reference on the last ``duration`` s of processed samples.

        Returns the tare as an event for a recording (``type`` "tare", ``counts_offset``
        (36,) counts, ``reference_bias`` (6,) N and N·m, ``from_tick``: the first cube tick
        (µs) it applies to), which :meth:`apply_tare` replays. The tare it replaces is kept:
        :meth:`undo_tare` brings it back.

        With ``check`` (the live view's Tare), the window must pass
        :func:`~pito_core.devices.check_tare` — still, and loaded only as known: unloaded, or with
        a ``support`` (:class:`~pito_core.devices.TareSupport`: mass, base face) at rest on its
        base face, which then reads the object's weight after the tare (``known_load`` in the event).

        Raises
        ------
        TareRefused
            ``check`` and the window is not still or carries a load not known (``.check.reason`` says which).
        ValueError
            No sample processed yet, or ``duration`` not > 0.
        """
        if not duration > 0:
            raise ValueError(f"duration: expected > 0 s, got {duration!r}")
        tail = self._tail.last(copy=False)
        if tail["time"].size == 0:
            raise ValueError("tare: no sample processed yet")
        sel = tail["time"] >= tail["time"][-1] - duration
        extra, expected = {}, None
        if check:
            verdict = check_tare(tail["counts"][sel], tail["reference"][sel], self.calibration, support, self.core)
            if not verdict.ok:
                raise TareRefused(verdict)
            extra.update(checked=True, state=verdict.state)
            expected = verdict.expected
        extra["taken_at"] = time.time()  # wall clock, s: for the operator's "tare taken at"
        event = tare_event(tail["counts"][sel], tail["reference"][sel], duration=duration,
                           previous_bias=self.reference_bias, calibration=self.calibration, expected=expected,
                           from_tick=None if self.last_tick is None else self.last_tick + 1, **extra)
        self.apply_tare(event)
        return event

    def undo_tare(self) -> dict:
        """Bring back the tare before the last :meth:`tare` (the calibration's own zero if none).

        Returns it as an event (``undo`` True) for a recording. Raises ``ValueError`` if there is
        nothing to undo.
        """
        if not self._tare_history:
            raise ValueError("tare: no tare to undo")
        offset, bias = self._tare_history.pop()
        event = {"type": "tare", "counts_offset": None if offset is None else offset.tolist(),
                 "reference_bias": bias.tolist(), "undo": True,
                 "from_tick": None if self.last_tick is None else self.last_tick + 1}
        self._set_tare(offset, bias)
        return event

    @property
    def tare_in_force(self) -> dict | None:
        """The last tare applied (its event), or None: the calibration's own zero."""
        return self._tare_event

    def apply_tare(self, event: dict) -> None:
        """Set the tare of an event made by :meth:`tare` (replay); ``counts_offset`` None: the calibration's zero."""
        self._tare_history.append((self.counts_offset, self.reference_bias.copy()))
        del self._tare_history[:-20]
        off = event.get("counts_offset")
        self._set_tare(None if off is None else np.asarray(off, dtype=float),
                       np.asarray(event["reference_bias"], dtype=float))
        self._tare_event = None if off is None else dict(event)

    def _set_tare(self, offset, bias) -> None:
        self.counts_offset = offset
        self.reference_bias = bias
        if offset is None:
            self._tare_event = None
        self._wtail.clear()

    def reset(self) -> None:
        """Forget the samples seen (reference history, waiting samples, tails); keep calibration and tare."""
        self._ref.clear()
        self._tail.clear()
        self._wtail.clear()
        self._pending = None
        self.last_tick = None

    # ------------------------------------------------------------ the pipeline
    def feed(self, samples, *, flush: bool = False) -> LiveBundle:
        """:meth:`process` one read of a reader (``NewSamples``): restarts, then tare events at their sample.

        A tare event's ``from_tick`` splits the cube rows: the rows before it are processed
        with the tare in force before, the rest with the event's tare (as live).
        """
        if samples.restart:
            self.reset()
        cube, ref = samples.cube, samples.reference
        events = sorted((e for e in samples.events if e.get("from_tick") is not None), key=lambda e: e["from_tick"])
        if not events or cube is None or "tick" not in cube:
            return self.process(cube, ref, flush=flush)
        out = None
        for ev in events:
            k = int(np.searchsorted(cube["tick"], int(ev["from_tick"]), side="left"))
            head = {key: v[:k] for key, v in cube.items()}
            b = self.process(head, ref, flush=True)
            ref = None
            self.apply_tare(ev)
            cube = {key: v[k:] for key, v in cube.items()}
            out = b if out is None else out.merged(b)
        b = self.process(cube, None, flush=flush)
        return out.merged(b)

    def process(self, cube: dict | None, reference: dict | None = None, *, flush: bool = False) -> LiveBundle:
        """Turn the new rows of both devices into one bundle.

        Parameters
        ----------
        cube : dict or None
            New cube rows: ``time (n,)`` s (pairing rule), ``counts (n, 36)``, optional
            ``tick (n,)`` µs. Rows come in order, each once.
        reference : dict or None
            New reference rows: ``time (m,)`` s, ``wrench (m, 6)`` N and N·m (raw, not tared).
        flush : bool
            Pass every waiting cube sample now (the end of a recording).

        Returns
        -------
        LiveBundle
            The cube samples whose records became complete (paired), in order; the cube
            samples that arrived (``arrived_time``, ``arrived_face_wrenches``) and the wrenches
            and contacts of the newest of them (``contacts_time``).
        """
        if reference is not None and len(reference["time"]):
            self._ref.append(time=np.asarray(reference["time"], dtype=np.float64),
                             wrench=np.asarray(reference["wrench"], dtype=np.float64))
        arrived = self._arrive(cube)
        rows = self._take_ready(arrived, flush)
        t, counts = rows["time"], rows["counts"]
        ref_hist = self._ref.last(copy=False)
        if self.has_reference and t.size:
            raw_ref = pair_reference(t, ref_hist["time"], ref_hist["wrench"])
        else:
            raw_ref = np.full((t.size, 6), np.nan)
        tick = rows.get("tick")
        self.samples += t.size
        self._tail.append(time=t, counts=counts, reference=raw_ref)
        b = LiveBundle(t, counts, raw_ref - rows["bias"], tick=tick)
        if "w" in rows and t.size:
            b.face_wrenches = rows["w"]
        if arrived is not None:
            b.arrived_time = arrived["time"]
            b.arrived_tick = arrived.get("tick")
            W = arrived.get("w")
            if W is not None:
                b.arrived_face_wrenches = W
                self._wtail.append(w=W, counts=arrived["counts"])
                tail = self._wtail.last(copy=False)
                latest = tail["w"].mean(axis=0)
                b.wrenches = latest
                b.contacts_time = float(arrived["time"][-1])
                b.sum_force, b.sum_torque = face_sums(latest, self.core, self.cog)
                if self.coverage is not None:
                    if not self.coverage.net_load:  # a sum over unmeasured directions: none
                        b.sum_force, b.sum_torque = np.full(3, np.nan), np.full(3, np.nan)
                    b.measured = self.coverage.faces
                cov = self._latest_cov(tail["counts"])
                b.contacts = self.contacts(latest, cov)
                # a gauge at its ADC limit (saturated: the true load is unknown) in the samples behind the
                # latest wrenches: no valid contact (every face's wrench depends on all 36 gauges through
                # the calibration matrix)
                if (np.abs(tail["counts"]) >= CUBE_ADC_LIMIT).any() and b.contacts is not None:
                    b.contacts.valid[...] = False
                if self.sample_contacts:  # each arrived sample's own contacts, by the same solve
                    b.arrived_contacts = self.contacts(W, cov)
                    saturated = (np.abs(arrived["counts"]) >= CUBE_ADC_LIMIT).any(axis=1)
                    if saturated.any():
                        b.arrived_contacts.valid[saturated] = False
        return b

    def _arrive(self, cube: dict | None) -> dict | None:
        """New cube rows with what the cube alone gives: the tare in force, face wrenches (if calibrated)."""
        if cube is None or not len(cube["time"]):
            return None
        new = {k: np.asarray(cube[k]) for k in ("time", "counts", "tick") if k in cube}
        new["counts"] = np.asarray(new["counts"], dtype=np.float64)
        n = new["time"].size
        new["bias"] = np.broadcast_to(self.reference_bias, (n, 6))  # the reference's tare, applied when paired
        if self.calibration is not None:
            new["w"] = self._masked(self.calibration.wrenches(new["counts"], offset=self.counts_offset))
        tick = new.get("tick")
        if tick is not None and tick.size:
            self.last_tick = int(tick[-1])
        return new

    def _masked(self, W):
        """Face wrenches with NaN where the calibration does not measure (``Calibration.coverage``)."""
        return W if self.coverage is None else self.coverage.mask(W)

    def _latest_cov(self, counts):
        """The wrench covariance for the latest contacts (``wrench_cov``; see the class docstring) at ``counts (k, 36)``."""
        if not isinstance(self.wrench_cov, str):
            return self.wrench_cov
        if getattr(self.calibration, "covariance", None) is None:
            return None
        counts = counts.mean(axis=0)
        return self.calibration.wrenches(counts, offset=self.counts_offset, return_cov=True)[1]

    def contacts(self, wrenches, wrench_cov=None) -> ContactEstimate:
        """Contacts (core frame, fields ``(..., 6, …)``) of face wrenches ``(..., 6, 6)`` on the object's patches.

        ``wrench_cov``: ``(6, 6)`` or ``(6, 6, 6)`` covariance for the point covariance (default none)
        and the single-contact test (``single_contact``, ``single_contact_p``,
        ``single_contact_reason`` per face; without a covariance the test assumes
        ``DEFAULT_WRENCH_COV``; docs/contact.md).
        """
        assembly = self.assembly if self.assembly is not None else "cube"
        return solve_object(assembly, wrenches, self.force_threshold, wrench_cov=wrench_cov)

    def _take_ready(self, new: dict | None, flush: bool) -> dict:
        """The waiting and new cube rows whose reference has arrived (pairing rule: never extrapolate)."""
        rows = self._pending
        if new is not None:
            rows = new if rows is None else {k: np.concatenate([rows[k], new[k]]) for k in new}
        if rows is None:
            return {"time": np.zeros(0), "counts": np.zeros((0, N_GAUGES)), "bias": np.zeros((0, 6))}
        if not self.has_reference or flush:
            n = rows["time"].size
        else:
            ref_t = self._ref.last(1, copy=False)["time"]
            newest = ref_t[0] if ref_t.size else -np.inf
            n = int(np.searchsorted(rows["time"], newest, side="right"))
            # a reference that stopped: samples older than max_wait pass with NaN
            n = max(n, int(np.searchsorted(rows["time"], rows["time"][-1] - self.max_wait, side="right")))
        ready = {k: v[:n] for k, v in rows.items()}
        self._pending = {k: v[n:] for k, v in rows.items()} if n < rows["time"].size else None
        return ready

    @property
    def waiting(self) -> int:
        """Cube samples waiting for the reference."""
        return 0 if self._pending is None else int(self._pending["time"].size)

"""The pipeline's output: one numpy bundle per read (:class:`LiveBundle`), and the face sums."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..contact import ContactEstimate
from ..frames import CubeCore, cross_rows

__all__ = ["LiveBundle", "face_sums"]


@dataclass
class LiveBundle:
    """What the pipeline made of the new samples of one read (numpy arrays, SI units).

    Attributes
    ----------
    time : ndarray, shape (n,)
        Sample times of the new cube samples, s (host clock, by the pairing rule).
    counts : ndarray, shape (n, 36)
        Raw gauge counts (not tared), face i in columns ``6(i−1) … 6i−1``.
    reference : ndarray, shape (n, 6)
        Reference ``[fx, fy, fz, tx, ty, tz]`` paired to each cube sample and tared, N and
        N·m in the reference frame; NaN rows where there is no reference.
    stats : dict
        Device figures: ``rate_cube``/``rate_reference`` (Hz), ``saturated``, ``dropped``
        (frames), ``simulated``, ``backlog`` (s).
    wrenches : ndarray, shape (6, 6) or None
        Wrench on each face in its frame at the latest sample (mean of the last
        ``Pipeline.smooth`` samples), tared, ``[fx, fy, fz, tx, ty, tz]`` N and N·m; NaN
        for faces without output. None without a calibration.
    contacts : ContactEstimate or None
        Contacts of ``wrenches`` on the object's patches, core frame (``frame = "core"``),
        fields of shape ``(6, …)`` (face i at index i−1): ``point`` m, ``normal``, ``force``
        N (on the object), ``torsion`` N·m, ``valid``, the single-contact test, the
        covariances m², N² or None.
    sum_force, sum_torque : ndarray, shape (3,) or None
        Σ of the face loads in the core frame (N; N·m about the object's centre of gravity);
        NaN when the calibration does not measure the net load (``Calibration.coverage``).
    measured : ndarray of bool, shape (6, 6) or None
        Face axes the calibration measures (``Calibration.coverage.faces``); ``wrenches``,
        the face wrenches and the contacts are NaN / invalid elsewhere. None without a calibration.
    recorded : int
        Cube samples recorded so far in the current recording (0 when not recording).
    replay_position, replay_duration : float or None
        Replay: s into the recording, and its length.
    tick : ndarray of int64, shape (n,) or None
        The cube's unwrapped device clock, µs (identifies samples across live and replay).
    face_wrenches : ndarray, shape (n, 6, 6) or None
        Wrench on each face at every new sample (face frames, tared, N and N·m).
    arrived_time : ndarray, shape (m,) or None
        The cube samples that arrived in this read, s. Their face wrenches and the contacts
        are made at once; their records (``time`` … ``face_wrenches``) follow when their
        reference has arrived (pairing rule), in this bundle or a later one. For a display:
        each cube sample arrives exactly once.
    arrived_face_wrenches : ndarray, shape (m, 6, 6) or None
        Face wrenches of the arrived samples (the same values their records will carry).
    arrived_tick : ndarray of int64, shape (m,) or None
        The arrived samples' device clock, µs (unwrapped): the time base of the live streams.
    arrived_contacts : ContactEstimate or None
        Contacts of each arrived sample's face wrenches (core frame, fields ``(m, 6, …)``), as
        ``contacts`` is of the latest wrenches; only when the pipeline keeps them
        (``Pipeline(sample_contacts=True)``: the LSL streams), else None.
    contacts_time : float
        Time of the newest sample behind ``wrenches``, ``contacts`` and the sums, s (NaN when
        the bundle has none).
    """

    time: np.ndarray
    counts: np.ndarray
    reference: np.ndarray
    stats: dict = field(default_factory=dict)
    wrenches: np.ndarray | None = None
    contacts: ContactEstimate | None = None
    sum_force: np.ndarray | None = None
    sum_torque: np.ndarray | None = None
    recorded: int = 0
    replay_position: float | None = None
    replay_duration: float | None = None
    tick: np.ndarray | None = None
    face_wrenches: np.ndarray | None = None
    arrived_time: np.ndarray | None = None
    arrived_face_wrenches: np.ndarray | None = None
    arrived_tick: np.ndarray | None = None
    arrived_contacts: ContactEstimate | None = None
    contacts_time: float = float("nan")
    measured: np.ndarray | None = None

    @property
    def latest_time(self) -> float:
        """Time of the newest sample, s (NaN when the bundle has none)."""
        return float(self.time[-1]) if self.time.size else float("nan")

    def __len__(self) -> int:
        return int(self.time.size)

    def merged(self, newer: "LiveBundle") -> "LiveBundle":
        """One bundle with the samples of both (this one first) and the latest derived values.

        For a consumer that fell behind: no sample is lost, the newest state wins.
        """
        na, nb = len(self), len(newer)

        def cat(a, b):
            if a is not None and b is not None:
                return np.concatenate([a, b])
            if a is None and na == 0:
                return b
            if b is None and nb == 0:
                return a
            return None

        out = LiveBundle(np.concatenate([self.time, newer.time]), np.concatenate([self.counts, newer.counts]),
                         np.concatenate([self.reference, newer.reference]), stats=newer.stats,
                         recorded=newer.recorded, replay_position=newer.replay_position,
                         replay_duration=newer.replay_duration, tick=cat(self.tick, newer.tick),
                         face_wrenches=cat(self.face_wrenches, newer.face_wrenches),
                         arrived_time=_cat_arrived(self.arrived_time, newer.arrived_time),
                         arrived_face_wrenches=_cat_arrived(self.arrived_face_wrenches, newer.arrived_face_wrenches),
                         arrived_tick=_cat_arrived(self.arrived_tick, newer.arrived_tick),
                         arrived_contacts=_cat_contacts(self, newer))
        src = newer if newer.wrenches is not None else self
        out.wrenches, out.contacts, out.contacts_time = src.wrenches, src.contacts, src.contacts_time
        out.sum_force, out.sum_torque = src.sum_force, src.sum_torque
        out.measured = src.measured
        return out


def _cat_arrived(a, b):
    """Arrived rows of two bundles, in order (a bundle without arrivals has None)."""
    if a is None or b is None:
        return b if a is None else a
    return np.concatenate([a, b])


def _cat_contacts(a: LiveBundle, b: LiveBundle) -> ContactEstimate | None:
    """Per-sample contacts of two bundles' arrived rows, in order; None unless every arrived row has its own."""
    na = 0 if a.arrived_time is None else len(a.arrived_time)
    nb = 0 if b.arrived_time is None else len(b.arrived_time)
    ca, cb = a.arrived_contacts, b.arrived_contacts
    if nb == 0 and (na == 0 or ca is not None):
        return ca
    if na == 0 and cb is not None:
        return cb
    if ca is None or cb is None:
        return None
    return ContactEstimate.concatenate([ca, cb])


def face_sums(wrenches, core: CubeCore, cog=(0.0, 0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    """Σ of the face wrenches ``(6, 6)`` (face frames) in the core frame: ``(ΣF (3,) N, ΣT (3,) N·m)``.

    Faces with NaN (no output) are left out. Moments about ``cog`` (core frame, m), the
    object's centre of gravity: in a still grasp ‖ΣF‖ = m·g and ΣT = 0 about it.
    """
    W = np.asarray(wrenches, dtype=float)
    T = core.face_poses()  # (6, 4, 4) T_core_face
    R, p = T[:, :3, :3], T[:, :3, 3]
    ok = np.isfinite(W).all(axis=1)
    fm = np.einsum("kij,klj->kli", R, W.reshape(6, 2, 3))[ok]  # (k, 2, 3): forces and moments, core frame
    f = fm[:, 0]
    force = f.sum(axis=0)
    moment = fm[:, 1].sum(axis=0) + cross_rows(p[ok], f).sum(axis=0)
    return force, moment - cross_rows(np.asarray(cog, dtype=float), force)

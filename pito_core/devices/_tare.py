"""The one tare: its checks (still, and loaded only as known) and its event, for the wizard, the live view and the recorder.

A tare is right only when nothing moves and every load on the cube is known: then the mean counts
are the gauges' readings of those loads. Two states are known:

- **unloaded** — in a stand that holds the core (a ``frame`` flange, or hung by it), hands off:
  every face carries nothing;
- **at rest** — the object stands still on a table on its *base face* b, hands off: face b
  carries the object's weight, ``F = −m g n_b`` (``n_b`` its outward normal) with the moment
  ``(c − p_b) × F`` about its origin (``c`` the centre of gravity), every other face nothing
  (:func:`resting_load`; ``m``, ``b`` and ``c`` from a :class:`TareSupport`).

:func:`check_tare` says whether a window of samples is such a moment (and why not, naming the load
and its size, in one line); :func:`tare_event` turns the window into the event that
``Pipeline.apply_tare`` applies and a recording replays: ``counts_offset`` is the counts at which
the calibration reads zero on every face — the window's mean when unloaded, and at rest the mean
less the counts of the known weight (:func:`counts_offset_for`), so that face b reads m·g after it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..defaults import (
    TARE_NO_LOAD_FORCE_N, TARE_NO_LOAD_TORQUE_NM, TARE_STILL_FORCE_STD_N, TARE_STILL_TORQUE_STD_NM,
)
from ..frames import N_GAUGES, CubeCore, check_face

__all__ = ["TareCheck", "TareRefused", "TareSupport", "check_tare", "tare_event", "resting_load",
           "counts_offset_for", "MIN_TARE_SAMPLES", "FACE_STILL_FACTOR", "STANDARD_GRAVITY"]

#: Fewest samples a tare is taken from.
MIN_TARE_SAMPLES = 10
#: The face wrenches' spread may exceed the reference's stillness limits by this factor (the cube's own noise).
FACE_STILL_FACTOR = 4.0
#: g, m/s² (the weight of a resting object).
STANDARD_GRAVITY = 9.81


class TareRefused(ValueError):
    """A tare was asked for while the cube moved or carried a load not known; ``check`` says which."""

    def __init__(self, check: "TareCheck"):
        super().__init__(f"tare refused: {check.reason}")
        self.check = check

    def __reduce__(self):  # pickles as itself (it crosses the pipeline process's boundary)
        return (TareRefused, (self.check,))


@dataclass(frozen=True)
class TareSupport:
    """What holds the object still when a tare is asked for at rest on a table.

    Attributes
    ----------
    mass : float
        The object's mass, kg (> 0).
    base_face : int
        The face it stands on, 1..6.
    cog : tuple of 3 floats, or None
        Its centre of gravity in the core frame, m (None: the core centre).
    """

    mass: float
    base_face: int = 6
    cog: tuple | None = None

    def __post_init__(self):
        m = float(self.mass)
        if not (np.isfinite(m) and m > 0):
            raise ValueError(f"mass: expected a positive mass in kg, got {self.mass!r}")
        object.__setattr__(self, "mass", m)
        object.__setattr__(self, "base_face", check_face(self.base_face, "base_face"))
        if self.cog is not None:
            c = np.asarray(self.cog, dtype=float).reshape(-1)
            if c.shape != (3,) or not np.isfinite(c).all():
                raise ValueError(f"cog: expected 3 finite coordinates in m, got {self.cog!r}")
            object.__setattr__(self, "cog", tuple(float(v) for v in c))

    @property
    def weight(self) -> float:
        """m·g, N."""
        return self.mass * STANDARD_GRAVITY


def resting_load(support: TareSupport, core: CubeCore | None = None) -> np.ndarray:
    """Face wrenches ``(6, 6)`` (face frames, N and N·m, moment about each face's origin) of an
    object standing still on ``support.base_face``: that face carries ``[−m g n_b, (c − p_b) × F]``
    (the table pushes it up, through the pressure centre under ``c``), the others nothing."""
    core = CubeCore() if core is None else core
    T = core.face_pose(support.base_face)
    R, p = T[:3, :3], T[:3, 3]
    c = np.zeros(3) if support.cog is None else np.asarray(support.cog, dtype=float)
    F = -support.weight * R[:, 2]  # core frame: opposite the base face's outward normal (up)
    W = np.zeros((6, 6))
    W[support.base_face - 1, :3] = R.T @ F
    W[support.base_face - 1, 3:] = R.T @ np.cross(c - p, F)
    return W


@dataclass(frozen=True)
class TareCheck:
    """Whether a window of samples may be a tare, and the figures behind the verdict.

    Attributes
    ----------
    ok : bool
    reason : str
        Why not, in one line ("" when ok).
    n : int
        Samples in the window.
    reference_force_std, reference_torque_std : float
        Largest standard deviation of the reference's force (N) / torque (N·m) axes; NaN without a reference.
    face_load : float
        Largest face force from the calibration's own zero, N (NaN without a calibration).
    face_torque : float
        Largest face torque from it, N·m.
    face : int
        The face carrying ``face_load`` (0 without a calibration).
    state : str
        The known state the window matches ("unloaded", "at rest on face b"), or the closest one when refused.
    excess_force, excess_torque : float
        Largest departure of a face's mean wrench from that state's loads, N and N·m.
    expected : ndarray, shape (6, 6), or None
        That state's face wrenches (N, N·m; zeros when unloaded); None without a calibration.
    """

    ok: bool
    reason: str
    n: int
    reference_force_std: float = float("nan")
    reference_torque_std: float = float("nan")
    face_load: float = float("nan")
    face_torque: float = float("nan")
    face: int = 0
    state: str = "unloaded"
    excess_force: float = float("nan")
    excess_torque: float = float("nan")
    expected: np.ndarray | None = None


def _pair(value: float, limit: float, unit: str, scale: float = 1.0) -> str:
    """``value`` and ``limit`` with as many decimals as it takes for them not to read alike."""
    v, lim = value * scale, limit * scale
    for d in range(2, 7):
        if round(v, d) != round(lim, d):
            break
    return f"{v:.{d}f} {unit} (limit {lim:.{d}f} {unit})"


def _reference_spread(reference):
    r = np.asarray(reference, dtype=float)
    r = r[np.isfinite(r).all(axis=1)] if r.ndim == 2 and r.shape[1] == 6 else np.zeros((0, 6))
    if r.shape[0] < MIN_TARE_SAMPLES:
        return float("nan"), float("nan")
    return float(r[:, :3].std(axis=0).max()), float(r[:, 3:].std(axis=0).max())


def check_tare(counts, reference=None, calibration=None, support: TareSupport | None = None,
               core: CubeCore | None = None) -> TareCheck:
    """Whether ``counts (n, 36)`` (and the paired ``reference (n, 6)``, N and N·m) can be a tare.

    Still: the reference's spread under ``TARE_STILL_FORCE_STD_N`` and ``TARE_STILL_TORQUE_STD_NM``
    (``pito_core.defaults``); with a ``calibration`` (anything with ``wrenches(counts)`` giving face
    wrenches ``(n, 6, 6)`` from its own zero), also each face's spread under ``FACE_STILL_FACTOR``
    times those. Loaded only as known (needs a calibration): every face's mean wrench within
    ``TARE_NO_LOAD_FORCE_N`` / ``TARE_NO_LOAD_TORQUE_NM`` of a known state — unloaded, or, with a
    ``support``, at rest on its base face (:func:`resting_load`, ``core`` default ``CubeCore()``).
    Refused, the reason names the face, its load and the figure it should be. Without a reference
    nor a calibration nothing can tell, and the tare is refused.
    """
    c = np.asarray(counts, dtype=float)
    n = int(c.shape[0]) if c.ndim == 2 else 0
    if c.ndim != 2 or c.shape[1] != N_GAUGES:
        raise ValueError(f"counts: expected shape (n, {N_GAUGES}), got {c.shape}")
    if n < MIN_TARE_SAMPLES:
        return TareCheck(False, f"only {n} samples (at least {MIN_TARE_SAMPLES})", n)
    sf, st = _reference_spread(np.zeros((0, 6)) if reference is None else reference)
    fig = {"reference_force_std": sf, "reference_torque_std": st}
    if calibration is None:
        if np.isfinite(sf) and (sf >= TARE_STILL_FORCE_STD_N or st >= TARE_STILL_TORQUE_STD_NM):
            what = (_pair(sf, TARE_STILL_FORCE_STD_N, "N") if sf >= TARE_STILL_FORCE_STD_N
                    else _pair(st, TARE_STILL_TORQUE_STD_NM, "mN·m", 1000))
            return TareCheck(False, f"the reference moved: spread {what} — hold still", n, **fig)
        if not np.isfinite(sf):
            return TareCheck(False, "no reference and no calibration: nothing tells that the cube is still and "
                                    "unloaded — load a calibration first", n, **fig)
        return TareCheck(True, "", n, **fig)
    W = np.asarray(calibration.wrenches(c), dtype=float)  # (n, 6, 6) from the calibration's own zero
    mean = np.nan_to_num(W.mean(axis=0))  # (6, 6); faces without output read 0
    F, T = np.linalg.norm(mean[:, :3], axis=1), np.linalg.norm(mean[:, 3:], axis=1)
    spread = np.nan_to_num(W[..., :3].std(axis=0).max(axis=1))  # (6,) N
    k = int(np.argmax(F))
    fig.update(face_load=float(F[k]), face_torque=float(T.max()), face=k + 1)
    # the known states, the closest first
    states = [("unloaded", np.zeros((6, 6)))]
    if support is not None:
        states.append((f"at rest on face {support.base_face}", resting_load(support, core)))
    measured = ~np.isnan(W[0]).all(axis=1)  # (6,) faces the calibration outputs
    scored = []
    for name, E in states:
        dF = np.where(measured, np.linalg.norm(mean[:, :3] - E[:, :3], axis=1), 0.0)
        dT = np.where(measured, np.linalg.norm(mean[:, 3:] - E[:, 3:], axis=1), 0.0)
        scored.append((max(dF.max() / TARE_NO_LOAD_FORCE_N, dT.max() / TARE_NO_LOAD_TORQUE_NM), name, E, dF, dT))
    score, name, E, dF, dT = min(scored, key=lambda s: s[0])
    fig.update(state=name, excess_force=float(dF.max()), excess_torque=float(dT.max()), expected=E)
    loaded = score >= 1.0
    limit = FACE_STILL_FACTOR * TARE_STILL_FORCE_STD_N
    moving = spread >= limit
    ref_moved = np.isfinite(sf) and (sf >= TARE_STILL_FORCE_STD_N or st >= TARE_STILL_TORQUE_STD_NM)
    if not (loaded or moving.any() or ref_moved):
        return TareCheck(True, "", n, **fig)
    parts = []
    if loaded:
        j = int(np.argmax(np.maximum(dF / TARE_NO_LOAD_FORCE_N, dT / TARE_NO_LOAD_TORQUE_NM)))
        load = f"face {j + 1} carries {F[j]:.2f} N, {T[j] * 1000:.1f} mN·m"
        lim = f"limits {TARE_NO_LOAD_FORCE_N} N, {TARE_NO_LOAD_TORQUE_NM * 1000:g} mN·m"
        ok_load = float(np.linalg.norm(E[j, :3]))
        if ok_load > 0:
            parts.append(f"{load} where the object at rest puts {ok_load:.2f} N ({support.mass:g} kg): "
                         f"{dF[j]:.2f} N, {dT[j] * 1000:.1f} mN·m off ({lim})")
        else:
            parts.append(f"{load} ({lim} with nothing on it)")
    if moving.any():
        j = int(np.argmax(spread))
        parts.append(f"face {j + 1} {'also ' if parts else ''}moves: spread {_pair(spread[j], limit, 'N')}")
    if ref_moved and not parts:
        what = (_pair(sf, TARE_STILL_FORCE_STD_N, "N") if sf >= TARE_STILL_FORCE_STD_N
                else _pair(st, TARE_STILL_TORQUE_STD_NM, "mN·m", 1000))
        parts.append(f"the reference moved: spread {what}")
    advice = ("hold still" if not loaded else
              f"take your hands off: tare in a stand, or at rest on face {support.base_face}" if support is not None
              else "take every load off the cube (its weight on a table too: give the object's mass to tare at rest)")
    return TareCheck(False, "; ".join(parts) + f" — {advice}", n, **fig)


def counts_offset_for(calibration, counts_mean, expected, iterations: int = 4) -> np.ndarray:
    """Counts ``o (36,)`` with ``calibration.wrenches(counts_mean, offset=o) ≈ expected (6, 6)``.

    The least change from ``counts_mean`` (the unloaded tare) that makes the calibration read
    the known loads ``expected`` (face frames, N and N·m) at ``counts_mean``: Newton steps on
    the least-norm solution of the calibration's Jacobian (faces it outputs only).
    """
    cm = np.asarray(counts_mean, dtype=float).reshape(N_GAUGES)
    E = np.asarray(expected, dtype=float).reshape(6, 6)
    if not E.any():
        return cm.copy()
    zero = np.zeros(N_GAUGES)
    x = np.zeros(N_GAUGES)  # counts above the offset
    h = 1.0  # counts
    for _ in range(iterations):
        X = x + np.vstack([np.zeros(N_GAUGES), h * np.eye(N_GAUGES)])
        W = np.asarray(calibration.wrenches(X, offset=zero), dtype=float).reshape(N_GAUGES + 1, -1)
        rows = np.isfinite(W).all(axis=0)
        J = (W[1:, rows] - W[0, rows]).T / h  # (m, 36)
        r = E.reshape(-1)[rows] - W[0, rows]
        x = x + np.linalg.lstsq(J, r, rcond=None)[0]
    return cm - x


def tare_event(counts, reference, *, from_tick, duration: float, previous_bias, calibration=None,
               expected=None, **extra) -> dict:
    """The tare event of a window: ``counts_offset`` (36,) counts, ``reference_bias`` (6,) N and N·m.

    ``counts_offset`` is the window's mean counts, or with known loads ``expected (6, 6)`` (face
    frames, N and N·m; needs the ``calibration``) the counts at which the calibration reads zero
    (:func:`counts_offset_for`); the event then keeps ``known_load`` (the (6, 6) list). ``reference (n, 6)``
    may hold NaN rows (no reference paired): the bias is the mean of the finite rows, or ``previous_bias``
    without any — and with known loads too (what the reference carries of them is not known here).
    ``from_tick`` (µs) is the first cube tick it applies to; ``extra`` fields are added
    (e.g. ``host_time``, ``check``).
    """
    c = np.asarray(counts, dtype=float)
    r = np.asarray(reference, dtype=float).reshape(-1, 6)
    finite = np.isfinite(r).all(axis=1)
    known = expected is not None and np.asarray(expected, dtype=float).any()
    if known and calibration is None:
        raise ValueError("expected: a tare on known loads needs the calibration")
    bias = r[finite].mean(axis=0) if finite.any() and not known else np.asarray(previous_bias, dtype=float)
    offset = counts_offset_for(calibration, c.mean(axis=0), expected) if known else c.mean(axis=0)
    if known:
        extra["known_load"] = np.asarray(expected, dtype=float).tolist()
    return {"type": "tare", "counts_offset": offset.tolist(), "reference_bias": bias.tolist(),
            "duration": float(duration), "from_tick": None if from_tick is None else int(from_tick), **extra}

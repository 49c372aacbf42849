"""Calibration sessions: gauge counts beside a reference sensor, with the mount.

The session is data and its file format (``io``): devices build it, the simulator writes
it, :mod:`pito_core.calibration` fits it. It imports nothing of ``calibration``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Iterator

import numpy as np

from ..frames import N_GAUGES, CubeCore, check_face, check_pose, invert_pose
from ._csv import read_session_csv_fields, write_session_csv
from ._hdf5 import FileFormatError
from ._session_file import read_session_fields, write_session

__all__ = ["CalibrationSession", "FLANGES", "SessionBlock", "DEFAULT_COUNTS_RANGE", "few_indices"]

#: Flange types (docs/conventions.md, "Calibration mounts").
FLANGES = ("frame", "frame_hole", "face")

#: Counts at or beyond these limits are saturated, unless a session says otherwise (int32 range).
DEFAULT_COUNTS_RANGE = (-(2**31), 2**31 - 1)


@dataclass(frozen=True)
class SessionBlock:
    """A contiguous block of samples ``[start, stop)`` of a session, as arrays."""

    start: int
    counts: np.ndarray  # (n, 36) float64 (the stored dtype from iter_blocks(counts_dtype=None))
    reference: np.ndarray  # (n, 6) float64
    loaded: np.ndarray  # (n, 6) bool


def _as_2d(x, ncols: int, name: str, dtype=None, lazy: bool = False):
    if lazy and hasattr(x, "shape") and hasattr(x, "dtype") and not isinstance(x, np.ndarray):
        shape = tuple(x.shape)  # an h5py dataset: checked blockwise when read
        a = x
    else:
        a = np.asarray(x) if dtype is None else np.asarray(x, dtype=dtype)
        shape = a.shape
    if len(shape) != 2 or shape[1] != ncols:
        raise ValueError(f"{name}: expected shape (N, {ncols}), got {shape}")
    return a


class CalibrationSession:
    """One calibration recording: counts beside the reference, under one mount.

    Parameters
    ----------
    counts : array-like, shape (N, 36)
        Raw gauge readings, counts; face i owns columns ``6(i-1) .. 6i-1``.
    reference : array-like, shape (N, 6)
        Reference sensor reading ``[fx, fy, fz, tx, ty, tz]`` in N and N·m: the total
        load applied on the object, tared, in the reference frame (S_A).
    loaded : array-like of bool, shape (N, 6)
        ``loaded[n, i-1]`` is True where face i is under load in sample n; a row of all
        False is an unloaded sample (used for the offsets).
    T_core_ati : array-like, shape (4, 4)
        Pose of the reference sensor's frame in the core frame.
    flange : {"frame", "frame_hole", "face"}
        The calibration mount (docs/conventions.md, "Calibration mounts").
    connected_face : int
        The face the flange is on, 1..6.
    core : CubeCore, optional
        Geometry of the core; default ``CubeCore()``.
    time : array-like, shape (N,), optional
        Sample times in s (host clock); default ``arange(N)`` × nan is not used: None.
    meta : dict, optional
        Free metadata (JSON-serialisable values: str, numbers, bools, lists, dicts).
    counts_range : (int, int), optional
        ADC limits: a count ``<= lo`` or ``>= hi`` is saturated. Default int32 limits.

    Raises
    ------
    ValueError
        Naming the field and what was expected.
    """

    def __init__(
        self,
        counts,
        reference,
        loaded,
        T_core_ati,
        flange,
        connected_face,
        *,
        core: CubeCore | None = None,
        time=None,
        meta: dict | None = None,
        counts_range=None,
        _lazy: bool = False,
    ):
        counts = _as_2d(counts, N_GAUGES, "counts", lazy=_lazy)
        reference = _as_2d(reference, 6, "reference", lazy=_lazy)
        loaded = _as_2d(loaded, 6, "loaded", lazy=_lazy)
        n = counts.shape[0]
        for name, a in (("reference", reference), ("loaded", loaded)):
            if a.shape[0] != n:
                raise ValueError(f"{name}: expected {n} rows to match counts, got {a.shape[0]}")
        if not _lazy:
            if not (np.issubdtype(counts.dtype, np.integer) or np.issubdtype(counts.dtype, np.floating)):
                raise ValueError(f"counts: expected integer or float values, got dtype {counts.dtype}")
            if loaded.dtype != bool:
                if np.issubdtype(loaded.dtype, np.number) and np.all((loaded == 0) | (loaded == 1)):
                    loaded = loaded.astype(bool)
                else:
                    raise ValueError(f"loaded: expected booleans (or 0/1), got dtype {loaded.dtype}")
            reference = reference.astype(float, copy=False)
        if flange not in FLANGES:
            raise ValueError(f"flange: expected one of {FLANGES}, got {flange!r}")
        self.flange = str(flange)
        self.connected_face = check_face(connected_face, "connected_face")
        self.T_core_ati = check_pose(T_core_ati, "T_core_ati")
        if core is None:
            core = CubeCore()
        if not isinstance(core, CubeCore):
            raise ValueError(f"core: expected a CubeCore, got {type(core).__name__}")
        self.core = core
        if time is not None:
            time = np.asarray(time, dtype=float)
            if time.shape != (n,):
                raise ValueError(f"time: expected shape ({n},) to match counts, got {time.shape}")
        self.time = time
        meta = {} if meta is None else dict(meta)
        if not all(isinstance(k, str) for k in meta):
            raise ValueError("meta: expected string keys")
        self.meta = meta
        if counts_range is None:
            counts_range = DEFAULT_COUNTS_RANGE
        lo, hi = counts_range
        if not lo < hi:
            raise ValueError(f"counts_range: expected (lo, hi) with lo < hi, got {counts_range!r}")
        self.counts_range = (int(lo), int(hi))
        self.counts = counts
        self.reference = reference
        self.loaded = loaded
        if not _lazy:
            bad = np.flatnonzero(~np.isfinite(reference).all(axis=1))
            if bad.size:
                raise ValueError(f"reference: NaN or inf at sample indices {few_indices(bad)}")
            if np.issubdtype(counts.dtype, np.floating):
                bad = np.flatnonzero(~np.isfinite(counts).all(axis=1))
                if bad.size:
                    raise ValueError(f"counts: NaN or inf at sample indices {few_indices(bad)}")

    # ------------------------------------------------------------------ basics
    def __len__(self) -> int:
        return int(self.counts.shape[0])

    @property
    def n_samples(self) -> int:
        """Number of samples N."""
        return len(self)

    def __repr__(self) -> str:
        return (
            f"CalibrationSession(N={len(self)}, flange={self.flange!r}, "
            f"connected_face={self.connected_face}, edge={self.core.edge} m)"
        )

    def T_ati_face(self, i) -> np.ndarray:
        """``T_ati_face_i (4, 4)``: face i's frame in the reference frame."""
        return invert_pose(self.T_core_ati) @ self.core.face_pose(i)

    # ------------------------------------------------------------------ blocks
    def iter_blocks(self, block_size: int = 65536, counts_dtype=float) -> Iterator[SessionBlock]:
        """Yield the samples in order as :class:`SessionBlock` of at most ``block_size`` rows.

        File-backed sessions read one block at a time, so memory stays bounded. ``counts_dtype``
        None keeps the counts in their stored dtype (e.g. int32: no float copy of the block).
        """
        n = len(self)
        for start in range(0, n, block_size):
            stop = min(n, start + block_size)
            yield SessionBlock(
                start,
                np.asarray(self.counts[start:stop], dtype=counts_dtype),
                np.asarray(self.reference[start:stop], dtype=float),
                np.asarray(self.loaded[start:stop], dtype=bool),
            )

    def subset(self, index) -> "CalibrationSession":
        """A new in-memory session with the samples ``index`` (slice, mask or indices)."""
        if isinstance(index, slice):
            idx = index
        else:
            idx = np.asarray(index)
            if idx.dtype == bool:
                idx = np.flatnonzero(idx)
        return CalibrationSession(
            np.asarray(self.counts[idx] if not isinstance(idx, np.ndarray) else _take(self.counts, idx)),
            np.asarray(self.reference[idx] if not isinstance(idx, np.ndarray) else _take(self.reference, idx)),
            np.asarray(self.loaded[idx] if not isinstance(idx, np.ndarray) else _take(self.loaded, idx)),
            self.T_core_ati,
            self.flange,
            self.connected_face,
            core=self.core,
            time=None if self.time is None else self.time[idx],
            meta=self.meta,
            counts_range=self.counts_range,
        )

    def to_memory(self) -> "CalibrationSession":
        """This session with every array read into memory."""
        return self.subset(slice(None))

    def split(self, holdout: float = 0.2, block: int = 200, seed: int = 0):
        """Split into ``(train, test)`` sessions, ``holdout`` the test fraction.

        Stratified by load pattern (which faces are loaded): the samples of each
        pattern are cut into contiguous blocks of ``block`` samples and whole blocks
        are held out at random (``seed``), so every loaded face appears on both sides
        and slowly varying effects (drift, one loading gesture) do not leak across the
        split. Unloaded samples are shared out evenly (every k-th to the test side) so
        both sides keep their own tare.
        """
        if not 0.0 < holdout < 1.0:
            raise ValueError(f"holdout: expected a fraction in (0, 1), got {holdout!r}")
        rng = np.random.default_rng(seed)
        loaded = np.asarray(self.loaded[:], dtype=bool)
        code = loaded.astype(np.int64) @ (1 << np.arange(6))
        is_test = np.zeros(len(self), dtype=bool)
        for pattern in np.unique(code):
            idx = np.flatnonzero(code == pattern)
            if pattern == 0:
                is_test[idx[:: max(2, round(1.0 / holdout))]] = True
                continue
            n_blocks = -(-idx.size // block)
            if n_blocks < 2:
                chunks = np.array_split(idx, 2) if idx.size >= 2 else [idx]
                if len(chunks) == 2:
                    is_test[chunks[1]] = True
                continue
            n_test = min(n_blocks - 1, max(1, round(holdout * n_blocks)))
            for b in rng.permutation(n_blocks)[:n_test]:
                is_test[idx[b * block : (b + 1) * block]] = True
        return self.subset(~is_test), self.subset(is_test)

    # ------------------------------------------------------------------ files
    def save(self, path) -> None:
        """Write exactly ``path`` (HDF5, format ``pito-session`` v1; see docs/file-formats.md)."""
        write_session(path, self)

    @classmethod
    def load(cls, path, *, lazy: bool = False) -> "CalibrationSession":
        """Read a session written by :meth:`save`.

        With ``lazy=True`` the arrays stay on disk (h5py datasets) and are read block by
        block by :meth:`iter_blocks`; the file stays open while the session lives.
        """
        fields, f = read_session_fields(path, lazy=lazy)
        core_edge = fields.pop("core_edge")
        try:
            session = cls(**fields, core=CubeCore(core_edge), _lazy=lazy)
        except ValueError as exc:
            if f is not None:
                f.close()
            raise FileFormatError(f"{path}: inconsistent session: {exc}") from None
        if f is not None:
            session._file = f  # keeps the lazy datasets readable while the session lives
        return session

    @classmethod
    def from_csv(cls, path, *, flange, connected_face, T_core_ati=None, core=None, meta=None):
        """Read a session from a CSV file (columns documented in docs/file-formats.md)."""
        cols = read_session_csv_fields(path)
        return cls(
            cols["counts"], cols["reference"], cols["loaded"], np.eye(4) if T_core_ati is None else T_core_ati,
            flange, connected_face, core=core, time=cols["time"], meta=meta,
        )

    def to_csv(self, path) -> None:
        """Write the samples as CSV (the columns :meth:`from_csv` reads)."""
        write_session_csv(path, self)

    # ------------------------------------------------------------------ combine
    @staticmethod
    def concatenate(sessions) -> "CalibrationSession":
        """One in-memory session from several recorded under the same mount."""
        sessions = list(sessions)
        if not sessions:
            raise ValueError("sessions: expected at least one session")
        s0 = sessions[0]
        for s in sessions[1:]:
            if (s.flange, s.connected_face) != (s0.flange, s0.connected_face) or not np.allclose(
                s.T_core_ati, s0.T_core_ati
            ):
                raise ValueError("sessions: expected the same flange, connected_face and T_core_ati to concatenate")
        times = [s.time for s in sessions]
        return CalibrationSession(
            np.concatenate([np.asarray(s.counts) for s in sessions]),
            np.concatenate([np.asarray(s.reference) for s in sessions]),
            np.concatenate([np.asarray(s.loaded) for s in sessions]),
            s0.T_core_ati,
            s0.flange,
            s0.connected_face,
            core=s0.core,
            time=None if any(t is None for t in times) else np.concatenate(times),
            meta=s0.meta,
            counts_range=s0.counts_range,
        )


def _take(a, idx: np.ndarray) -> np.ndarray:
    if isinstance(a, np.ndarray):
        return a[idx]
    # h5py needs increasing indices; read the covering range in one go then take
    if idx.size == 0:
        return np.asarray(a[0:0])
    lo, hi = int(idx.min()), int(idx.max()) + 1
    return np.asarray(a[lo:hi])[idx - lo]


def few_indices(idx: np.ndarray, k: int = 10) -> str:
    """The first ``k`` of the sample indices ``idx`` for an error message: ``"[3, 9, … (40 in all)]"``."""
    head = ", ".join(str(int(i)) for i in idx[:k])
    more = f" … ({idx.size} in all)" if idx.size > k else ""
    return f"[{head}{more}]"

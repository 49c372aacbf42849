"""One ring buffer of named arrays (:class:`Ring`), and reading the acquisition's rings.

:class:`Ring` is the fixed-capacity ring every path uses: the acquisition's rings of both
streams (the cube's :data:`PITO_ROWS`, the reference's :data:`NETFT_ROWS`, read by write
cursor or host time through :class:`RingReader`) and the pipeline's reference history and
tails (:class:`~pito_core.pipeline.Pipeline`, read as views of the last rows).
"""

from __future__ import annotations

import numpy as np

from ..frames import N_GAUGES

__all__ = ["Ring", "PITO_ROWS", "NETFT_ROWS", "RingReader"]

#: The rows of the cube's ring: name -> (dtype, shape of one row).
PITO_ROWS = {"seq": (np.uint32, ()), "time_us": (np.uint32, ()), "tick": (np.int64, ()),
             "counts": (np.int32, (N_GAUGES,)), "host_time": (np.float64, ()), "time": (np.float64, ())}
#: The rows of the reference's ring.
NETFT_ROWS = {"rdt_seq": (np.uint32, ()), "ft_seq": (np.uint32, ()), "tick": (np.int64, ()),
              "status": (np.uint32, ()), "wrench": (np.float64, (6,)), "host_time": (np.float64, ()),
              "saturated": (bool, ()), "time": (np.float64, ())}


class Ring:
    """The last ``capacity`` rows of named arrays (first axis = rows), appended in blocks.

    Rows are numbered from 0 in the order appended; :attr:`count` (rows appended so far) is
    the write cursor. Reads take the last ``n`` rows (:meth:`last`) or the rows after a past
    cursor (:meth:`since`); their work is proportional to the rows read, never to the capacity.

    Parameters
    ----------
    capacity : int
        Rows kept (>= 1); older rows are overwritten.
    fields : dict
        ``name -> (dtype, shape of one row)``, e.g. ``{"time": (np.float64, ()),
        "wrench": (np.float64, (6,))}``: field ``name`` is stored as an array of shape
        ``(capacity,) + shape`` of that dtype (values are cast to it on append).
    contiguous : bool
        Keep every row twice (at ``i`` and ``i + capacity``: twice the memory and the
        writes) so that any run of the last ``<= capacity`` rows is one slice and
        ``last(n, copy=False)`` returns views. Without it (default) a read that crosses the
        end of the storage joins two slices.

    Attributes
    ----------
    capacity : int
    fields : dict
        The ``fields`` given.
    count : int
        Rows appended since construction or :meth:`clear` (the write cursor).
    """

    def __init__(self, capacity: int, fields: dict, *, contiguous: bool = False):
        if isinstance(capacity, bool) or not isinstance(capacity, (int, np.integer)) or capacity < 1:
            raise ValueError(f"capacity: expected an integer >= 1 rows, got {capacity!r}")
        if not fields:
            raise ValueError("fields: expected at least one field name -> (dtype, shape)")
        self.capacity = int(capacity)
        self.fields = {k: (np.dtype(dt), tuple(shape)) for k, (dt, shape) in fields.items()}
        # rows at positions < _mirror are also kept at position + capacity
        self._mirror = self.capacity if contiguous else 0
        self.data = {k: np.zeros((self.capacity + self._mirror,) + shape, dtype=dt)
                     for k, (dt, shape) in self.fields.items()}
        self.count = 0

    def __len__(self) -> int:
        """Rows held: ``min(count, capacity)``."""
        return min(self.count, self.capacity)

    def append(self, **arrays) -> None:
        """Append a block of rows: one array per field, all of the same length ``n`` (may be 0).

        A block longer than the capacity keeps its last ``capacity`` rows (the rest count
        as appended and overwritten).

        Raises
        ------
        ValueError
            A field missing or unknown, rows of another shape than the field's, or
            arrays of different lengths (the error names the field).
        """
        if arrays.keys() != self.fields.keys():
            missing = sorted(self.fields.keys() - arrays.keys())
            extra = sorted(arrays.keys() - self.fields.keys())
            raise ValueError(f"append: expected the fields {sorted(self.fields)}"
                             + (f"; missing {missing}" if missing else "") + (f"; unknown {extra}" if extra else ""))
        arrays = {k: np.asarray(v) for k, v in arrays.items()}
        n = None
        for k, v in arrays.items():
            shape = self.fields[k][1]
            if v.shape[1:] != shape or v.ndim != 1 + len(shape):
                raise ValueError(f"{k}: expected rows of shape {shape}, got an array of shape {v.shape}")
            if n is None:
                n = len(v)
            elif len(v) != n:
                raise ValueError(f"{k}: expected {n} rows like the other fields, got {len(v)}")
        if n == 0:
            return
        cap = self.capacity
        if n > cap:
            arrays = {k: v[-cap:] for k, v in arrays.items()}
            self.count += n - cap
            n = cap
        p = self.count % cap
        first = min(n, cap - p)
        # the block lands at [p, p + first) and [0, n - first); positions < _mirror again at + cap
        spans = [(p, 0, first), (0, first, n - first)]
        for k, v in arrays.items():
            d = self.data[k]
            for pos, src, m in spans:
                if m:
                    d[pos : pos + m] = v[src : src + m]
                    mm = min(m, self._mirror - pos)
                    if mm > 0:
                        d[cap + pos : cap + pos + mm] = v[src : src + mm]
        self.count += n

    def _rows(self, start: int, end: int, copy: bool) -> dict:
        """Rows ``start .. end - 1`` (held ones, ``end - start <= capacity``) per field, oldest first."""
        n = end - start
        a = start % self.capacity
        if a + n <= self.capacity + self._mirror:
            return {k: v[a : a + n].copy() if copy else v[a : a + n] for k, v in self.data.items()}
        b = end % self.capacity
        return {k: np.concatenate([v[a : self.capacity], v[:b]]) for k, v in self.data.items()}

    def last(self, n: int | None = None, *, copy: bool = True) -> dict:
        """The last ``n`` rows held (all held if None; fewer if fewer are held), oldest first.

        Returns
        -------
        dict
            ``name -> array (k,) + shape`` with ``k = min(n, len(self))``. With ``copy=False``
            the arrays are views into the ring where the rows are one slice (always for a
            ``contiguous`` ring): valid until the next :meth:`append`.
        """
        held = len(self)
        n = held if n is None else max(0, min(int(n), held))
        return self._rows(self.count - n, self.count, copy)

    def since(self, cursor: int, limit: int | None = None) -> tuple[dict, int, int]:
        """Rows appended after ``cursor`` (a past :attr:`count`): ``(rows, new cursor, lost)``.

        ``rows`` are copies (``name -> array (k,) + shape``, oldest first). ``lost`` counts
        rows overwritten before they were read (the reader fell behind by more than the
        capacity). ``limit`` caps the rows returned (the oldest first); the cursor then stops
        after them.
        """
        end = self.count
        start = max(int(cursor), end - self.capacity)
        lost = start - int(cursor)
        if limit is not None:
            end = min(end, start + int(limit))
        return self._rows(start, max(start, end), True), max(start, end), lost

    def clear(self) -> None:
        """Forget every row: :attr:`count` back to 0 (cursors taken before are void)."""
        self.count = 0


class RingReader:
    """Reading both streams' rings by write cursor (shared by :class:`Acquisition` and its remote twin).

    Subclasses own ``_pito_ring``, ``_ft_ring`` (:class:`Ring` of :data:`PITO_ROWS`,
    :data:`NETFT_ROWS`), ``_lock`` and ``has_reference``.
    """

    def cursors(self) -> tuple[int, int]:
        """The write cursors ``(cube, reference)``: rows appended so far to each ring."""
        with self._lock:
            return self._pito_ring.count, self._ft_ring.count

    def read_since(self, cube_cursor: int, reference_cursor: int, limit: int | None = None):
        """Rows appended after the cursors: ``(cube rows, reference rows or None, new cursors, lost)``.

        Rows are dicts of arrays: cube ``seq, time_us, tick, counts (n, 36), host_time, time``;
        reference ``rdt_seq, ft_seq, tick, status, wrench (m, 6), host_time, saturated, time``
        (``time``: sample time by the pairing rule, s). Work is proportional to the new rows.
        ``lost`` ``(cube, reference)`` counts rows overwritten before they were read.
        """
        with self._lock:
            p, pc, pl = self._pito_ring.since(cube_cursor, limit)
            if self.has_reference:
                f, fc, fl = self._ft_ring.since(reference_cursor, limit)
            else:
                f, fc, fl = None, reference_cursor, 0
        return p, f, (pc, fc), (pl, fl)

    def _window(self, ring: Ring, t0, t1) -> dict:
        """All buffered rows of ``ring`` with ``t0 <= host_time <= t1`` (host s; None: unbounded)."""
        with self._lock:
            d = ring.last()
        t = d["host_time"]
        m = np.ones(t.shape, bool)
        if t0 is not None:
            m &= t >= t0
        if t1 is not None:
            m &= t <= t1
        return {k: v[m] for k, v in d.items()}

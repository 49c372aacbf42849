"""The acquisition's ring buffers and reading them by write cursor or by host time.

:class:`_Ring` is a fixed-capacity ring of named arrays; :class:`RingReader` reads both
streams' rings (the cube's :data:`PITO_ROWS`, the reference's :data:`NETFT_ROWS`) for
:class:`~pito_core.devices.Acquisition`.
"""

from __future__ import annotations

import numpy as np

from ..frames import N_GAUGES

__all__ = ["PITO_ROWS", "NETFT_ROWS", "RingReader"]

#: The rows of the cube's ring: name -> (dtype, shape of one row).
PITO_ROWS = {"seq": (np.uint32, ()), "time_us": (np.uint32, ()), "tick": (np.int64, ()),
             "counts": (np.int32, (N_GAUGES,)), "host_time": (np.float64, ()), "time": (np.float64, ())}
#: The rows of the reference's ring.
NETFT_ROWS = {"rdt_seq": (np.uint32, ()), "ft_seq": (np.uint32, ()), "tick": (np.int64, ()),
              "status": (np.uint32, ()), "wrench": (np.float64, (6,)), "host_time": (np.float64, ()),
              "saturated": (bool, ()), "time": (np.float64, ())}


class _Ring:
    """Fixed-capacity ring buffer of named arrays (first axis = samples)."""

    def __init__(self, capacity: int, fields: dict):
        self.capacity = int(capacity)
        self.data = {k: np.zeros((self.capacity,) + shape, dtype=dt) for k, (dt, shape) in fields.items()}
        self.count = 0  # total samples ever appended

    def append(self, **arrays) -> None:
        n = len(next(iter(arrays.values())))
        if n == 0:
            return
        if n > self.capacity:
            arrays = {k: v[-self.capacity :] for k, v in arrays.items()}
            self.count += n - self.capacity
            n = self.capacity
        start = self.count % self.capacity
        first = min(n, self.capacity - start)
        for k, v in arrays.items():
            self.data[k][start : start + first] = v[:first]
            self.data[k][: n - first] = v[first:]
        self.count += n

    def since(self, cursor: int, limit: int | None = None) -> tuple[dict, int, int]:
        """Rows appended after ``cursor`` (a past :attr:`count`): ``(rows, new cursor, lost)``.

        Reads by the write cursor: the work is proportional to the new rows, never to the
        capacity (a wrap gives two slices). ``lost`` counts rows overwritten before they
        were read (the reader fell behind by more than the capacity). ``limit`` caps the
        rows returned (the oldest first); the cursor then stops after them.
        """
        end = self.count
        start = max(int(cursor), end - self.capacity)
        lost = start - int(cursor)
        if limit is not None:
            end = min(end, start + int(limit))
        n = end - start
        a, b = start % self.capacity, end % self.capacity
        if n == 0:
            return {k: v[:0].copy() for k, v in self.data.items()}, end, lost
        if a < b:
            rows = {k: v[a:b].copy() for k, v in self.data.items()}
        else:
            rows = {k: np.concatenate([v[a:], v[:b]]) for k, v in self.data.items()}
        return rows, end, lost

    def last(self, n: int | None = None) -> dict:
        avail = min(self.count, self.capacity)
        n = avail if n is None else max(0, min(int(n), avail))
        idx = (np.arange(self.count - n, self.count)) % self.capacity
        return {k: v[idx] for k, v in self.data.items()}


class RingReader:
    """Reading both streams' rings by write cursor (shared by :class:`Acquisition` and its remote twin).

    Subclasses own ``_pito_ring``, ``_ft_ring`` (:class:`_Ring` of :data:`PITO_ROWS`,
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

    def _window(self, ring: _Ring, t0, t1) -> dict:
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

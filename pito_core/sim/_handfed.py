"""An acquisition fed by hand: idle devices, and synthetic 1 kHz rows pushed into the rings (SIMULATED).

For what reads a running ``pito_core.devices.Acquisition`` (``AcquisitionReader``, the
pipeline) in tests and benchmarks: no reader thread and no timing, exactly the rows
pushed, in the devices' batch formats (``PitoBatch``, ``NetFTBatch``).
"""

from __future__ import annotations

import numpy as np

from ..devices import Acquisition, NetFTBatch, PitoBatch
from ..frames import N_GAUGES

__all__ = ["IdleDevice", "push_samples"]


class IdleDevice:
    """A device that delivers nothing by itself (rows are pushed by :func:`push_samples`).

    Answers the device protocol ``Acquisition`` uses: ``start``, ``read``, ``stats``, ``close``.
    """

    def start(self):
        return self

    def read(self, timeout=0):
        return None

    def stats(self):
        return {"frames": 0, "dropped": 0, "connected": True, "records": 0, "lost": 0, "saturated": 0}

    def close(self):
        pass


def push_samples(acq: Acquisition, first: int, n: int, *, host0: float = 10.0, counts=None, wrench=None) -> None:
    """Push samples ``first .. first + n − 1`` of a 1 kHz run into both rings of ``acq``.

    Sample ``i``: cube ``seq = i``, ``time_us = 1000·i``, host time ``host0 + i·1 ms + 2 ms``;
    reference ``rdt_seq = i + 1``, ``ft_seq = i``, status 0, host time 1 ms after the cube's,
    not saturated.

    Parameters
    ----------
    acq : Acquisition
        Built on :class:`IdleDevice` s (nothing else feeds it).
    first, n : int
        First sample index and number of samples.
    host0 : float
        Host clock at sample 0, s.
    counts : array-like, shape (n, 36), optional
        Cube counts; default ``i`` in every channel.
    wrench : array-like, shape (n, 6), optional
        Reference wrench ``[fx, fy, fz, tx, ty, tz]``, N and N·m; default ``i`` on every axis.
    """
    idx = np.arange(first, first + n)
    host = host0 + idx * 1e-3 + 0.002
    counts = np.tile(idx[:, None], (1, N_GAUGES)) if counts is None else counts
    wrench = np.tile(idx[:, None], (1, 6)) if wrench is None else wrench
    acq._add_pito(PitoBatch(idx.astype(np.uint32), (idx * 1000).astype(np.uint32),
                            np.asarray(counts).astype(np.int32), host))
    acq._add_netft(NetFTBatch((idx + 1).astype(np.uint32), idx.astype(np.uint32), np.zeros(n, np.uint32),
                              np.asarray(wrench).astype(float), host + 0.001, np.zeros(n, bool)))

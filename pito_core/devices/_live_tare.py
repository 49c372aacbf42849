"""The acquisition's live tare: the mean of the last seconds of both streams as the unloaded offsets."""

from __future__ import annotations

import numpy as np

from ._tare import tare_event

__all__ = ["LiveTare"]


class LiveTare:
    """:meth:`tare` for :class:`~pito_core.devices.Acquisition`.

    Subclasses own ``netft``, ``recorder``, ``now()``, ``_drain()``, ``_window()``, the rings
    ``_pito_ring``, ``_ft_ring`` and the offsets ``counts_offset``, ``reference_bias``, ``tared_at``.
    """

    def tare(self, duration: float = 0.5) -> dict:
        """Take the mean of the last ``duration`` s of both streams as the unloaded offsets.

        Sets :attr:`counts_offset` ``(36,)`` (counts) and :attr:`reference_bias` ``(6,)``
        (N, N·m), records a ``tare`` event in the recorder if any (the event of
        ``pito_core.pipeline.Pipeline.tare``: ``from_tick`` is the next cube tick, µs), and
        returns them.

        Raises
        ------
        ValueError
            If a stream has no sample in that window.
        """
        if not duration > 0:
            raise ValueError(f"duration: expected > 0 s, got {duration!r}")
        self._drain()
        now = self.now()
        p = self._window(self._pito_ring, now - duration, None)
        if p["counts"].shape[0] == 0:
            raise ValueError(f"duration: no cube sample in the last {duration} s")
        wrench = np.zeros((0, 6))
        if self.netft is not None:
            f = self._window(self._ft_ring, now - duration, None)
            if f["wrench"].shape[0] == 0:
                raise ValueError(f"duration: no reference sample in the last {duration} s")
            wrench = f["wrench"]
        # the one tare event (``Pipeline.tare``'s): replay applies it from the next cube sample
        out = tare_event(p["counts"], wrench, from_tick=int(p["tick"][-1]) + 1, duration=duration,
                         previous_bias=self.reference_bias, host_time=now)
        self.counts_offset = np.asarray(out["counts_offset"])
        self.reference_bias, self.tared_at = np.asarray(out["reference_bias"]), now
        if self.recorder is not None:
            self.recorder.append_event(out)
        return out

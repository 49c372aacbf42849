"""Calibration sessions from an acquisition's buffered samples, paired by the one pairing rule."""

from __future__ import annotations

import numpy as np

from ..frames import check_face
from ..io import session_from_arrays
from ._clock import PAIRING_RULE, pair_reference

__all__ = ["SessionBuilder"]


class SessionBuilder:
    """:meth:`to_session` for :class:`~pito_core.devices.Acquisition`.

    Subclasses own ``netft``, ``meta``, ``reference_rate_hz``, ``reference_bias``,
    ``counts_offset``, ``_drain()``, ``_window()`` and the rings ``_pito_ring``, ``_ft_ring``.
    """

    def to_session(self, t0=None, t1=None, loaded=None, *, flange, connected_face, T_core_ati,
                   core=None, meta: dict | None = None, reference_delay: float = 0.0):
        """Build a :class:`~pito_core.io.CalibrationSession` from the buffered samples.

        Parameters
        ----------
        t0, t1 : float, optional
            Host-time window (s, :meth:`now`); default everything buffered.
        loaded : None, int, array-like or callable, optional
            Which faces are loaded: None (all unloaded), a face number 1..6 (that face,
            for every sample), a ``(6,)`` bool mask for every sample, an ``(N, 6)`` bool
            array for the N cube samples in the window, or ``f(time (N,)) -> (N, 6)``.
        flange, connected_face, T_core_ati, core
            As :class:`CalibrationSession`.
        meta : dict, optional
            Added to the session's ``meta`` (with the clock fits, tare and device stats).
        reference_delay : float, optional
            Extra transport latency of the reference relative to the cube, s (not
            observable from the data); default 0.

        Returns
        -------
        CalibrationSession
            ``counts`` raw (the calibration removes the unloaded offset itself),
            ``reference`` paired to the cube samples by the one pairing rule
            (:mod:`pito_core.devices._clock`) and minus :attr:`reference_bias`, ``time``
            the cube's sample times (s, host clock).

        Raises
        ------
        ValueError
            No reference connected, no samples in the window, or a bad ``loaded``.
        """
        if self.netft is None:
            raise ValueError("netft: a reference sensor is needed to build a session")
        p, f, sel, t_ref = self._session_rows(t0, t1, reference_delay)
        # a sample paired with a saturated reference record, or with a cube gauge at its
        # ADC limit, never enters a calibration
        t = p["time"][sel]
        sat_ref = pair_reference(t, t_ref, np.repeat(f["saturated"].astype(float)[:, None], 6, axis=1))[:, 0] > 0
        reference = pair_reference(t, t_ref, f["wrench"]) - self.reference_bias
        loaded_arr = self._loaded(loaded, t)
        info = dict(self.meta)
        info.update(meta or {})
        info["acquisition"] = self._acquisition_info(reference_delay, int(f["saturated"].sum()))
        try:  # the one session builder and saturation rule (the wizard's too)
            session = session_from_arrays(p["counts"][sel], reference, loaded_arr, t, T_core_ati=T_core_ati,
                                          flange=flange, connected_face=connected_face, core=core, meta=info,
                                          reference_saturated=sat_ref)
        except ValueError as exc:
            raise ValueError(f"t0, t1: {exc} in the window") from None
        info["acquisition"]["excluded_saturated_samples"] = session.meta["excluded_saturated_samples"]
        session.meta["acquisition"] = info["acquisition"]
        return session

    def _session_rows(self, t0, t1, reference_delay: float):
        """Both streams' rows around ``[t0, t1]`` (host s): ``(cube, reference, cube mask, reference times)``.

        The mask keeps the cube samples inside ``[t0, t1]`` and inside the reference's time span
        (no extrapolation); reference times are minus ``reference_delay`` (s).
        """
        self._drain()
        margin = 0.5
        p = self._window(self._pito_ring, None if t0 is None else t0 - margin, None if t1 is None else t1 + margin)
        f = self._window(self._ft_ring, None if t0 is None else t0 - margin, None if t1 is None else t1 + margin)
        if p["tick"].size < 2 or f["tick"].size < 2:
            raise ValueError("t0, t1: fewer than 2 samples of a stream in the window")
        t_cube = p["time"]
        t_ref = f["time"] - reference_delay
        sel = np.ones(t_cube.shape, bool)
        if t0 is not None:
            sel &= p["host_time"] >= t0
        if t1 is not None:
            sel &= p["host_time"] <= t1
        sel &= (t_cube >= t_ref[0]) & (t_cube <= t_ref[-1])  # no extrapolation
        if not sel.any():
            raise ValueError("t0, t1: no cube sample inside the reference's time span")
        return p, f, sel, t_ref

    def _acquisition_info(self, reference_delay: float, saturated_reference_samples: int) -> dict:
        """The session's ``meta["acquisition"]``: pairing rule, reference rate and delay, tare."""
        return {
            "pairing": PAIRING_RULE,
            "reference_rate_hz": self.reference_rate_hz,
            "reference_delay": reference_delay,
            "reference_bias": self.reference_bias.tolist(),
            "counts_offset": self.counts_offset.tolist(),
            "saturated_reference_samples": saturated_reference_samples,
        }

    @staticmethod
    def _loaded(loaded, t: np.ndarray) -> np.ndarray:
        n = t.size
        if loaded is None:
            return np.zeros((n, 6), bool)
        if callable(loaded):
            out = np.asarray(loaded(t))
        elif np.isscalar(loaded) and not isinstance(loaded, (bool, np.bool_)):
            face = check_face(loaded, "loaded")
            out = np.zeros((n, 6), bool)
            out[:, face - 1] = True
        else:
            out = np.asarray(loaded)
            if out.shape == (6,):
                out = np.broadcast_to(out, (n, 6))
        if out.shape != (n, 6):
            raise ValueError(f"loaded: expected None, a face 1..6, a (6,) mask or shape ({n}, 6), got {out.shape}")
        return out.astype(bool)

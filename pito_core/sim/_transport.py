"""Simulated devices on real transports: the cube on a pseudo-terminal, the Net F/T on loopback UDP.

The physics comes from a *source* (``pito_core.sim`` provides real ones); these classes
only move its numbers through the same bytes as the hardware, so :class:`PitoSerial` and
:class:`NetFT` run unchanged, end to end. Fault injection (dropped, corrupted, truncated
frames, line noise; lost UDP packets, saturation status) is logged exactly so tests can
check every counter.
"""

from __future__ import annotations

import contextlib
import time

from ._transport_netft import SimulatedNetFT
from ._transport_pito import SimulatedPitoPort
from ._transport_source import Source, TestSignalSource, default_simulated_source

__all__ = [
    "Source",
    "TestSignalSource",
    "SimulatedPitoPort",
    "SimulatedNetFT",
    "open_simulated_devices",
    "default_simulated_source",
]


@contextlib.contextmanager
def open_simulated_devices(source=None, rate_hz: float = 1000.0, netft_rate_hz: float = 1000.0, *,
                           speed: float = 1.0, pito_options: dict | None = None,
                           netft_options: dict | None = None, seed: int = 0):
    """Start a simulated cube (pty) and a simulated Net F/T (loopback) on one source.

    Both share one simulated clock (``epoch``), so the cube and the reference see the same
    load at the same time. Yields ``(pito_sim, netft_sim)``: open the real drivers on them with
    ``PitoSerial(pito_sim.port)`` and
    ``NetFT(netft_sim.host, netft_sim.port, http_port=netft_sim.http_port)``.
    ``source=None`` uses :func:`default_simulated_source`.
    """
    if source is None:
        source, _ = default_simulated_source(seed)
    epoch = time.monotonic()  # one simulated world: both devices see the same load at the same time
    pito_sim = SimulatedPitoPort(source, rate_hz, speed=speed, seed=seed, epoch=epoch, **(pito_options or {}))
    try:
        netft_sim = SimulatedNetFT(source, netft_rate_hz, speed=speed, seed=seed, epoch=epoch,
                                   **(netft_options or {}))
    except Exception:
        pito_sim.close()
        raise
    try:
        yield pito_sim, netft_sim
    finally:
        netft_sim.close()
        pito_sim.close()

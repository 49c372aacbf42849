"""Open the cube and the reference from simple addresses, including ``"sim"``."""

from __future__ import annotations

import contextlib
import time

from ._netft import RDT_PORT, NetFT
from ._serial import DEFAULT_BAUDRATE, PitoSerial
from ._sim_transport import SimulatedNetFT, SimulatedPitoPort, default_simulated_source

__all__ = ["open_devices", "SIM"]

#: The address that selects a simulated device (``--pito sim``, ``--ati sim``).
SIM = "sim"


@contextlib.contextmanager
def open_devices(pito: str, ati: str | None = None, *, baudrate: int = DEFAULT_BAUDRATE, ati_port: int = RDT_PORT,
                 http_port: int = 80, counts_per_force=None, counts_per_torque=None, buffered: bool = False,
                 sim_speed: float = 1.0, sim_rate_hz: float = 1000.0, seed: int = 0, sim_options: dict | None = None):
    """Open the cube (serial port or ``"sim"``) and the reference (host, ``"sim"`` or None).

    ``"sim"`` starts the simulated transport on :func:`default_simulated_source` (the
    ``pito_core.sim`` live source when available, else the labelled test signal); the real
    drivers then run on it unchanged. Yields ``(PitoSerial, NetFT or None, info)``, both
    started; ``info`` has ``simulated`` (bool), ``source`` (label or None), ``pito`` and ``ati``
    (what was opened). Everything is closed on exit.
    """
    sim_options = dict(sim_options or {})
    with contextlib.ExitStack() as stack:
        source = label = None
        if SIM in (pito, ati):
            source, label = default_simulated_source(seed)
        info = {"simulated": source is not None, "source": label, "pito": pito, "ati": ati}
        pito_sim = None
        epoch = time.monotonic()  # one simulated world for both devices
        if pito == SIM:
            pito_sim = stack.enter_context(SimulatedPitoPort(source, sim_rate_hz, speed=sim_speed, seed=seed,
                                                             epoch=epoch, start=False, **sim_options.get("pito", {})))
            port = pito_sim.port
        else:
            port = pito
        if ati == SIM:
            ati_sim = stack.enter_context(SimulatedNetFT(source, sim_rate_hz, speed=sim_speed, seed=seed,
                                                         epoch=epoch, **sim_options.get("netft", {})))
            netft = NetFT(ati_sim.host, ati_sim.port, counts_per_force, counts_per_torque,
                          http_port=ati_sim.http_port, buffered=buffered)
        elif ati:
            netft = NetFT(ati, ati_port, counts_per_force, counts_per_torque, http_port=http_port, buffered=buffered)
        else:
            netft = None
        cube = PitoSerial(port, baudrate)
        cube.start()
        stack.callback(cube.close)
        if pito_sim is not None:
            pito_sim.start()  # after the port is open: pyserial flushes input on open
        if netft is not None:
            netft.start()
            stack.callback(netft.close)
        yield cube, netft, info

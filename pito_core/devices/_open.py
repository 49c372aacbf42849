"""Open the cube and the reference from simple addresses (a serial port; ``HOST`` or ``HOST:PORT``)."""

from __future__ import annotations

import contextlib

from ._netft import RDT_PORT, NetFT
from ._serial import DEFAULT_BAUDRATE, PitoSerial

__all__ = ["open_devices", "parse_ati_address", "SIM"]

#: The address that asks a command to start the simulated devices (``--pito sim``, ``--ati sim``);
#: the command starts them (``pito_core.sim.SimulatedDevices``) and passes their real addresses here.
SIM = "sim"


def parse_ati_address(ati: str, ati_port: int = RDT_PORT, http_port: int = 80) -> tuple[str, int, int]:
    """``(host, rdt_port, http_port)`` from ``"HOST"`` or ``"HOST:PORT"``.

    ``HOST:PORT`` gives one port number for both the RDT stream (UDP) and the configuration
    page (TCP), as the simulated box of ``pito sim-devices`` serves them; a bare ``HOST``
    keeps ``ati_port`` and ``http_port``.
    """
    if not isinstance(ati, str) or not ati:
        raise ValueError(f"ati: expected a host name or HOST:PORT, got {ati!r}")
    if ati.count(":") == 1:
        host, p = ati.split(":")
        try:
            port = int(p)
        except ValueError:
            raise ValueError(f"ati: expected HOST:PORT with a port number, got {ati!r}") from None
        if not 0 < port < 65536 or not host:
            raise ValueError(f"ati: expected HOST:PORT with a port in 1..65535, got {ati!r}")
        return host, port, port
    return ati, int(ati_port), int(http_port)


@contextlib.contextmanager
def open_devices(pito: str, ati: str | None = None, *, baudrate: int = DEFAULT_BAUDRATE, ati_port: int = RDT_PORT,
                 http_port: int = 80, counts_per_force=None, counts_per_torque=None, buffered: bool = False):
    """Open the cube (serial port) and the reference (``HOST``, ``HOST:PORT`` or None), both started.

    Yields ``(PitoSerial, NetFT or None)``; both are closed on exit. Simulated devices are
    opened the same way, at the addresses ``pito_core.sim.SimulatedDevices`` (or ``pito
    sim-devices``) announces.
    """
    if pito == SIM or ati == SIM:
        raise ValueError("pito, ati: 'sim' is resolved by the command (start pito_core.sim.SimulatedDevices and "
                         "pass its addresses)")
    with contextlib.ExitStack() as stack:
        netft = None
        if ati:
            host, rdt_port, page_port = parse_ati_address(ati, ati_port, http_port)
            netft = NetFT(host, rdt_port, counts_per_force, counts_per_torque, http_port=page_port, buffered=buffered)
        cube = PitoSerial(pito, baudrate)
        cube.start()
        stack.callback(cube.close)
        if netft is not None:
            netft.start()
            stack.callback(netft.close)
        yield cube, netft

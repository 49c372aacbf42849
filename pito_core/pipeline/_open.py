"""Open a running acquisition on device addresses — real hardware and the simulated devices alike."""

from __future__ import annotations

from ..devices import Acquisition, NetFT, PitoSerial, parse_ati_address
from ._readers import AcquisitionReader

__all__ = ["open_acquisition", "open_reader"]


def open_acquisition(pito: str, ati: str | None = None, *, buffered: bool = False, buffer_seconds: float = 60.0,
                     reference_rate_hz: float = 1000.0, recorder=None, meta: dict | None = None) -> Acquisition:
    """The cube on serial port ``pito`` and the Net F/T at ``ati`` (``HOST``, ``HOST:PORT`` or None), collecting.

    The simulated devices (``pito_core.sim.SimulatedDevices``, ``pito sim-devices``) are
    opened exactly the same way, at the addresses they announce. Close with ``.close()``.
    """
    cube = PitoSerial(pito)
    netft = None
    if ati:
        host, port, http_port = parse_ati_address(ati)
        netft = NetFT(host, port, http_port=http_port, buffered=buffered)
    acq = Acquisition(cube, netft, buffer_seconds=buffer_seconds, reference_rate_hz=reference_rate_hz,
                      recorder=recorder, meta=meta)
    try:
        return acq.start()
    except BaseException:
        acq.close()
        raise


def open_reader(pito: str, ati: str | None = None, *, simulated: bool = False, **options) -> AcquisitionReader:
    """:func:`open_acquisition` wrapped in an :class:`AcquisitionReader` that owns it (closing it closes the devices)."""
    acq = open_acquisition(pito, ati, meta={"simulated": bool(simulated)}, **options)
    return AcquisitionReader(acq, simulated=simulated, owns=True)

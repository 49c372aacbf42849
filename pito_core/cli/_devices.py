"""``pito devices``: list serial ports (and the simulated devices)."""

from __future__ import annotations

import argparse
import json

from ..devices import SIM, list_serial_ports

HELP = """\
List the serial ports the PITO cube may be on (pyserial's serial.tools.list_ports).

Give one of the listed devices to `pito record --pito PORT`. The address `sim` is always
available: it starts the simulated devices in their own process — the cube on a
pseudo-terminal streaming real frames and, with `--ati sim`, an ATI Net F/T on loopback
UDP (`pito sim-devices` runs them standalone and prints their addresses).

The Net F/T is not listed: it is addressed by IP (`--ati HOST`, RDT on UDP port 49152,
configuration page on HTTP port 80; the factory default address is 192.168.1.1).
"""


def register(sub) -> None:
    p = sub.add_parser("devices", help="list serial ports for the cube", description=HELP,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--json", action="store_true", help="print a JSON list instead of a table")
    p.set_defaults(func=run)


def run(args) -> int:
    ports = list_serial_ports()
    if args.json:
        print(json.dumps(ports + [{"device": SIM, "description": "simulated cube and Net F/T", "hwid": ""}]))
        return 0
    if not ports:
        print("no serial ports found")
    else:
        width = max(len(p["device"]) for p in ports)
        for p in ports:
            print(f"{p['device']:<{width}}  {p['description']}  [{p['hwid']}]")
    print(f"{SIM}  (simulated cube and Net F/T: pito record --pito sim --ati sim)")
    return 0

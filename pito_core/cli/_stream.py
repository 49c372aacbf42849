"""``pito stream --pito PORT --ati HOST --calibration F``: publish live LSL streams without recording."""

from __future__ import annotations

import argparse
import contextlib
import os
import signal
import sys
import time

from ..calibration import load_calibration
from ..devices import DEFAULT_BAUDRATE, Acquisition, DeviceError, open_devices
from ..interop import (
    CONTACT_CHANNEL_COUNT,
    WRENCH_CHANNELS,
    LslPublisher,
    calibration_record,
    listening_sockets,
    machine_only_config,
)
from ..pipeline import AcquisitionReader, Pipeline
from ..sim import SimulatorError
from ._record import _addresses

HELP = f"""\
Publish the cube's face wrenches and contacts as Lab Streaming Layer streams, live,
without recording (`pito record ... --lsl` publishes while it records):

  pito-wrenches  type Force, {6 * len(WRENCH_CHANNELS)} channels (face i: fx fy fz in N, tx ty tz in N*m, own frame)
  pito-contacts  type Contact, {CONTACT_CHANNEL_COUNT} channels (face i: point xyz m, normal xyz, force xyz N in the
                 core frame, torsion N*m, valid 0/1, single 0/1: one fingertip can produce the wrench)

at the cube's rate, time-stamped on the LSL clock at acquisition (the cube's device clock,
strictly increasing, placed on the LSL clock at the first sample), with channel metadata and the calibration's identity (method, date, sha256
hash) and the patch assembly in the stream description. docs/interop.md gives the layout.

LSL finds peers by multicast on the local network unless configured: set LSLAPICFG to a
machine-only config (`pito stream --write-machine-config FILE` writes one) so discovery stays
on 127.0.0.1. liblsl still binds each outlet's TCP and UDP data ports (16572, 16573, ...)
to every interface (it has no setting for their address): the first line printed says
exactly what this process listens on; a firewall (or a private network namespace) keeps
other computers out.

Addresses as `pito record`: --pito PORT or `sim`, --ati HOST[:PORT] or `sim` (or omitted).
"""


def register(sub) -> None:
    p = sub.add_parser("stream", help="publish live LSL streams (wrenches, contacts)", description=HELP,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--pito", metavar="PORT", help="cube serial port, or 'sim'")
    p.add_argument("--ati", metavar="HOST", help="Net F/T address (HOST or HOST:PORT), or 'sim' (default: none)")
    p.add_argument("--calibration", metavar="FILE", help="calibration file (required: the streams carry wrenches)")
    p.add_argument("--object", metavar="NAME", default="cube",
                   help="patch assembly for the contacts (library name or .json; default cube)")
    p.add_argument("--duration", type=float, metavar="S", help="stop after S seconds (default: until Ctrl-C)")
    p.add_argument("--baudrate", type=int, default=DEFAULT_BAUDRATE, help=f"cube baud rate (default {DEFAULT_BAUDRATE})")
    p.add_argument("--ati-rate", type=float, default=1000.0, metavar="HZ", help="Net F/T RDT rate, Hz (default 1000)")
    p.add_argument("--rate", type=float, default=1000.0, metavar="HZ", help="the cube's nominal rate for LSL, Hz (default 1000)")
    p.add_argument("--source-id", default="pito", help="LSL source id prefix (default 'pito')")
    p.add_argument("--sim-speed", type=float, default=1.0, help="simulated devices: speed (default 1)")
    p.add_argument("--seed", type=int, default=0, help="simulated devices: seed (default 0)")
    p.add_argument("--write-machine-config", metavar="FILE",
                   help="write a machine-only lsl_api.cfg to FILE and exit (use with LSLAPICFG=FILE)")
    p.set_defaults(func=run)


def run(args) -> int:
    if args.write_machine_config:
        print(f"wrote {machine_only_config(args.write_machine_config)}  (export LSLAPICFG={args.write_machine_config})")
        return 0
    if not args.pito:
        raise ValueError("--pito: required (a serial port or 'sim')")
    if not args.calibration:
        raise ValueError("--calibration: required (the streams carry wrenches)")
    if args.duration is not None and not args.duration > 0:
        raise ValueError(f"--duration: expected > 0 s, got {args.duration}")
    cal = load_calibration(args.calibration)
    args.simulated = False
    stop = {"flag": False}
    old = signal.signal(signal.SIGTERM, lambda *a: stop.update(flag=True))
    try:
        with contextlib.ExitStack() as stack:
            pito, ati, info = _addresses(args, stack)
            cube, netft = stack.enter_context(open_devices(pito, ati, baudrate=args.baudrate))
            pipe = Pipeline(cal, args.object, has_reference=netft is not None, rate_hz=args.rate)
            pub = LslPublisher(pipe, rate_hz=args.rate, source_id=args.source_id, simulated=info["simulated"],
                               calibration_record=calibration_record(cal, args.calibration))
            acq = Acquisition(cube, netft, buffer_seconds=10.0, reference_rate_hz=args.ati_rate,
                              meta={"simulated": info["simulated"]})
            reader = AcquisitionReader(acq, simulated=info["simulated"], history=0.0)
            where = listening_sockets()
            print(f"publishing LSL streams {pub.names[0]} (Force, {6 * len(WRENCH_CHANNELS)} ch) and {pub.names[1]} "
                  f"(Contact, {CONTACT_CHANNEL_COUNT} ch)"
                  f"{' (simulated devices)' if info['simulated'] else ''}; listening on "
                  f"{', '.join(where) if where else 'ports 16571-16604 (liblsl defaults; address not readable here)'}"
                  f" (LSLAPICFG={os.environ.get('LSLAPICFG') or 'not set: multicast discovery on the network'}); "
                  "Ctrl-C stops", file=sys.stderr, flush=True)
            t0 = time.monotonic()
            try:
                acq.start()
                while not stop["flag"]:
                    if args.duration is not None and time.monotonic() - t0 >= args.duration:
                        break
                    pub(pipe.feed(reader.read()))
                    time.sleep(0.02)
            except KeyboardInterrupt:
                pass
            finally:
                acq.stop()
                pub.close()
            print(f"published {pub.pushed} samples on each stream", file=sys.stderr)
    except (DeviceError, SimulatorError) as exc:
        print(f"pito: error: {exc}", file=sys.stderr)
        return 1
    finally:
        signal.signal(signal.SIGTERM, old)
    return 0

"""``pito sim-devices``: the simulated cube and Net F/T, standalone, at addresses to record from."""

from __future__ import annotations

import argparse
import json
import sys
import threading

from ..sim import run_devices

HELP = """\
Run the SIMULATED devices in the foreground, exactly as hardware is reached: the virtual
cube writes real 156-byte frames (1 kHz) into a pseudo-terminal, the virtual ATI Net F/T
answers RDT requests on loopback UDP and serves its configuration page on TCP (one port
number of 127.0.0.1 for both). It prints the addresses to pass on, e.g.

    pito record --pito /tmp/pito-sim-XXXX/pito --ati 127.0.0.1:PORT --simulated -o run.pitorec
    pito-app --pito /tmp/pito-sim-XXXX/pito --ati 127.0.0.1:PORT

and a control address (TCP, JSON lines) that steers the simulated world: the scenario
(grasp, calibration), the mount, the face the simulated operator loads, the object
(docs/devices.md, "Simulated devices"). Stop with Ctrl-C or --duration. Everything these
devices send is simulated (pito_core.sim), not measured.
"""


def register(sub) -> None:
    p = sub.add_parser("sim-devices", help="run the simulated cube and Net F/T (pty + loopback UDP)",
                       description=HELP, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--seed", type=int, default=0, help="seed of the simulated world (default 0)")
    p.add_argument("--speed", type=float, default=1.0, help="simulated seconds per wall second (default 1)")
    p.add_argument("--period", type=float, default=1.5, metavar="S",
                   help="seconds per move-and-hold of the simulated operator (default 1.5)")
    p.add_argument("--scenario", choices=("grasp", "calibration"), default="grasp",
                   help="grasp: a hand grasps and moves the object; calibration: an operator loads faces (default grasp)")
    p.add_argument("--assembly", metavar="NAME", help="patch assembly the grasp's fingers touch (default flat patches)")
    p.add_argument("--duration", type=float, metavar="S", help="stop after S seconds (default: until Ctrl-C)")
    p.add_argument("--json", action="store_true", help="print the addresses as one JSON line")
    p.set_defaults(func=run)


def run(args) -> int:
    if not args.speed > 0 or args.speed == float("inf"):
        raise ValueError(f"--speed: expected a finite speed > 0, got {args.speed}")
    if args.duration is not None and not args.duration > 0:
        raise ValueError(f"--duration: expected > 0 s, got {args.duration}")
    stop = threading.Event()
    if args.duration is not None:
        timer = threading.Timer(args.duration, stop.set)
        timer.daemon = True
        timer.start()

    def announce(info):
        if args.json:
            print(json.dumps(info), flush=True)
            return
        print(f"SIMULATED devices running (process {info['pid']}; Ctrl-C stops them):\n"
              f"  cube (serial port):   {info['pito']}\n"
              f"  Net F/T (RDT + page): {info['ati']}\n"
              f"  control (JSON lines): {info['control']}\n"
              f"record:  pito record --pito {info['pito']} --ati {info['ati']} --simulated -o run.pitorec\n"
              f"app:     pito-app --pito {info['pito']} --ati {info['ati']}", flush=True)

    run_devices(seed=args.seed, speed=args.speed, period=args.period, scenario=args.scenario,
                assembly=args.assembly, announce=announce, stop=stop)
    print("simulated devices stopped", file=sys.stderr)
    return 0

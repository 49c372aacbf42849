"""``pito record --pito PORT --ati HOST -o FILE``: record both streams, crash-safely."""

from __future__ import annotations

import argparse
import signal
import sys
import time

HELP = """\
Record the cube and the reference sensor to a pito recording file.

The file (format pito-recording v1, docs/devices.md) is written in checked chunks at
least every --flush-interval seconds, so a crash or a kill loses at most that much;
`pito replay --recover` reads what was written. Units: cube counts (raw), reference in
N and N·m as the Net F/T reports them (its own bias, if set, included), times in s.
Stop with Ctrl-C (the file is then closed cleanly) or give --duration.

Addresses: --pito is a serial port (see `pito devices`) or `sim`; --ati is the Net F/T's
IP address or host name, `sim`, or omitted (cube only). The simulated devices use
pito_core.sim's live source when available, else a labelled simulated test signal; the
recording's metadata says "simulated": true.
"""


def register(sub) -> None:
    from ..devices import DEFAULT_BAUDRATE, RDT_PORT

    p = sub.add_parser("record", help="record the cube and the reference to a file", description=HELP,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--pito", required=True, metavar="PORT", help="cube serial port, or 'sim'")
    p.add_argument("--ati", metavar="HOST", help="Net F/T address, or 'sim' (default: no reference)")
    p.add_argument("-o", "--output", required=True, metavar="FILE", help="recording file to write (overwritten)")
    p.add_argument("--duration", type=float, metavar="S", help="stop after S seconds (default: until Ctrl-C)")
    p.add_argument("--baudrate", type=int, default=DEFAULT_BAUDRATE,
                   help=f"cube baud rate (default {DEFAULT_BAUDRATE}; 1 kHz frames need 1.56 Mbit/s)")
    p.add_argument("--ati-port", type=int, default=RDT_PORT, help=f"Net F/T RDT UDP port (default {RDT_PORT})")
    p.add_argument("--ati-http-port", type=int, default=80, help="Net F/T configuration page port (default 80)")
    p.add_argument("--counts-per-force", type=float, metavar="C",
                   help="Net F/T counts per N (default: read from the box, with --counts-per-torque)")
    p.add_argument("--counts-per-torque", type=float, metavar="C",
                   help="Net F/T counts per N·m (default: read from the box)")
    p.add_argument("--buffered", action="store_true", help="Net F/T buffered streaming (several records per packet)")
    p.add_argument("--tare", type=float, default=0.0, metavar="S",
                   help="after S seconds, record a tare event (means of the last 0.5 s); default 0 = none")
    p.add_argument("--flush-interval", type=float, default=0.5, metavar="S",
                   help="maximum seconds between writes to disk, at most 1 (default 0.5)")
    p.add_argument("--sim-speed", type=float, default=1.0,
                   help="simulated devices: simulated seconds per wall second (default 1)")
    p.add_argument("--progress", type=float, default=1.0, metavar="S",
                   help="seconds between progress lines on stderr, 0 for none (default 1)")
    p.set_defaults(func=run)


def _line(elapsed, stats) -> str:
    p = stats["pito"]
    s = f"{elapsed:7.1f} s  cube {p['frames']} frames, dropped {p['dropped']}, crc errors {p['crc_errors']}"
    if not p["connected"]:
        s += " (disconnected)"
    if stats["netft"] is not None:
        f = stats["netft"]
        s += f" | ati {f['records']} records, lost {f['lost']}, saturated {f['saturated']}"
    return s


def run(args) -> int:
    from ..devices import DeviceError

    try:
        return _record(args)
    except DeviceError as exc:  # a device that cannot be opened: one clear line
        print(f"pito: error: {exc}", file=sys.stderr)
        return 1


def _record(args) -> int:
    from ..devices import Acquisition, open_devices
    from ..io import RecordingWriter

    if args.duration is not None and not args.duration > 0:
        raise ValueError(f"--duration: expected > 0 s, got {args.duration}")
    stop = {"flag": False}

    def on_term(signum, frame):  # SIGTERM: close the file cleanly as Ctrl-C does
        stop["flag"] = True

    old = signal.signal(signal.SIGTERM, on_term)
    try:
        with open_devices(args.pito, args.ati, baudrate=args.baudrate, ati_port=args.ati_port,
                          http_port=args.ati_http_port, counts_per_force=args.counts_per_force,
                          counts_per_torque=args.counts_per_torque, buffered=args.buffered,
                          sim_speed=args.sim_speed) as (cube, netft, info):
            meta = {"simulated": info["simulated"], "source": info["source"], "pito_port": args.pito,
                    "ati_host": args.ati, "units": {"counts": "counts", "wrench": "N, N·m", "time": "s"}}
            if netft is not None:
                meta["ati_scaling"] = {"counts_per_force": netft.config.counts_per_force,
                                       "counts_per_torque": netft.config.counts_per_torque,
                                       "force_unit": netft.config.force_unit, "torque_unit": netft.config.torque_unit}
            writer = RecordingWriter(args.output, meta, flush_interval=args.flush_interval)
            acq = Acquisition(cube, netft, recorder=writer, buffer_seconds=10.0)
            t0 = time.monotonic()
            next_progress = t0 + args.progress
            tared = args.tare <= 0
            try:
                acq.start()
                while not stop["flag"]:
                    now = time.monotonic()
                    if args.duration is not None and now - t0 >= args.duration:
                        break
                    if not tared and now - t0 >= args.tare:
                        acq.tare()
                        tared = True
                    if args.progress > 0 and now >= next_progress:
                        print(_line(now - t0, acq.stats()), file=sys.stderr, flush=True)
                        next_progress += args.progress
                    time.sleep(0.02)
            except KeyboardInterrupt:
                pass
            finally:
                acq.stop()
                writer.close()
            stats = acq.stats()
            print(_line(time.monotonic() - t0, stats), file=sys.stderr)
            rows = writer.rows_written
            label = " (simulated)" if info["simulated"] else ""
            print(f"wrote {args.output}: {rows['pito']} cube samples, {rows['netft']} reference samples{label}")
    finally:
        signal.signal(signal.SIGTERM, old)
    return 0

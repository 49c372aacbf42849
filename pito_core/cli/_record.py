"""``pito record --pito PORT --ati HOST -o FILE``: record both streams, crash-safely, through the one pipeline.

Structure (for extensions such as ``--calibration`` and ``--lsl``): :func:`register` adds
the options; :func:`_pipeline_for` builds the :class:`~pito_core.pipeline.Pipeline` every read
goes through; :func:`_sinks_for` returns the callables that receive each
:class:`~pito_core.pipeline.LiveBundle` (live publishers); :func:`_recording_meta` what the
file's header says. The recording itself is written beside the pipeline, in the
acquisition's collecting thread.
"""

from __future__ import annotations

import argparse
import contextlib
import signal
import sys
import time

from ..calibration import load_calibration
from ..devices import (
    DEFAULT_BAUDRATE,
    RDT_PORT,
    SIM,
    Acquisition,
    DeviceError,
    StallReporter,
    health_words,
    open_devices,
)
from ..interop import LslPublisher, assembly_record, calibration_record, listening_sockets
from ..io import RecordingWriter
from ..pipeline import AcquisitionReader, Pipeline
from ..sim import SimulatedDevices, SimulatorError

HELP = """\
Record the cube and the reference sensor to a pito recording file.

The file (format pito-recording v1, docs/devices.md) is written in checked chunks at
least every --flush-interval seconds, so a crash or a kill loses at most that much;
`pito replay --recover` reads what was written. Units: cube counts (raw), reference in
N and N·m as the Net F/T reports them (its own bias, if set, included), times in s.
Stop with Ctrl-C (the file is then closed cleanly) or give --duration.

Addresses: --pito is a serial port (see `pito devices`) or `sim`; --ati is the Net F/T's
IP address or host name, HOST:PORT (one port for RDT and the configuration page, as
`pito sim-devices` announces), `sim`, or omitted (cube only). `sim` starts the simulated
devices (pito_core.sim) in their own process, exactly as `pito sim-devices` does, and
records from them; the recording's metadata says "simulated": true.

Every read goes through the same pipeline as the desktop app (pairing of the reference
with the cube by the device clocks, tare); --tare records the tare as an event that
replay applies at the same sample.
"""


def register(sub) -> None:
    p = sub.add_parser("record", help="record the cube and the reference to a file", description=HELP,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--pito", required=True, metavar="PORT", help="cube serial port, or 'sim'")
    p.add_argument("--ati", metavar="HOST", help="Net F/T address (HOST or HOST:PORT), or 'sim' (default: no reference)")
    p.add_argument("-o", "--output", required=True, metavar="FILE", help="recording file to write (overwritten)")
    p.add_argument("--duration", type=float, metavar="S", help="stop after S seconds (default: until Ctrl-C)")
    p.add_argument("--baudrate", type=int, default=DEFAULT_BAUDRATE,
                   help=f"cube baud rate (default {DEFAULT_BAUDRATE}; 1 kHz frames need 1.56 Mbit/s)")
    p.add_argument("--ati-port", type=int, default=RDT_PORT, help=f"Net F/T RDT UDP port (default {RDT_PORT})")
    p.add_argument("--ati-http-port", type=int, default=80, help="Net F/T configuration page port (default 80)")
    p.add_argument("--ati-rate", type=float, default=1000.0, metavar="HZ",
                   help="the Net F/T's configured RDT output rate, Hz: its clock for pairing (default 1000)")
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
    p.add_argument("--seed", type=int, default=0, help="simulated devices: seed (default 0)")
    p.add_argument("--simulated", action="store_true",
                   help="label the recording simulated (devices of `pito sim-devices` given by address)")
    p.add_argument("--calibration", metavar="FILE",
                   help="calibration file: computed live, and embedded in the recording (the file's exact bytes: "
                        "the whole model, under its content hash) so exports compute with it (docs/interop.md)")
    p.add_argument("--object", metavar="NAME", help="patch assembly (library name or .json) for contacts; embedded too")
    p.add_argument("--lsl", action="store_true",
                   help="also publish the LSL streams pito-wrenches and pito-contacts while recording "
                        "(needs --calibration; see `pito stream --help` and docs/interop.md)")
    p.add_argument("--progress", type=float, default=1.0, metavar="S",
                   help="seconds between progress lines on stderr, 0 for none (default 1)")
    p.set_defaults(func=run)


def _line(elapsed, stats, closed: bool = False) -> str:
    """One progress line; ``closed``: the final one, after pito closed the devices itself."""
    p = stats["pito"]
    s = f"{elapsed:7.1f} s  cube {p['frames']} frames, dropped {p['dropped']}, crc errors {p['crc_errors']}"
    if not p["connected"] and not closed:
        s += " (disconnected)"
    if stats["netft"] is not None:
        f = stats["netft"]
        s += f" | ati {f['records']} records, lost {f['lost']}, saturated {f['saturated']}"
        s += f", out of order {f.get('out_of_order', 0)}"
    words = health_words(stats)
    return s + (" | " + "; ".join(words) if words else "")


def run(args) -> int:
    try:
        return _record(args)
    except (DeviceError, SimulatorError) as exc:  # a device that cannot be opened: one clear line
        print(f"pito: error: {exc}", file=sys.stderr)
        return 1


def _addresses(args, stack) -> tuple[str, str | None, dict]:
    """``(cube port, reference address or None, info)``; ``sim`` starts the simulated devices' process."""
    info = {"simulated": bool(args.simulated), "source": "simulated devices (pito sim-devices)" if args.simulated else None}
    pito, ati = args.pito, args.ati
    if SIM in (pito, ati):
        sim = stack.enter_context(SimulatedDevices(seed=args.seed, speed=args.sim_speed))
        info = {"simulated": True, "source": f"{sim.label}: {sim.describe()}"}
        pito = sim.port if pito == SIM else pito
        ati = sim.ati if ati == SIM else ati
    return pito, ati, info


def _pipeline_for(args, has_reference: bool):
    """The pipeline every read goes through (hook: a calibration, an object)."""
    cal = None
    if getattr(args, "calibration", None):
        cal = load_calibration(args.calibration)
    return Pipeline(cal, getattr(args, "object", None), has_reference=has_reference, rate_hz=1000.0)


def _sinks_for(args, meta: dict, pipeline=None) -> list:
    """Callables receiving each :class:`~pito_core.pipeline.LiveBundle` (hook: live publishers)."""
    if not getattr(args, "lsl", False):
        return []
    return [LslPublisher(pipeline, simulated=bool(meta.get("simulated")), calibration_record=meta.get("calibration"),
                         assembly_record=meta.get("assembly"))]


def _recording_meta(args, info: dict, netft, pipeline=None) -> dict:
    meta = {"simulated": info["simulated"], "source": info["source"], "pito_port": args.pito,
            "ati_host": args.ati, "reference_rate_hz": args.ati_rate,
            "units": {"counts": "counts", "wrench": "N, N·m", "time": "s"}}
    if pipeline is not None and (getattr(args, "calibration", None) or getattr(args, "object", None)):  # provenance
        if pipeline.calibration is not None:
            meta["calibration"] = calibration_record(pipeline.calibration, args.calibration)
        meta["assembly"] = assembly_record(pipeline.assembly if pipeline.assembly is not None else "cube")
    if netft is not None:
        meta["ati_scaling"] = {"counts_per_force": netft.config.counts_per_force,
                               "counts_per_torque": netft.config.counts_per_torque,
                               "force_unit": netft.config.force_unit, "torque_unit": netft.config.torque_unit}
    return meta


def _record(args) -> int:
    if args.duration is not None and not args.duration > 0:
        raise ValueError(f"--duration: expected > 0 s, got {args.duration}")
    if not args.ati_rate > 0:
        raise ValueError(f"--ati-rate: expected > 0 Hz, got {args.ati_rate}")
    stop = {"flag": False}

    def on_term(signum, frame):  # SIGTERM: close the file cleanly as Ctrl-C does
        stop["flag"] = True

    old = signal.signal(signal.SIGTERM, on_term)
    try:
        with contextlib.ExitStack() as stack:
            pito, ati, info = _addresses(args, stack)
            cube, netft = stack.enter_context(open_devices(
                pito, ati, baudrate=args.baudrate, ati_port=args.ati_port, http_port=args.ati_http_port,
                counts_per_force=args.counts_per_force, counts_per_torque=args.counts_per_torque,
                buffered=args.buffered))
            if getattr(args, "lsl", False) and not getattr(args, "calibration", None):
                raise ValueError("--lsl: needs --calibration FILE (the streams carry wrenches)")
            pipeline = _pipeline_for(args, netft is not None)
            meta = _recording_meta(args, info, netft, pipeline)
            sinks = _sinks_for(args, meta, pipeline)
            if sinks:  # what liblsl listens on (docs/interop.md, "What listens where")
                where = listening_sockets()
                print(f"publishing LSL streams {', '.join(sinks[0].names)}; listening on "
                      f"{', '.join(where) if where else 'ports 16571-16604 (liblsl defaults)'}", file=sys.stderr, flush=True)
            writer = RecordingWriter(args.output, meta, flush_interval=args.flush_interval)
            acq = Acquisition(cube, netft, recorder=writer, buffer_seconds=10.0, reference_rate_hz=args.ati_rate,
                              meta={"simulated": info["simulated"]})
            reader = AcquisitionReader(acq, simulated=info["simulated"], history=0.0)
            t0 = time.monotonic()
            try:
                acq.start()
                _record_loop(args, acq, reader, pipeline, sinks, writer, stop, t0)
            except KeyboardInterrupt:
                pass
            finally:
                acq.stop()
                for device in (cube, netft):  # no frame after this: every frame received is collected next
                    if device is not None:
                        device.close()
                acq.stop()  # collects what arrived until the devices closed
                writer.close()
            stats = acq.stats()
            print(_line(time.monotonic() - t0, stats, closed=True), file=sys.stderr)
            rows = writer.rows_written
            label = " (simulated)" if info["simulated"] else ""
            print(f"wrote {args.output}: {rows['pito']} cube samples, {rows['netft']} reference samples{label}")
            lost = _lost_at_handoff(stats, rows)
            if lost:
                print(f"pito: error: {lost}", file=sys.stderr)
                return 1
    finally:
        signal.signal(signal.SIGTERM, old)
    return 0


def _lost_at_handoff(stats: dict, rows: dict) -> str:
    """A sentence naming the stream whose frames received by the driver did not all reach the file ('' if none)."""
    lost = []
    got = int(stats["pito"]["frames"])
    if got != rows["pito"]:
        lost.append(f"cube: {got} frames received, {rows['pito']} recorded")
    if stats.get("netft") is not None:
        got = int(stats["netft"]["records"])
        if got != rows["netft"]:
            lost.append(f"reference: {got} records received, {rows['netft']} recorded")
    return "; ".join(lost)


def _record_loop(args, acq, reader, pipeline, sinks, writer, stop: dict, t0: float) -> None:
    """Every 20 ms until ``--duration`` s after ``t0`` (host monotonic) or ``stop["flag"]``: new samples
    through the pipeline to the sinks, the tare once after ``--tare`` s (an event in the file), stall
    and progress lines on stderr."""
    next_progress = t0 + args.progress
    stall_reporter = StallReporter()
    tared = args.tare <= 0
    while not stop["flag"]:
        now = time.monotonic()
        if args.duration is not None and now - t0 >= args.duration:
            break
        bundle = pipeline.feed(reader.read())
        for sink in sinks:
            sink(bundle)
        if not tared and now - t0 >= args.tare:
            try:
                writer.append_event(pipeline.tare())
                tared = True
            except ValueError:  # no sample yet: try at the next read
                pass
        for change in stall_reporter.changes(acq.stats()):  # "stalled" within 200 ms
            print(f"{now - t0:7.1f} s  {change}", file=sys.stderr, flush=True)
        if args.progress > 0 and now >= next_progress:
            print(_line(now - t0, acq.stats()), file=sys.stderr, flush=True)
            next_progress += args.progress
        time.sleep(0.02)

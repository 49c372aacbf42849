"""The simulated devices in their own process, exactly as hardware: a pty and loopback UDP.

:func:`run_devices` runs the virtual cube (156-byte frames into a pseudo-terminal,
:class:`SimulatedPitoPort`) and the virtual Net F/T (RDT on UDP and its configuration page
on TCP, both on one port number of 127.0.0.1, :class:`SimulatedNetFT`) on one
:class:`~pito_core.sim.DemoWorld`, until told to stop. ``pito sim-devices`` runs it in the
foreground; :class:`SimulatedDevices` runs it in a child process that the parent always
stops, also when the parent is killed (no orphans, see below).

Announcement
    On start the devices print one JSON line on stdout:
    ``{"pito": "/tmp/pito-sim-…/pito", "ati": "127.0.0.1:PORT", "control": "127.0.0.1:CPORT",
    "pid": …, "label": "…"}``. Pass ``--pito PITO --ati ATI`` to ``pito record`` or ``pito-app``.

Control channel (``control``: TCP on 127.0.0.1, JSON lines)
    Each request is one JSON object on one line; each answer is one line
    ``{"ok": true, ...}`` or ``{"ok": false, "error": "..."}``. Requests (``cmd``):

    - ``{"cmd": "state"}`` → ``state``: scenario, mount, operator face, assembly, ``sim_time`` (s).
    - ``{"cmd": "set_scenario", "name": "grasp" | "rest" | "two_fingers" | "calibration"}``
    - ``{"cmd": "set_mount", "flange": "frame" | "frame_hole" | "face", "connected_face": 1..6}``
    - ``{"cmd": "set_operator_face", "face": 1..6 | null}`` (null: hands off)
    - ``{"cmd": "set_assembly", "name": "pito_mixed" | … | null}`` (patches the grasp's fingers touch)
    - ``{"cmd": "stats"}`` → ``frames`` (cube frames written), ``netft_requests``.
    - ``{"cmd": "quit"}`` stops the devices.

No orphans
    The child asks the kernel for SIGTERM when its parent dies (``prctl(PR_SET_PDEATHSIG)``
    on Linux, through ctypes; only when started from the parent's main thread, since the
    signal follows the starting *thread*), polls ``os.getppid()`` every 0.2 s, and stops when its stdin
    (a pipe from the parent) reaches end of file: any one of the three ends it, also when
    the parent is SIGKILLed.
"""

from __future__ import annotations

import contextlib
import json
import os
import select
import socket
import subprocess
import sys
import threading
import time
from typing import TYPE_CHECKING

from ..devices import die_with_parent, install_stop_signals
from ._launch import DevicesLaunch

if TYPE_CHECKING:
    from ._world import DemoWorld

__all__ = ["SimulatedDevices", "SimulatorError", "run_devices"]

class SimulatorError(RuntimeError):
    """The simulated devices refused a control request or could not start."""


class _Control:
    """The control server: one thread per client, one JSON line per request and answer."""

    def __init__(self, world: DemoWorld, devices: dict, stop: threading.Event):
        self.world, self.devices, self.stop = world, devices, stop
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.listen(4)
        self.sock.settimeout(0.2)
        self.address = "127.0.0.1:%d" % self.sock.getsockname()[1]
        self._lock = threading.Lock()
        self.thread = threading.Thread(target=self._accept, name="sim-control", daemon=True)
        self.thread.start()

    def _accept(self) -> None:
        while not self.stop.is_set():
            try:
                conn, _ = self.sock.accept()
            except socket.timeout:
                continue
            except OSError:
                return
            threading.Thread(target=self._serve, args=(conn,), name="sim-control-client", daemon=True).start()

    def _serve(self, conn) -> None:
        with conn, conn.makefile("rw", encoding="utf-8", newline="\n") as f:
            for line in f:
                if not line.strip():
                    continue
                try:
                    req = json.loads(line)
                    if not isinstance(req, dict):
                        raise ValueError("request: expected a JSON object")
                    with self._lock:
                        answer = {"ok": True, **self.handle(req)}
                except (ValueError, KeyError, TypeError) as exc:
                    answer = {"ok": False, "error": f"{type(exc).__name__}: {exc}"}
                f.write(json.dumps(answer) + "\n")
                f.flush()
                if req_is_quit(line):
                    return

    def handle(self, req: dict) -> dict:
        w = self.world
        cmd = req.get("cmd")
        if cmd == "state":
            return {"state": w.state()}
        if cmd == "set_scenario":
            w.set_scenario(req["name"])
        elif cmd == "set_mount":
            w.set_mount(req["flange"], int(req["connected_face"]))
        elif cmd == "set_operator_face":
            w.set_operator_face(req.get("face"))
        elif cmd == "set_assembly":
            w.set_assembly(req.get("name"))
        elif cmd == "stats":
            pito, netft = self.devices["pito"], self.devices["netft"]
            return {"frames": pito.frames_written, "netft_requests": len(netft.log["requests"])}
        elif cmd == "quit":
            self.stop.set()
        else:
            raise ValueError(f"cmd: unknown request {cmd!r} (state, set_scenario, set_mount, set_operator_face, "
                             "set_assembly, stats, quit)")
        return {"state": w.state()}

    def close(self) -> None:
        with contextlib.suppress(OSError):
            self.sock.close()


def req_is_quit(line: str) -> bool:
    with contextlib.suppress(ValueError, AttributeError):
        return json.loads(line).get("cmd") == "quit"
    return False


def run_devices(*, seed: int = 0, speed: float = 1.0, period: float = 1.5, scenario: str = "grasp",
                assembly: str | None = None, rate_hz: float = 1000.0, records_per_packet: int = 10,
                announce=None, stop: threading.Event | None = None, watch_parent: bool = False,
                pdeathsig: bool = True) -> None:
    """Run the simulated cube and Net F/T on one :class:`DemoWorld` until ``stop`` is set.

    Parameters
    ----------
    seed, speed, period
        As :class:`DemoWorld` (``speed``: simulated seconds per wall second).
    scenario : {"grasp", "rest", "two_fingers", "calibration"}
    assembly : str, optional
        Library assembly whose patches the grasp's fingers touch.
    rate_hz : float
        Cube frame rate and Net F/T record rate, Hz.
    records_per_packet : int
        Net F/T records per packet in buffered mode.
    announce : callable, optional
        ``announce(info: dict)`` once the devices run (default: print it as one JSON line).
    stop : threading.Event, optional
        Set it (or send ``{"cmd": "quit"}``, SIGTERM, SIGINT) to stop.
    watch_parent : bool
        Child mode: also stop when the parent dies or stdin reaches end of file.
    pdeathsig : bool
        Child mode: ask the kernel for SIGTERM when the parent (thread) ends.
    """
    # deferred: the simulation (world, patches, contact, scipy) loads in the devices' process only, not
    # in a process that merely steers them (SimulatedDevices: pito-app's, docs/app.md "Start-up")
    from ._transport_netft import SimulatedNetFT
    from ._transport_pito import SimulatedPitoPort
    from ._world import DemoWorld

    stop = stop or threading.Event()
    if watch_parent and pdeathsig:
        die_with_parent()
    epoch = time.monotonic()
    world = DemoWorld(seed=seed, speed=speed, period=period, epoch=epoch)
    world.set_scenario(scenario)
    if assembly is not None:
        world.set_assembly(assembly)
    with contextlib.ExitStack() as stack:
        pito = stack.enter_context(SimulatedPitoPort(world.source, rate_hz, speed=speed, seed=seed, epoch=epoch))
        netft = stack.enter_context(SimulatedNetFT(world.source, rate_hz, speed=speed, seed=seed, epoch=epoch,
                                                   records_per_packet=records_per_packet, same_port=True))
        control = _Control(world, {"pito": pito, "netft": netft}, stop)
        stack.callback(control.close)
        signalled = install_stop_signals()
        info = {"pito": pito.port, "ati": f"{netft.host}:{netft.port}", "control": control.address,
                "pid": os.getpid(), "label": "simulated cube and Net F/T (pito_core.sim)", "simulated": True}
        (announce or (lambda i: print(json.dumps(i), flush=True)))(info)
        parent = os.getppid()
        while not (stop.is_set() or signalled()):
            time.sleep(0.2)
            # the transports log every sequence number for tests; a long-running device keeps none
            pito.log["sent"].clear()
            netft.log["sent"].clear()
            if watch_parent:
                if os.getppid() != parent:
                    break
                with contextlib.suppress(OSError, ValueError):
                    r, _, _ = select.select([sys.stdin], [], [], 0)
                    if r and not sys.stdin.buffer.read1(4096):  # end of file: the parent is gone
                        break
        stop.set()


class SimulatedDevices:
    """The simulated devices (:func:`run_devices`) in a child process, steered over its control channel.

    Parameters
    ----------
    seed, speed, period, scenario, assembly, rate_hz
        As :func:`run_devices`.
    startup_timeout : float
        Seconds to wait for the child's announcement.
    launch : DevicesLaunch, optional
        A child started earlier (its settings win over the ones above); default: start one now.

    Attributes
    ----------
    port : str
        The cube's serial port (a pty path): ``PitoSerial(port)``.
    ati : str
        ``"127.0.0.1:PORT"``: the Net F/T's RDT port and configuration page (``NetFT(host, PORT,
        http_port=PORT)``; ``host``, ``ati_port`` hold the parts).
    pid : int
        The child's process id.

    Examples
    --------
    >>> with SimulatedDevices(seed=0) as sim:                    # doctest: +SKIP
    ...     sim.set_scenario("calibration"); sim.set_operator_face(2)
    ...     cube, ref = PitoSerial(sim.port), NetFT(sim.host, sim.ati_port, http_port=sim.ati_port)
    """

    label = "simulated cube and Net F/T (pito_core.sim, own process)"

    def __init__(self, seed: int = 0, speed: float = 1.0, period: float = 1.5, scenario: str = "grasp",
                 assembly: str | None = None, rate_hz: float = 1000.0, startup_timeout: float = 60.0,
                 launch: DevicesLaunch | None = None):
        if launch is None:
            launch = DevicesLaunch(seed, speed, period, scenario, assembly, rate_hz)
        cfg = launch.cfg  # a launch started earlier (pito-app's first line) carries its own settings
        self.seed, self.speed, self.period = cfg["seed"], cfg["speed"], cfg["period"]
        self._proc = launch.proc
        self.pid = self._proc.pid
        self._lock = threading.Lock()
        self._conn = self._file = None
        try:
            info = self._announcement(startup_timeout)
            self.port, self.ati, self.control = info["pito"], info["ati"], info["control"]
            self.host, p = self.ati.rsplit(":", 1)
            self.ati_port = int(p)
            chost, cport = self.control.rsplit(":", 1)
            self._conn = socket.create_connection((chost, int(cport)), timeout=10.0)
            self._file = self._conn.makefile("rw", encoding="utf-8", newline="\n")
        except BaseException:
            self.close()
            raise

    def _announcement(self, timeout: float) -> dict:
        r, _, _ = select.select([self._proc.stdout], [], [], timeout)
        line = self._proc.stdout.readline() if r else ""
        if not line:
            code = self._proc.poll()
            raise SimulatorError(f"simulated devices: no announcement within {timeout} s (exit status {code})")
        return json.loads(line)

    def command(self, cmd: str, **fields) -> dict:
        """Send one control request (module docstring); returns the answer.

        Raises
        ------
        SimulatorError
            The devices refused it (the message says why) or are gone.
        """
        with self._lock:
            if self._file is None:
                raise SimulatorError("simulated devices: closed")
            try:
                self._file.write(json.dumps({"cmd": cmd, **fields}) + "\n")
                self._file.flush()
                line = self._file.readline()
            except OSError as exc:
                raise SimulatorError(f"simulated devices: control channel lost ({exc})") from exc
        if not line:
            raise SimulatorError("simulated devices: control channel closed")
        answer = json.loads(line)
        if not answer.get("ok"):
            raise SimulatorError(f"simulated devices: {cmd}: {answer.get('error')}")
        return answer

    def set_scenario(self, name: str) -> None:
        """``"grasp"`` (looping grasp) or ``"calibration"`` (operator loading faces under a mount)."""
        self.command("set_scenario", name=name)

    def set_mount(self, flange: str, connected_face: int) -> None:
        self.command("set_mount", flange=flange, connected_face=int(connected_face))

    def set_operator_face(self, face) -> None:
        """The simulated operator loads ``face`` 1..6 (None: hands off) from the current simulated time."""
        self.command("set_operator_face", face=None if face is None else int(face))

    def set_assembly(self, name) -> None:
        """The grasp's fingers touch library assembly ``name`` (None: flat patches)."""
        self.command("set_assembly", name=name)

    def state(self) -> dict:
        return self.command("state")["state"]

    def describe(self) -> str:
        return f"virtual cube on {self.port}, virtual Net F/T at {self.ati} (pito_core.sim, process {self.pid})"

    def alive(self) -> bool:
        return self._proc.poll() is None

    def close(self, timeout: float = 5.0) -> None:
        """Stop the child (quit request, then SIGTERM, then SIGKILL); idempotent."""
        if self._file is not None:
            with contextlib.suppress(Exception):
                self.command("quit")
            with contextlib.suppress(OSError):
                self._file.close()
                self._conn.close()
            self._file = self._conn = None
        if self._proc.poll() is None:
            with contextlib.suppress(OSError):
                self._proc.stdin.close()
            try:
                self._proc.wait(timeout)
            except subprocess.TimeoutExpired:
                self._proc.terminate()
                try:
                    self._proc.wait(timeout)
                except subprocess.TimeoutExpired:
                    self._proc.kill()
                    self._proc.wait(timeout)
        for f in (self._proc.stdin, self._proc.stdout):
            with contextlib.suppress(OSError, ValueError):
                f.close()

    def __enter__(self) -> "SimulatedDevices":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __del__(self):  # a forgotten handle still stops its child
        with contextlib.suppress(Exception):
            if self._proc.poll() is None:
                self._proc.kill()

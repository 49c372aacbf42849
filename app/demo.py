"""Demo mode: the simulated devices in their own process, opened exactly as hardware.

:class:`DemoDevices` starts ``pito_core.sim.SimulatedDevices`` (a child process: the cube on
a pty, the Net F/T on loopback UDP), opens the real drivers and an acquisition on the
addresses it announces, and steers the simulated world (scenario, mount, operator, object)
over the child's control channel. :func:`demo_calibration` calibrates the virtual cube with
the simulator; :func:`cached_demo_calibration` reads the one a previous start wrote to the
user's cache, keyed by everything that makes it (method, mount, k, seed, the simulator's
parameters, the source of ``pito_core`` ``calibration``, ``sim`` and ``io``), so a start
after the first shows forces at once. No Qt here.
"""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

import pito_core
import pito_core.calibration  # the fit (scipy.linalg) loads at its first use: in the child that calibrates
import pito_core.sim
from pito_core.calibration import load_calibration
from pito_core.io import FileFormatError
from pito_core.pipeline import PipelineProcess
from pito_core.sim import SimParams, SimulatedDevices

__all__ = ["DemoDevices", "demo_calibration", "cached_demo_calibration", "demo_cache_path", "cache_dir", "DEMO_METHOD",
           "DEMO_OBJECT_MASS"]

#: The simulated object's mass, kg (``pito_core.sim.GraspLiveSource``'s): the live view's mass in the demo.
DEMO_OBJECT_MASS = 0.3

#: Method of the demo's startup calibration (every face calibrated on its own, all six loaded).
DEMO_METHOD = "loaded_frame"


class DemoDevices:
    """The simulated cube and reference in a child process, read and processed in another (``PipelineProcess``).

    Parameters
    ----------
    seed : int
    speed : float
        Simulated seconds per wall second.
    period : float
        Seconds per move-and-hold of the simulated operator.
    launches : (DevicesLaunch, PipelineLaunch), optional
        The two child processes, started earlier (``app.main``): they boot while
        the caller imports; default: start them now, one after the other.
    hold : threading.Event, optional
        The pipeline opens the devices once it is set (``app.main``: when the window is built).
        Until then neither child works: the cube's pty fills and its writer waits, the Net F/T
        streams to nobody (it waits for a start request).
    """

    simulated = True

    def __init__(self, seed: int = 0, speed: float = 1.0, period: float = 1.5, launches=None, hold=None):
        sim_launch, pipe_launch = launches or (None, None)
        try:
            self.sim = SimulatedDevices(seed=seed, speed=speed, period=period, launch=sim_launch)
        except BaseException:
            if pipe_launch is not None:
                pipe_launch.close()
            raise
        if hold is not None:
            hold.wait()
        try:
            # the drivers and the pipeline in a process of their own, as for hardware (MainWindow.connect_devices);
            # buffered RDT (10 records per packet), as a real box allows: a tenth of the packets
            self.process = PipelineProcess(self.sim.port, self.sim.ati, simulated=True, buffered=True,
                                           launch=pipe_launch)
        except BaseException:
            self.sim.close()
            raise
        self.port, self.address = self.sim.port, self.sim.ati

    def describe(self) -> str:
        return self.sim.describe()

    def open_source(self):
        """A live-feed source on the demo's pipeline process (the demo keeps it: the source's close leaves it running)."""
        return self.process.borrowed()

    def set_scenario(self, name: str) -> None:
        self.sim.set_scenario(name)

    def set_mount(self, flange: str, connected_face: int) -> None:
        self.sim.set_mount(flange, connected_face)

    def set_operator_face(self, face) -> None:
        self.sim.set_operator_face(face)

    def set_assembly(self, assembly) -> None:
        """The grasp's fingers touch this assembly's patches (an ``Assembly``, a library name, or None)."""
        self.sim.set_assembly(getattr(assembly, "name", assembly))

    def close(self) -> None:
        try:
            self.process.close()
        finally:
            self.sim.close()


#: The demo calibration's mount: a flange with an access hole on face 6.
DEMO_MOUNT = ("frame_hole", 6)


def _source_digest() -> str:
    """SHA-256 of the source of the packages that make the demo calibration (calibration, sim, io)."""
    h = hashlib.sha256()
    root = Path(pito_core.__file__).parent
    for pkg in ("calibration", "sim", "io", "frames"):
        for f in sorted((root / pkg).rglob("*.py")):
            h.update(f.relative_to(root).as_posix().encode())
            h.update(f.read_bytes())
    return h.hexdigest()


def cache_dir() -> Path:
    """The app's cache: ``$PITO_CACHE_DIR``, default ``$XDG_CACHE_HOME/pito``, else ``~/.cache/pito``."""
    return Path(os.environ.get("PITO_CACHE_DIR") or Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
                / "pito")


def demo_cache_path(k: int = 1500, seed: int = 0) -> Path:
    """Where the demo calibration of ``(k, seed)`` is cached: ``$PITO_CACHE_DIR`` (default
    ``$XDG_CACHE_HOME/pito``, else ``~/.cache/pito``) ``/demo-<key>.pitocal``, the key a hash of
    everything that makes it."""
    base = cache_dir()
    key = json.dumps({"method": DEMO_METHOD, "mount": DEMO_MOUNT, "k": int(k), "seed": int(seed),
                      "sim": SimParams().to_dict(), "source": _source_digest()}, sort_keys=True, default=str)
    return Path(base) / f"demo-{hashlib.sha256(key.encode()).hexdigest()[:16]}.pitocal"


def cached_demo_calibration(k: int = 1500, seed: int = 0):
    """The demo calibration a previous start cached for ``(k, seed)`` and today's code, or None.

    A cache file that cannot be read is removed (and None returned): the next start writes it again."""
    path = demo_cache_path(k, seed)
    if not path.is_file():
        return None
    try:
        cal = load_calibration(path)
    except FileFormatError:
        path.unlink(missing_ok=True)
        return None
    return cal if cal.meta.get("simulated") else None


def demo_calibration(k: int = 1500, seed: int = 0, cache: bool = True):
    """Calibrate the virtual cube with the simulator: method :data:`DEMO_METHOD` (flange with an
    access hole on face 6, all six faces loaded, ``k`` samples each). SIMULATED data.

    With ``cache`` the result is written to :func:`demo_cache_path` for the next start."""
    session = pito_core.sim.simulate_calibration(*DEMO_MOUNT, k=k, seed=seed)
    cal = pito_core.calibration.calibrate(session, DEMO_METHOD)
    if cache:
        path = demo_cache_path(k, seed)
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            cal.save(path)
        except OSError:  # a read-only home: no cache, the demo calibrates at every start as before
            pass
    return cal

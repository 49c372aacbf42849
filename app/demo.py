"""Demo mode: the simulated devices in their own process, opened exactly as hardware.

:class:`DemoDevices` starts ``pito_core.sim.SimulatedDevices`` (a child process: the cube on
a pty, the Net F/T on loopback UDP), opens the real drivers and an acquisition on the
addresses it announces, and steers the simulated world (scenario, mount, operator, object)
over the child's control channel. :func:`demo_calibration` calibrates the virtual cube with
the simulator at startup. No Qt here.
"""

from __future__ import annotations

from pito_core.calibration import calibrate
from pito_core.pipeline import PipelineProcess
from pito_core.sim import SimulatedDevices, simulate_calibration

__all__ = ["DemoDevices", "demo_calibration", "DEMO_METHOD", "DEMO_OBJECT_MASS"]

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
    """

    simulated = True

    def __init__(self, seed: int = 0, speed: float = 1.0, period: float = 1.5):
        self.sim = SimulatedDevices(seed=seed, speed=speed, period=period)
        try:
            # the drivers and the pipeline in a process of their own, as for hardware (MainWindow.connect_devices);
            # buffered RDT (10 records per packet), as a real box allows: a tenth of the packets
            self.process = PipelineProcess(self.sim.port, self.sim.ati, simulated=True, buffered=True)
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


def demo_calibration(k: int = 1500, seed: int = 0):
    """Calibrate the virtual cube with the simulator: method :data:`DEMO_METHOD` (flange with an
    access hole on face 6, all six faces loaded, ``k`` samples each). SIMULATED data."""
    session = simulate_calibration("frame_hole", 6, k=k, seed=seed)
    return calibrate(session, DEMO_METHOD)

"""The app's one doorway into ``pito_core``: devices, simulators, assemblies, contacts, recordings.

Everything the widgets need from the core goes through these small adapters, so a change
of a core API touches this module only. No Qt here.
"""

from __future__ import annotations

import time as _time
from pathlib import Path

import numpy as np

from pito_core.frames import FACES, CubeCore

__all__ = [
    "ReplaySource", "DemoRig", "open_hardware", "demo_calibration", "mount_pose", "list_assemblies",
    "load_assembly", "display_meshes", "weight", "make_solver", "save_recording",
]

ASSETS = Path(__file__).resolve().parent.parent / "assets" / "patches"


# ---------------------------------------------------------------- geometry of the mounts
def mount_pose(flange: str, connected_face: int, core: CubeCore | None = None) -> np.ndarray:
    """``T_core_ati (4, 4)``: the reference sensor's frame under ``flange`` on ``connected_face``."""
    from pito_core.sim import reference_pose

    return reference_pose(flange, connected_face, core)


# ---------------------------------------------------------------- sources
class ReplaySource:
    """Plays samples back in real time (a recording, or any arrays), looping; seekable.

    Parameters
    ----------
    path_or_arrays : path or (time (n,), counts (n, 36), reference (n, 6))
    loop : bool
    """

    simulated = False

    def __init__(self, path_or_arrays, loop: bool = True, speed: float = 1.0):
        if isinstance(path_or_arrays, (str, Path)):
            t, counts, reference, self.simulated = load_recording(path_or_arrays)
        else:
            t, counts, reference = path_or_arrays
        self.time = np.asarray(t, dtype=float)
        self.counts = np.asarray(counts, dtype=float)
        self.reference = np.asarray(reference, dtype=float)
        if self.time.size == 0:
            raise ValueError("recording: no samples")
        self.t0 = float(self.time[0])
        self.duration = float(self.time[-1] - self.t0)
        self.loop = loop
        self.speed = float(speed)
        self._pos = 0.0  # s into the recording
        self._wall = None
        self._index = 0

    def seek(self, t: float) -> None:
        self._pos = float(np.clip(t, 0.0, self.duration))
        self._index = int(np.searchsorted(self.time - self.t0, self._pos))
        self._wall = _time.monotonic()

    def read(self):
        now = _time.monotonic()
        if self._wall is None:
            self._wall = now
        self._pos += (now - self._wall) * self.speed
        self._wall = now
        if self._pos > self.duration:
            if not self.loop:
                self._pos = self.duration
            else:
                self._pos = 0.0
                self._index = 0
        stop = int(np.searchsorted(self.time - self.t0, self._pos, side="right"))
        sl = slice(self._index, max(stop, self._index))
        self._index = max(stop, self._index)
        return self.time[sl], self.counts[sl], self.reference[sl]

    def stats(self) -> dict:
        return {"position": self._pos, "duration": self.duration, "replay": True}

    def close(self) -> None:
        pass


def open_hardware(port: str, host: str):
    """The real cube on ``port`` and the Net F/T at ``host``, as a worker source."""
    from pito_core import devices

    acq = devices.Acquisition(devices.PitoSerial(port), devices.NetFT(host))
    return AcquisitionSource(acq, simulated=False)


class AcquisitionSource:
    """Adapter: a ``pito_core.devices.Acquisition`` as a worker :class:`~app.workers.Source`."""

    def __init__(self, acquisition, simulated: bool, on_close=None):
        self.acq = acquisition
        self.simulated = simulated
        self._on_close = on_close

    def read(self):
        return self.acq.read_new()

    def stats(self) -> dict:
        return dict(self.acq.stats())

    def close(self) -> None:
        self.acq.close()
        if self._on_close is not None:
            self._on_close()


# ---------------------------------------------------------------- demo
class DemoRig:
    """The simulated cube and reference behind the real drivers, with two scenarios.

    ``grasp``: a hand grasps, lifts and moves the patched object (live view);
    ``calibration``: the cube on a flange, a simulated operator loading one face at a time.
    """

    def __init__(self, seed: int = 0, core: CubeCore | None = None):
        self.seed = seed
        self.core = core or CubeCore()
        self.scenario = "grasp"
        self.flange, self.connected_face = "face", 6
        self.operator_face = None
        self.assembly = None
        self._sources = []

    def describe(self) -> str:
        return "virtual cube and virtual reference"

    def set_scenario(self, name: str) -> None:
        self.scenario = name

    def set_mount(self, flange: str, connected_face: int) -> None:
        self.flange, self.connected_face = flange, connected_face

    def set_operator_face(self, face) -> None:
        self.operator_face = face

    def set_assembly(self, assembly) -> None:
        self.assembly = assembly

    def open_source(self):
        return self._interim_source()

    def _interim_source(self):
        """INTERIM until pito_core.sim live sources and the simulated transports land: replay
        simulator output in real time (no drivers in the path)."""
        from pito_core import sim

        if self.scenario == "grasp":
            run = sim.simulate_free_grasp(k=12000, seed=self.seed)
            ref = np.full((run.time.size, 6), np.nan)
            src = ReplaySource((run.time, run.counts, ref))
        else:
            s = sim.simulate_calibration(self.flange, self.connected_face, k=3000, seed=self.seed)
            src = ReplaySource((s.time, s.counts, s.reference))
        src.simulated = True
        self._sources.append(src)
        return src

    def close(self) -> None:
        for s in self._sources:
            s.close()
        self._sources = []


def demo_calibration(rig: DemoRig | None = None, k: int = 1500, seed: int = 0):
    """Calibrate the virtual cube with the simulator: method ``total``, flange on face 6, ``k`` per face."""
    from pito_core.calibration import calibrate
    from pito_core.sim import simulate_calibration

    session = simulate_calibration("face", 6, k=k, seed=seed)
    return calibrate(session, "total")


# ---------------------------------------------------------------- objects and contacts
def list_assemblies() -> list[str]:
    """Assemblies in ``assets/patches/`` (plus the bare ``cube``)."""
    try:
        from pito_core.contact import list_assemblies as _list

        names = list(_list())
    except ImportError:
        names = sorted(p.stem for p in ASSETS.glob("*.json")) if ASSETS.is_dir() else []
    return names or ["cube"]


def load_assembly(name: str, core: CubeCore):
    try:
        from pito_core.contact import load_assembly as _load
    except ImportError:
        return None
    return _load(name)


def display_meshes(assembly) -> dict | None:
    """Face → pyvista mesh (core frame, m) of each patch, or None for the bare cube."""
    if assembly is None:
        return None
    import pyvista as pv

    out = {}
    meshes = getattr(assembly, "display_meshes", None)
    if callable(meshes):
        meshes = meshes()
    for i, m in (meshes or {}).items():
        out[int(i)] = pv.wrap(m) if not isinstance(m, pv.DataSet) else m
    return out


def weight(assembly) -> float:
    """m·g of the object, N."""
    mass = getattr(assembly, "mass", None)
    return float(mass) * 9.81 if mass else 0.3 * 9.81


def make_solver(assembly, core: CubeCore):
    """``solver(wrenches (6, 6)) -> contacts dict`` for the worker (core frame)."""
    try:
        from pito_core.contact import Plane, solve
    except ImportError:
        return None
    if assembly is not None:
        from pito_core.contact import solve_object

        def solver(W):
            c = solve_object(assembly, W)
            return {k: np.asarray(getattr(c, k)) for k in ("points", "normals", "forces", "torsions", "valid", "covariance")}

        return solver
    surfaces = {i: Plane((0.0, 0.0, 0.0), (0.0, 0.0, 1.0)) for i in FACES}
    poses = core.face_poses()

    def solver(W):
        pts = np.full((6, 3), np.nan)
        nrm = np.full((6, 3), np.nan)
        frc = np.full((6, 3), np.nan)
        tor = np.full(6, np.nan)
        val = np.zeros(6, dtype=bool)
        for k, i in enumerate(FACES):
            if not np.all(np.isfinite(W[k])):
                continue
            e = solve(surfaces[i], W[k])
            if not e.valid:
                continue
            R, p = poses[k][:3, :3], poses[k][:3, 3]
            pts[k] = R @ e.point + p
            nrm[k] = R @ e.normal
            frc[k] = R @ e.force
            tor[k] = e.torsion
            val[k] = True
        return {"points": pts, "normals": nrm, "forces": frc, "torsions": tor, "valid": val, "covariance": None}

    return solver


# ---------------------------------------------------------------- recordings
def save_recording(path, time, counts, reference, simulated: bool = False) -> None:
    from pito_core import io

    io.write_recording(path, time=time, counts=counts, reference=reference, meta={"simulated": simulated})


def load_recording(path):
    from pito_core import io

    rec = io.read_recording(path)
    return rec.time, rec.counts, rec.reference, bool(rec.meta.get("simulated", False))

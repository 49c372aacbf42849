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
            self.path = str(path_or_arrays)
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

    cube = devices.PitoSerial(port)
    netft = devices.NetFT(host) if host else None
    acq = devices.Acquisition(cube, netft, buffer_seconds=60.0).start()
    return AcquisitionSource(acq, simulated=False, owns=True)


#: A cube sample at or beyond these counts is saturated (24-bit ADC of the cube's boards).
CUBE_ADC_LIMIT = 2**23 - 1


class AcquisitionSource:
    """Adapter: a running ``pito_core.devices.Acquisition`` as a worker :class:`~app.workers.Source`.

    ``read()`` returns the cube samples that arrived since the previous call, with the
    reference interpolated at their host times; cube samples newer than the newest
    reference record wait for the next call (never extrapolated). ``last_raw`` keeps the
    raw device rows of that call for the recorder.
    """

    def __init__(self, acquisition, simulated: bool, owns: bool = False, window: int = 4000,
                 ref_window: int = 20000):
        self.acq = acquisition
        self.ref_window = ref_window
        self.backlog = 0.0  # s by which the newest cube sample trails the newest reference record
        self.simulated = simulated
        self.owns = owns
        self.window = window
        self._last_seq = None
        self._last_ref_seq = None
        self._rates = {"cube": _Rate(), "reference": _Rate()}
        self._saturated = 0
        self.last_raw = None

    @staticmethod
    def _new(seq, last):
        if last is None:
            return np.ones(seq.shape, dtype=bool)
        d = (seq.astype(np.int64) - int(last)) % 2**32
        return (d >= 1) & (d < 2**31)

    def read(self):
        pb, fb = self.acq.latest(self.window)
        if self.acq.netft is not None:  # a longer reference history: the cube may be read late
            fb = self.acq.latest(self.ref_window)[1]
        new = self._new(pb.seq, self._last_seq)
        if self._last_seq is None:  # start with the last 0.1 s only
            new[: max(0, new.size - 100)] = False
        t_all = self._cube_clock(pb)
        have_ref = fb is not None and fb.host_time.size > 0
        if have_ref:
            tr_all = self._ref_clock(fb)
            # no extrapolation: cube samples newer than the newest reference record wait for the
            # next read (a held reference would look still while the load moves)
            new &= t_all <= tr_all.max()
        elif self.acq.netft is not None:
            new[:] = False
        idx = np.flatnonzero(new)
        if idx.size:
            self._last_seq = int(pb.seq[idx[-1]])
        t = t_all[new]
        counts = np.asarray(pb.counts[new], dtype=float)
        reference = np.full((t.size, 6), np.nan)
        new_ref = None
        if have_ref:
            new_ref = self._new(fb.rdt_seq, self._last_ref_seq)
            self._last_ref_seq = int(fb.rdt_seq[-1])
            self._rates["reference"].add(fb.host_time[new_ref])
            if t.size:
                order = np.argsort(tr_all, kind="stable")
                w = fb.wrench[order] - self.acq.reference_bias
                reference = np.column_stack([np.interp(t, tr_all[order], w[:, j]) for j in range(6)])
                reference[t < tr_all.min()] = np.nan  # older than the reference history: unknown
        self._rates["cube"].add(pb.host_time[new])
        self.backlog = float(tr_all.max() - t.max()) if have_ref and t.size else 0.0
        self._saturated += int((np.abs(counts) >= CUBE_ADC_LIMIT).any(axis=1).sum())
        self.last_raw = (pb, new, fb, new_ref)
        return t, counts, reference

    # Both streams are put on the host clock through their own sample clocks: sample time =
    # device time + the smallest (host arrival − device time) seen so far. Arrival times
    # alone would pair samples wrongly whenever one stream is read late (a busy CPU, a
    # buffered pty), and the two devices are then compared sample by sample.
    def _cube_clock(self, pb) -> np.ndarray:
        raw = pb.time_us.astype(np.int64)
        if raw.size == 0:
            return np.zeros(0)
        d = np.diff(raw, prepend=raw[0]) % 2**32  # unwrapped within the window
        dev = (raw[0] + np.cumsum(d)) * 1e-6
        if not hasattr(self, "_cube_clk"):
            self._cube_clk = _ClockOffset()
        return dev + self._cube_clk.update(pb.host_time - dev)

    def _ref_clock(self, fb, rate: float = 1000.0) -> np.ndarray:
        """Reference records at the RDT rate ``rate`` (Hz, the Net F/T's configured output rate)."""
        raw = fb.rdt_seq.astype(np.int64)
        d = np.diff(raw, prepend=raw[0]) % 2**32
        dev = (raw[0] + np.cumsum(d)) / rate
        if not hasattr(self, "_ref_clk"):
            self._ref_clk = _ClockOffset()
        return dev + self._ref_clk.update(fb.host_time[-200:] - dev[-200:]) if dev.size else dev

    def stats(self) -> dict:
        s = self.acq.stats()
        net = s.get("netft") or {}
        cube = s.get("pito") or {}
        return {
            "rate_cube": self._rates["cube"].rate(),
            "rate_reference": self._rates["reference"].rate() if s.get("netft") is not None else None,
            "saturated": self._saturated + int(net.get("saturated", 0) or 0),
            "dropped": int(cube.get("dropped", 0) or 0) + int(net.get("lost", 0) or 0),
            "simulated": self.simulated,
            "backlog": self.backlog,
        }

    def close(self) -> None:
        if self.owns:
            self.acq.close()


class _ClockOffset:
    """Host time minus device time of a stream, s: the smallest difference seen (the
    least-delayed sample: a sample can arrive late, never before it was taken), restarted
    when the device clock jumps (wrap, reset). Late reads (a busy CPU, a buffered pty) then
    leave sample times unchanged."""

    def __init__(self):
        self.offset = None

    def update(self, diff) -> float:
        v = float(np.min(diff))
        if self.offset is None or abs(v - self.offset) > 10.0:
            self.offset = v
        else:
            self.offset = min(self.offset, v)
        return self.offset


class _Rate:
    """Sample rate over the last ~2 s of host times, Hz."""

    def __init__(self, span: float = 2.0):
        self.span = span
        self.times = np.zeros(0)

    def add(self, t) -> None:
        if len(t):
            self.times = np.concatenate([self.times, np.asarray(t, dtype=float)])
            self.times = self.times[self.times >= self.times[-1] - self.span]

    def rate(self) -> float:
        if self.times.size < 2 or self.times[-1] <= self.times[0]:
            return 0.0
        return (self.times.size - 1) / (self.times[-1] - self.times[0])


# ---------------------------------------------------------------- demo
class _SwitchedLiveSource:
    """The live source the simulated transports read, switched on the *simulated* clock.

    The two simulated devices compute their samples in their own threads, sometimes late
    (a busy CPU) and then for past times. A switch (scenario, face being loaded) therefore
    takes effect from a simulated time on: a sample of an earlier time still comes from the
    source that was active then, so the cube and the reference never disagree about it.
    """

    def __init__(self, source, clock):
        self.clock = clock  # () -> current simulated time, s
        self._schedule = [(-np.inf, source)]  # (from time, source), in order

    @property
    def active(self):
        return self._schedule[-1][1]

    @active.setter
    def active(self, source):
        now = self.clock()
        self._schedule = [seg for seg in self._schedule if seg[0] < now][-4:] + [(now, source)]

    def _split(self, t, method: str):
        t = np.atleast_1d(np.asarray(t, dtype=float))
        sched = self._schedule
        if t.size == 0 or t.min() >= sched[-1][0]:
            return getattr(sched[-1][1], method)(t)
        starts = np.array([s for s, _ in sched])
        which = np.searchsorted(starts, t, side="right") - 1
        out = None
        for k in np.unique(which):
            m = which == k
            part = getattr(sched[k][1], method)(t[m])
            if out is None:
                out = np.empty((t.size,) + part.shape[1:], dtype=part.dtype)
            out[m] = part
        return out

    def counts_at(self, t):
        return self._split(t, "counts_at")

    def reference_at(self, t):
        return self._split(t, "reference_at")


class DemoRig:
    """The simulated cube and reference behind the real drivers, with two scenarios.

    The simulators (``pito_core.sim`` live sources) write real frames into a pty and real
    RDT packets on loopback UDP; the real drivers (``PitoSerial``, ``NetFT``) and the
    ``Acquisition`` read them. ``grasp``: a hand grasps, lifts and moves the object (live
    view); ``calibration``: the cube on a flange, a simulated operator loading one face at a
    time (the wizard).

    Parameters
    ----------
    seed : int
    speed : float
        Simulated seconds per wall second (tests run faster than real time).
    period : float
        Seconds per move-and-hold of the simulated operator.
    """

    def __init__(self, seed: int = 0, core: CubeCore | None = None, speed: float = 1.0, period: float = 1.5):
        import contextlib

        from pito_core import devices, sim

        self.seed = seed
        self.core = core or CubeCore()
        self.speed = speed
        self.period = period
        self.model = sim.VirtualCube()
        self.assembly_name = None
        self.grasp = sim.GraspLiveSource(seed=seed, model=self.model)
        self.flange, self.connected_face = "face", 6
        self.operator_face = None
        self._cal_sources = {}
        self.calibration = self._calibration_source(None)
        self._epoch = None
        self.switch = _SwitchedLiveSource(self.grasp, self.sim_time)
        self.scenario = "grasp"
        self._stack = contextlib.ExitStack()
        try:
            pito_sim, netft_sim = self._stack.enter_context(
                devices.open_simulated_devices(self.switch, speed=speed, seed=seed))
            self._epoch = pito_sim.epoch
            self.port = pito_sim.port
            self.address = f"{netft_sim.host}:{netft_sim.port}"
            cube = devices.PitoSerial(pito_sim.port)
            # buffered RDT (10 records per packet): a tenth of the packets, and of the Python
            # work per sample in the two in-process device threads, as a real box allows too
            netft = devices.NetFT(netft_sim.host, netft_sim.port, http_port=netft_sim.http_port, buffered=True)
            self.acquisition = devices.Acquisition(cube, netft, buffer_seconds=30.0, meta={"simulated": True}).start()
            self._stack.callback(self.acquisition.close)
        except Exception:
            self._stack.close()
            raise

    def sim_time(self) -> float:
        """The simulated devices' clock, s (the same for the cube and the reference)."""
        import time

        if self._epoch is None:
            return 0.0
        return (time.monotonic() - self._epoch) * self.speed

    def _calibration_source(self, face):
        """The operator loading ``face`` (None: hands off) under the current mount (one source per face)."""
        from pito_core import sim

        key = (self.flange, self.connected_face, face)
        if key not in self._cal_sources:
            src = sim.CalibrationLiveSource(self.flange, self.connected_face, seed=self.seed, model=self.model,
                                            period=self.period)
            src.face = face
            self._cal_sources[key] = src
        return self._cal_sources[key]

    def describe(self) -> str:
        return f"virtual cube on {self.port}, virtual Net F/T at {self.address} (pito_core.sim)"

    def open_source(self) -> "AcquisitionSource":
        """A worker source on the rig's acquisition (the rig keeps the devices)."""
        return AcquisitionSource(self.acquisition, simulated=True, owns=False)

    def set_scenario(self, name: str) -> None:
        if name not in ("grasp", "calibration"):
            raise ValueError(f"scenario: expected 'grasp' or 'calibration', got {name!r}")
        self.scenario = name
        self.switch.active = self.grasp if name == "grasp" else self.calibration

    def set_mount(self, flange: str, connected_face: int) -> None:
        if (flange, connected_face) == (self.flange, self.connected_face):
            return
        self.flange, self.connected_face = flange, connected_face
        face = self.operator_face
        if flange == "frame" and face == connected_face:
            face = None
        self.set_operator_face(face)

    def set_operator_face(self, face) -> None:
        """The simulated operator loads ``face`` (None: hands off), from the current simulated time on."""
        self.operator_face = face
        self.calibration = self._calibration_source(face)
        if self.scenario == "calibration":
            self.switch.active = self.calibration

    def set_assembly(self, assembly) -> None:
        """Fingers of the grasp touch this assembly's patches."""
        from pito_core import sim

        name = getattr(assembly, "name", None)
        if name == self.assembly_name:
            return
        self.assembly_name = name
        try:
            self.grasp = sim.GraspLiveSource(seed=self.seed, model=self.model, assembly=name)
        except Exception:  # noqa: BLE001 - an assembly the grasp does not know: flat patches
            self.grasp = sim.GraspLiveSource(seed=self.seed, model=self.model)
        if self.scenario == "grasp":
            self.switch.active = self.grasp

    def close(self) -> None:
        self._stack.close()


#: Method of the demo's startup calibration.
DEMO_METHOD = "loaded_frame"


def demo_calibration(rig: DemoRig | None = None, k: int = 1500, seed: int = 0):
    """Calibrate the virtual cube with the simulator: method ``loaded_frame`` (flange with an access
    hole on face 6, all six faces loaded, ``k`` samples each) — every face calibrated on its own."""
    from pito_core.calibration import calibrate
    from pito_core.sim import simulate_calibration

    session = simulate_calibration("frame_hole", 6, k=k, seed=seed, model=None if rig is None else rig.model)
    return calibrate(session, DEMO_METHOD)


# ---------------------------------------------------------------- objects and contacts
def list_assemblies() -> list[str]:
    """Object assemblies of the patch library (``assets/patches/``), ``pito_mixed`` first."""
    from pito_core.contact import list_assemblies as _list

    names = list(_list())
    return sorted(names, key=lambda n: (n != "pito_mixed", n))


def load_assembly(name: str, core: CubeCore):
    from pito_core.contact import load_assembly as _load

    return _load(name)


def display_meshes(assembly) -> dict | None:
    """Face → pyvista mesh (core frame, m) of each patch, or None for the bare cube."""
    if assembly is None:
        return None
    import pyvista as pv

    out = {}
    for i in FACES:
        m = assembly.face_mesh(i)
        out[i] = pv.wrap(m)
    return out


def weight(assembly) -> float:
    """m·g of the object, N (0.3 kg when the assembly does not say)."""
    mass = getattr(assembly, "mass", None)
    return float(mass if mass else 0.3) * 9.81


def center_of_gravity(assembly) -> np.ndarray:
    """Centre of gravity of the object in the core frame, m (the core centre when unknown)."""
    c = getattr(assembly, "center_of_gravity", None)
    return np.zeros(3) if c is None else np.asarray(c, dtype=float)


def wrench_covariance():
    """Noise covariance of a face wrench ``(6, 6)`` (N², N²·m, N²·m²) for the contact uncertainty."""
    from pito_core.contact import DEFAULT_WRENCH_COV

    return DEFAULT_WRENCH_COV


def make_solver(assembly, core: CubeCore, force_threshold: float = 0.3, wrench_cov=None):
    """``solver(wrenches (6, 6)) -> contacts dict`` for the worker (core frame), or None."""
    from pito_core.contact import solve_object

    if assembly is None:
        assembly = "cube"

    def solver(W):
        c = solve_object(assembly, W[None], force_threshold, wrench_cov=wrench_cov)
        cov = None if c.point_cov is None else np.asarray(c.point_cov)[0]
        return {
            "points": np.asarray(c.point)[0], "normals": np.asarray(c.normal)[0],
            "forces": np.asarray(c.force)[0], "torsions": np.asarray(c.torsion)[0],
            "valid": np.asarray(c.valid)[0], "covariance": cov,
        }

    return solver


# ---------------------------------------------------------------- recordings
def open_recorder(path, simulated: bool, meta: dict | None = None):
    """A ``pito_core.io.RecordingWriter`` on ``path`` (format ``pito-recording``)."""
    from pito_core.io import RecordingWriter

    info = {"simulated": bool(simulated), "source": "pito-app"}
    info.update(meta or {})
    return RecordingWriter(path, meta=info)


def record_raw(writer, raw) -> None:
    """Append the raw device rows of one read (``AcquisitionSource.last_raw``) to ``writer``."""
    if raw is None:
        return
    pb, new, fb, new_ref = raw
    if new is not None and new.any():
        writer.append_pito(pb.seq[new], pb.time_us[new], pb.host_time[new], pb.counts[new])
    if fb is not None and new_ref is not None and new_ref.any():
        writer.append_netft(fb.rdt_seq[new_ref], fb.ft_seq[new_ref], fb.status[new_ref], fb.host_time[new_ref],
                            fb.wrench[new_ref])


def load_recording(path):
    """``(time (n,), counts (n, 36), reference (n, 6), simulated)`` of a recording, reference at the cube times."""
    from pito_core.io import read_recording

    rec = read_recording(path, recover=True)
    t = np.asarray(rec.pito["host_time"], dtype=float)
    counts = np.asarray(rec.pito["counts"], dtype=float)
    reference = np.full((t.size, 6), np.nan)
    if rec.netft.size and t.size:
        tr = np.asarray(rec.netft["host_time"], dtype=float)
        w = np.asarray(rec.netft["wrench"], dtype=float)
        order = np.argsort(tr, kind="stable")
        reference = np.column_stack([np.interp(t, tr[order], w[order, j]) for j in range(6)])
    return t, counts, reference, rec.simulated

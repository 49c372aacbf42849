"""Simulated calibration data for the benchmark, generated block by block.

Every array here is simulated (``pito_core.sim.VirtualCube``): one face is loaded at a
time with a wrench uniform in ±15 N and ±0.1 N·m per axis (face frame, at the face
centre), 5 % of the samples are unloaded, the faces carry what the mount's load paths
give them (``face_wrenches_from_applied``), the cube turns them into 36 counts (linear
sensitivity with inter-face coupling, each hub's quadratic response, offsets, gauge noise)
and the reference reads the total load, noise free. Temperature drift and the frame
joints' hysteresis are left out so that the fit, not the data, is what the benchmark
measures. Generation is deterministic in ``seed`` and independent of the block size.
"""

from __future__ import annotations

import numpy as np

from pito_core.calibration import CalibrationSession
from pito_core.defaults import FULL_SCALE_FACE
from pito_core.frames import FACES, N_GAUGES, invert_pose, wrench_adjoint
from pito_core.io import write_session
from pito_core.sim import VirtualCube, reference_pose

__all__ = ["MOUNT_OF_METHOD", "BenchData", "generate_session", "write_session_file"]

#: Mount (flange, connected face) whose sessions each method is fitted from.
MOUNT_OF_METHOD = {
    "face_to_face": ("face", 6),
    "quasi_total": ("frame", 6),
    "total": ("face", 6),
    "loaded_frame": ("frame_hole", 6),
    "unloaded_frame": ("face", 6),
}
#: Full-scale applied load per axis, N and N·m.
LOAD_SCALE = np.asarray(FULL_SCALE_FACE)
#: Fraction of unloaded samples.
UNLOADED_FRACTION = 0.05
#: Samples generated per block (memory of the generator ≈ 400 B × this).
GEN_BLOCK = 1 << 16


class BenchData:
    """A deterministic stream of simulated calibration samples for one mount.

    Parameters
    ----------
    flange : {"frame", "frame_hole", "face"}
    connected_face : int
        1..6.
    n : int
        Number of samples.
    seed : int
        Seed of the loads and the gauge noise (the cube itself is ``VirtualCube(seed=0)``).
    """

    def __init__(self, flange: str, connected_face: int, n: int, seed: int = 0):
        self.flange, self.connected_face, self.n, self.seed = flange, int(connected_face), int(n), int(seed)
        self.cube = VirtualCube(seed=0)
        self.core = self.cube.core
        self.T_core_ati = reference_pose(flange, connected_face, self.core)
        # the free faces; through the frame's hole the connected face is loaded too
        self.faces = list(FACES) if flange == "frame_hole" else [f for f in FACES if f != self.connected_face]
        T_core_c = self.core.face_pose(self.connected_face)
        # wrench maps from face i's frame to the reference frame and to the connected face's frame
        T_face_core = [invert_pose(self.core.face_pose(i)) for i in FACES]
        self._X_ati_face = [wrench_adjoint(T @ self.T_core_ati) for T in T_face_core]
        self._X_c_face = [wrench_adjoint(T @ T_core_c) for T in T_face_core]

    def block(self, index: int):
        """Samples ``[index·GEN_BLOCK, …)``: ``counts (n, 36) int32``, ``reference (n, 6)``, ``loaded (n, 6)``."""
        start = index * GEN_BLOCK
        m = max(0, min(GEN_BLOCK, self.n - start))
        rng = np.random.default_rng([self.seed, index])
        face = np.asarray(self.faces)[rng.integers(0, len(self.faces), m)]
        face[rng.random(m) < UNLOADED_FRACTION] = 0
        if index == 0:
            face[: min(m, 50)] = 0  # every session starts with a tare
        W_face = rng.uniform(-1.0, 1.0, (m, 6)) * LOAD_SCALE
        F = np.zeros((m, 6, 6))  # wrench on each face, face frames
        reference = np.zeros((m, 6))
        loaded = np.zeros((m, 6), dtype=bool)
        c = self.connected_face - 1
        for i in FACES:
            sel = np.flatnonzero(face == i)
            if not sel.size:
                continue
            loaded[sel, i - 1] = True
            w = W_face[sel]
            reference[sel] = w @ self._X_ati_face[i - 1].T
            if self.flange == "face" and i - 1 == c:
                F[sel, c] = w  # eq. 6 of the multi-touch paper: carried by the connected face
                continue
            F[sel, i - 1] = w
            if self.flange == "face":
                F[sel, c] = -(w @ self._X_c_face[i - 1].T)  # the connected face's reaction
        counts = self.cube.counts_from_face_wrenches(F, np.zeros(m), rng=rng)
        return counts, reference, loaded

    def n_blocks(self) -> int:
        return -(-self.n // GEN_BLOCK)

    def session(self) -> CalibrationSession:
        """All samples in memory."""
        parts = [self.block(b) for b in range(self.n_blocks())]
        counts, reference, loaded = (np.concatenate([p[k] for p in parts]) for k in range(3))
        return CalibrationSession(
            counts, reference, loaded, self.T_core_ati, self.flange, self.connected_face, core=self.core,
            meta={"simulated": True, "generator": "pito_bench (VirtualCube, seed 0)", "seed": self.seed},
            counts_range=self.cube.counts_range,
        )


class _Column:
    """Array-like view of one field of a :class:`BenchData`, generated on slicing."""

    def __init__(self, gen: "_LazyGenerated", k: int, width: int, dtype):
        self.gen, self.k, self.shape, self.dtype = gen, k, (gen.data.n, width), np.dtype(dtype)

    def __getitem__(self, sl):
        if not isinstance(sl, slice):
            raise TypeError("only slices")
        start, stop, _ = sl.indices(self.shape[0])
        if stop <= start:
            return np.zeros((0, self.shape[1]), self.dtype)
        return self.gen.rows(start, stop)[self.k]


class _LazyGenerated:
    """What ``write_session`` needs from a session, generated block by block."""

    def __init__(self, data: BenchData):
        self.data = data
        self.flange, self.connected_face, self.core = data.flange, data.connected_face, data.core
        self.T_core_ati, self.time = data.T_core_ati, None
        self.counts_range = data.cube.counts_range
        self.meta = {"simulated": True, "generator": "pito_bench (VirtualCube, seed 0)", "seed": data.seed}
        self.counts = _Column(self, 0, N_GAUGES, np.int32)
        self.reference = _Column(self, 1, 6, float)
        self.loaded = _Column(self, 2, 6, bool)
        self._cache: dict[int, tuple] = {}

    def __len__(self) -> int:
        return self.data.n

    def rows(self, start: int, stop: int):
        first, last = start // GEN_BLOCK, (stop - 1) // GEN_BLOCK
        for b in list(self._cache):
            if b < first:
                del self._cache[b]
        parts = []
        for b in range(first, last + 1):
            if b not in self._cache:
                self._cache[b] = self.data.block(b)
            parts.append(self._cache[b])
        base = first * GEN_BLOCK
        return tuple(np.concatenate([p[k] for p in parts])[start - base : stop - base] for k in range(3))


def generate_session(flange: str, connected_face: int, n: int, seed: int = 0) -> CalibrationSession:
    """An in-memory simulated session of ``n`` samples (see module docstring)."""
    return BenchData(flange, connected_face, n, seed).session()


def write_session_file(path, flange: str, connected_face: int, n: int, seed: int = 0) -> None:
    """Write a simulated session of ``n`` samples to ``path`` (pito-session v1), in bounded memory."""
    write_session(path, _LazyGenerated(BenchData(flange, connected_face, n, seed)), block_size=GEN_BLOCK)

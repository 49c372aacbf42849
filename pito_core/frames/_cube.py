"""The cube's geometry: the core frame and the six face frames."""

from __future__ import annotations

import numpy as np

from ._checks import check_face

__all__ = ["CubeCore", "FACE_NORMALS", "OPPOSITE_FACE", "FACES", "DEFAULT_EDGE", "N_GAUGES", "CUBE_ADC_LIMIT"]

#: Faces in the order of every public array: face i at index i-1.
FACES = (1, 2, 3, 4, 5, 6)

#: Outward normal of each face in the core frame (docs/conventions.md, "Face frames": 1 +x, 2 +y, 3 −x, 4 −y, 5 +z, 6 −z).
FACE_NORMALS = {
    1: (1.0, 0.0, 0.0),
    2: (0.0, 1.0, 0.0),
    3: (-1.0, 0.0, 0.0),
    4: (0.0, -1.0, 0.0),
    5: (0.0, 0.0, 1.0),
    6: (0.0, 0.0, -1.0),
}

#: The face opposite each face.
OPPOSITE_FACE = {1: 3, 3: 1, 2: 4, 4: 2, 5: 6, 6: 5}

#: In-plane y axis of each face frame, in the core frame. Lateral faces (1-4) have
#: y = +z (up); the top face 5 has x = +x, y = +y; the bottom face 6 has x = +x, y = −y.
_FACE_Y = {
    1: (0.0, 0.0, 1.0),
    2: (0.0, 0.0, 1.0),
    3: (0.0, 0.0, 1.0),
    4: (0.0, 0.0, 1.0),
    5: (0.0, 1.0, 0.0),
    6: (0.0, -1.0, 0.0),
}

#: Default edge of the sensing core, m (the PITO prototype's order of size).
DEFAULT_EDGE = 0.05

#: Strain-gauge channels of the cube: face i owns columns 6(i-1) .. 6i-1 of every ``counts`` array.
N_GAUGES = 36

#: A cube sample with a gauge at or beyond ± this many counts is saturated (the boards' 24-bit ADC).
CUBE_ADC_LIMIT = 2**23 - 1


class CubeCore:
    """The sensing core: a cube of edge ``edge`` (m) centred on the core frame.

    Face i's frame has its origin at the centre of face i and its z axis along the
    outward normal (face 1 +x, 2 +y, 3 −x, 4 −y, 5 +z, 6 −z). Its y axis is the
    core's +z for the lateral faces 1-4, +y for face 5 and −y for face 6; x = y × z.

    Parameters
    ----------
    edge : float
        Edge length of the cube in m, > 0.
    """

    def __init__(self, edge: float = DEFAULT_EDGE):
        edge = float(edge)
        if not np.isfinite(edge) or edge <= 0:
            raise ValueError(f"edge: expected a positive length in m, got {edge!r}")
        self.edge = edge
        self._poses = {i: self._make_pose(i) for i in FACES}

    def _make_pose(self, i: int) -> np.ndarray:
        z = np.array(FACE_NORMALS[i])
        y = np.array(_FACE_Y[i])
        x = np.cross(y, z)
        T = np.eye(4)
        T[:3, 0], T[:3, 1], T[:3, 2] = x, y, z
        T[:3, 3] = z * self.edge / 2.0
        return T

    def face_pose(self, i) -> np.ndarray:
        """``T_core_face_i (4, 4)``: pose of face i's frame in the core frame (a copy)."""
        return self._poses[check_face(i, "i")].copy()

    def face_poses(self) -> np.ndarray:
        """``(6, 4, 4)``: ``T_core_face_i`` for faces 1..6 at indices 0..5."""
        return np.stack([self._poses[i] for i in FACES])

    def __repr__(self) -> str:
        return f"CubeCore(edge={self.edge!r})"

    def __eq__(self, other) -> bool:
        return isinstance(other, CubeCore) and other.edge == self.edge

    def __hash__(self) -> int:
        return hash(("CubeCore", self.edge))

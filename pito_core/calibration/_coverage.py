"""What a calibration measures: each face's six axes and the object's net load.

A fit maps counts to the loads its training data spanned. Load directions the data never
excited (a ``face`` flange: the net load, which its loads always balance; a ``frame``
flange: the connected face) are not calibrated: a reading with a component along them is
wrong by that component (phantom forces, ``ΣF = 0`` under the object's weight). A face
axis, or the net load, is *measured* when its reading does not depend on those
directions: its functional lies in the span of the training loads (docs/calibration.md,
"What a calibration measures").
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..defaults import FULL_SCALE_FACE
from ..frames import FACES, CubeCore, invert_pose, wrench_adjoint
from ._methods import get_method

__all__ = ["Coverage", "CompletingMount", "measured_directions", "completing_mount", "NOT_MEASURED_TEXT"]

#: What a reading shows where the calibration did not measure it.
NOT_MEASURED_TEXT = "not measured by this calibration"
#: Fraction of a functional (scaled by full scale) that may lie along unexcited loads for it to count as measured.
LEAK_RTOL = 0.05
#: Unexcited load directions: singular values of the scaled loads below this fraction of the largest
#: (the excitation threshold of the fit).
WEAK_RTOL = 1e-3
_FS = np.tile(np.asarray(FULL_SCALE_FACE, dtype=float), 6)  # (36,) N, N·m


@dataclass(frozen=True)
class Coverage:
    """Which readings a calibration measures.

    Attributes
    ----------
    faces : ndarray of bool, shape (6, 6)
        ``faces[i-1, a]``: axis ``a`` of ``[fx, fy, fz, tx, ty, tz]`` on face i is measured.
    net_load : bool
        The object's net load (the sum of the six face wrenches, ‖ΣF‖, ΣT) is measured.
    known : bool
        False for files written before pito recorded it (derived from their ``net_load`` note).
    """

    faces: np.ndarray
    net_load: bool
    known: bool = True

    def __post_init__(self):
        f = np.asarray(self.faces, dtype=bool)
        if f.shape != (6, 6):
            raise ValueError(f"faces: expected shape (6, 6), got {f.shape}")
        object.__setattr__(self, "faces", f)

    @property
    def complete(self) -> bool:
        """Every face axis and the net load are measured."""
        return bool(self.faces.all() and self.net_load)

    @property
    def face_measured(self) -> np.ndarray:
        """(6,) bool: every axis of face i is measured."""
        return self.faces.all(axis=1)

    def describe(self) -> str:
        """One line for an operator: what is not measured (or that everything is)."""
        if self.complete:
            return "measures every face and the net load"
        missing = [str(i) for i in FACES if not self.face_measured[i - 1]]
        parts = []
        if missing:
            parts.append(f"face{'s' if len(missing) > 1 else ''} {', '.join(missing)}")
        if not self.net_load:
            parts.append("the net load (‖ΣF‖, ΣT)")
        return "partial: " + " and ".join(parts) + f" {NOT_MEASURED_TEXT}"

    def to_meta(self) -> dict:
        """JSON form for ``Calibration.meta["coverage"]``."""
        return {"faces": self.faces.astype(int).tolist(), "net_load": bool(self.net_load)}

    @classmethod
    def from_meta(cls, meta: dict, has_output) -> "Coverage":
        """The coverage recorded in ``meta``, or derived for older files (see :attr:`known`)."""
        rec = meta.get("coverage")
        if isinstance(rec, dict) and "faces" in rec:
            return cls(np.asarray(rec["faces"], dtype=bool) & np.asarray(has_output, bool)[:, None],
                       bool(rec.get("net_load", False)))
        faces = np.repeat(np.asarray(has_output, dtype=bool)[:, None], 6, axis=1)
        net = meta.get("net_load") == "measured"
        if not net and meta.get("flanges") == ["face"] and get_method(meta.get("method", "total")).inputs == "all":
            faces[:] = False  # the unexcited net-load directions reach every face of a joint fit
        return cls(faces, bool(net and faces.all()), known=False)

    def mask(self, wrenches) -> np.ndarray:
        """``wrenches (..., 6, 6)`` with NaN on the axes not measured (a copy)."""
        W = np.array(wrenches, dtype=float)
        W[..., ~self.faces] = np.nan
        return W


def _net_rows(output_frame: str, core: CubeCore) -> np.ndarray:
    """(6, 36): the net load (in a common frame) from the 6 faces' wrenches in the output frame."""
    if output_frame == "reference":
        return np.tile(np.eye(6), 6)  # every face's output is already in S_A
    return np.hstack([wrench_adjoint(invert_pose(core.face_pose(f))) for f in FACES])  # face → core frame


def measured_directions(gram, output_faces, output_frame: str, core: CubeCore) -> Coverage:
    """The :class:`Coverage` of a fit from the Gram matrix of its training loads.

    Parameters
    ----------
    gram : ndarray, shape (36, 36)
        ``Σ t tᵀ`` of the target wrenches of all six faces (usable samples), each divided
        by full scale (15 N, 0.1 N·m): ``t[6(i-1) + a]`` is axis a of face i.
    output_faces : sequence of int
        Faces the calibration outputs.
    output_frame : {"face", "reference"}
        Frame of the targets.
    core : CubeCore

    Returns
    -------
    Coverage
        A face axis (or the net load) is measured when at most :data:`LEAK_RTOL` of its
        functional (scaled) lies along the unexcited loads, and the face has output.
    """
    G = 0.5 * (np.asarray(gram, dtype=float) + np.asarray(gram, dtype=float).T)
    w, V = np.linalg.eigh(G)
    weak = np.sqrt(np.clip(w, 0, None) / w[-1]) < WEAK_RTOL if w[-1] > 0 else np.ones(36, bool)
    Vw = V[:, weak]

    def leak(rows):  # fraction of each scaled functional along the unexcited loads
        r = rows * _FS
        return np.linalg.norm(r @ Vw, axis=1) / np.linalg.norm(r, axis=1)

    out = np.zeros(6, dtype=bool)
    out[[f - 1 for f in output_faces]] = True
    faces = (leak(np.eye(36)) <= LEAK_RTOL).reshape(6, 6) & out[:, None]
    net = bool(out.all() and np.all(leak(_net_rows(output_frame, core)) <= LEAK_RTOL))
    return Coverage(faces, net)


@dataclass(frozen=True)
class CompletingMount:
    """The extra session a method's main mount needs to measure every reading.

    Attributes
    ----------
    flange : str
        Its flange.
    connected_face : int
        The face towards the flange.
    faces : tuple of int
        Faces loaded one at a time in it.
    why : str
        The reason, in one line for the operator.
    """

    flange: str
    connected_face: int
    faces: tuple
    why: str


def completing_mount(method, flange: str, connected_face: int) -> CompletingMount | None:
    """The extra mount that completes ``method`` on ``flange`` at ``connected_face`` (None if complete).

    A ``face`` flange whose protocol does not load the connected face (``unloaded_frame``)
    never excites the net load nor loads that face directly; a ``frame`` flange never loads
    the connected face. A short ``frame_hole`` session on the same face, that face loaded
    through the access hole, excites both (docs/calibration.md, step 5).
    """
    spec = get_method(method)
    c = int(connected_face)
    if flange == "face" and not spec.load_connected:
        return CompletingMount("frame_hole", c, (c,), (
            f"The face flange never loads face {c} directly nor the object's net load (its loads always balance): "
            f"a short session on the type-2 flange, face {c} loaded through the hole, measures both."))
    if flange == "frame" and spec.name in ("quasi_total", "face_to_face"):
        out = "gives face " + str(c) + " its own output" if spec.name == "face_to_face" else \
            "keeps a load on it out of the other faces' readings"
        return CompletingMount("frame_hole", c, (c,), (
            f"The frame flange never loads face {c}: a short session on the type-2 flange, face {c} loaded "
            f"through the hole, {out}."))
    return None

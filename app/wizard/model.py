"""The calibration wizard's model: choices, tare, captures per face, result (Qt signals, no widgets)."""

from __future__ import annotations

import numpy as np
from PySide6.QtCore import QObject, Signal

from pito_core.calibration import METHODS, CalibrationSession, get_method
from pito_core.frames import FACES, CubeCore, invert_pose

from .capture import CaptureRules, FaceCaptures

__all__ = ["WizardModel", "faces_to_load", "RECOMMENDED_METHOD", "RECOMMENDED_WHY"]

#: The wizard's default: the method the PITO paper recommends (III-B).
RECOMMENDED_METHOD = "unloaded_frame"
#: One line for the operator: why it is the default.
RECOMMENDED_WHY = ("Recommended (PITO paper, III-B): every face from all 36 gauges, so the coupling between faces is "
                   "calibrated (face_to_face ignores it and is the worst under coupling), outputs in face frames, "
                   "no access hole needed.")


def faces_to_load(method: str, flange: str, connected_face: int) -> tuple[int, ...]:
    """Faces the operator loads, one at a time, for ``method`` on ``flange`` at ``connected_face``.

    ``frame`` (type 1): the connected face cannot be loaded. ``frame_hole`` (type 2): all six,
    the connected one through the hole. ``face`` (type 3): the five free faces, plus the
    connected face itself when the method loads it directly.
    """
    spec = get_method(method)
    free = tuple(i for i in FACES if i != connected_face)
    if flange == "frame_hole":
        return FACES
    if flange == "face" and spec.load_connected:
        return FACES
    return free


class WizardModel(QObject):
    """State of one guided calibration.

    Signals: ``mount_changed`` (method, flange, connected face), ``face_changed`` (the face
    being loaded), ``captures_changed`` (face), ``tare_changed``, ``result_changed``.
    """

    mount_changed = Signal()
    face_changed = Signal(int)
    captures_changed = Signal(int)
    tare_changed = Signal()
    result_changed = Signal()

    def __init__(self, core: CubeCore | None = None, rules: CaptureRules | None = None, parent=None):
        super().__init__(parent)
        self.core = core or CubeCore()
        self.rules = rules or CaptureRules()
        # the PITO paper's recommended method (see RECOMMENDED_WHY in the method page)
        self.method = RECOMMENDED_METHOD
        self.flange = "face"
        self.connected_face = 6
        self.T_core_ati = np.eye(4)
        self.simulated = False
        self.current_face = 1
        self.captures: dict[int, FaceCaptures] = {}
        self.tare_counts = np.zeros((0, 36))
        self.tare_reference = np.zeros((0, 6))
        self.tare_still = False
        self.calibration = None
        self.evaluation = None
        self.accepted = False
        self.saved_path = None
        self._reset_captures()

    # ------------------------------------------------------------ choices
    def set_mount(self, method: str | None = None, flange: str | None = None, connected_face: int | None = None) -> None:
        if method is not None:
            spec = get_method(method)
            self.method = spec.name
            if self.flange not in spec.flanges:
                self.flange = spec.flanges[0] if "frame_hole" not in spec.flanges else "frame_hole"
        if flange is not None:
            if flange not in get_method(self.method).flanges:
                raise ValueError(f"flange: method '{self.method}' needs one of {get_method(self.method).flanges}, got {flange!r}")
            self.flange = flange
        if connected_face is not None:
            self.connected_face = int(connected_face)
        self._reset_captures()
        self.mount_changed.emit()

    @property
    def spec(self):
        return METHODS[self.method]

    @property
    def faces(self) -> tuple[int, ...]:
        return faces_to_load(self.method, self.flange, self.connected_face)

    def _reset_captures(self) -> None:
        self.captures = {i: FaceCaptures(i, self.rules) for i in self.faces}
        self.current_face = self.faces[0]
        self.calibration = None
        self.evaluation = None
        self.accepted = False

    def set_current_face(self, face: int) -> None:
        if face not in self.captures:
            raise ValueError(f"face: expected one of {self.faces}, got {face!r}")
        self.current_face = int(face)
        self.face_changed.emit(self.current_face)

    def set_k(self, k: int) -> None:
        self.rules.k = int(k)
        for c in self.captures.values():
            c.rules = self.rules

    # ------------------------------------------------------------ geometry
    def T_ati_face(self, face: int) -> np.ndarray:
        """``T_ati_face`` (4, 4): face ``face``'s frame in the reference frame."""
        return invert_pose(self.T_core_ati) @ self.core.face_pose(face)

    # ------------------------------------------------------------ data
    def set_tare(self, counts, reference, still: bool) -> None:
        self.tare_counts = np.asarray(counts, dtype=float)
        self.tare_reference = np.asarray(reference, dtype=float)
        self.tare_still = bool(still)
        self.tare_changed.emit()

    @property
    def has_tare(self) -> bool:
        return self.tare_counts.shape[0] > 0 and self.tare_still

    def face_done(self, face: int) -> bool:
        return self.captures[face].sufficient

    @property
    def all_faces_done(self) -> bool:
        return all(c.sufficient for c in self.captures.values())

    def clear_face(self, face: int) -> None:
        self.captures[face].clear()
        self.calibration = None
        self.evaluation = None
        self.accepted = False
        self.captures_changed.emit(face)

    def session(self) -> CalibrationSession:
        """All kept samples as one :class:`CalibrationSession`: the tare (unloaded), then each face's captures."""
        counts = [self.tare_counts]
        reference = [self.tare_reference]
        loaded = [np.zeros((self.tare_counts.shape[0], 6), dtype=bool)]
        times = [np.zeros(self.tare_counts.shape[0])]
        for face, fc in self.captures.items():
            for c in fc.captures:
                counts.append(c.counts)
                reference.append(c.reference)
                m = np.zeros((c.counts.shape[0], 6), dtype=bool)
                m[:, face - 1] = True
                loaded.append(m)
                times.append(c.time)
        return CalibrationSession(
            np.concatenate(counts), np.concatenate(reference), np.concatenate(loaded), self.T_core_ati,
            self.flange, self.connected_face, core=self.core, time=np.concatenate(times),
            meta={"simulated": self.simulated, "source": "pito-app calibration wizard", "method": self.method},
        )

    def set_result(self, calibration, evaluation) -> None:
        self.calibration = calibration
        self.evaluation = evaluation
        self.accepted = False
        self.result_changed.emit()


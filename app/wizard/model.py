"""The calibration wizard's model: choices, tare, captures per face, result (Qt signals, no widgets)."""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from PySide6.QtCore import QObject, Signal

from pito_core.calibration import METHODS, CalibrationSession, completing_mount, get_method, session_from_arrays
from pito_core.frames import FACES, CubeCore, invert_pose

from pito_core.devices import CaptureRules, FaceCaptures

__all__ = ["WizardModel", "Stage", "faces_to_load", "validation_rules", "RECOMMENDED_METHOD", "RECOMMENDED_WHY",
           "VALIDATION_WHY", "completing_validation_why"]

#: The wizard's default: the method the PITO paper recommends (III-B).
RECOMMENDED_METHOD = "unloaded_frame"
#: One line for the operator: why it is the default.
RECOMMENDED_WHY = ("Recommended (PITO paper, III-B): every face from all 36 gauges, so the coupling between faces is "
                   "calibrated (face_to_face ignores it and is the worst under coupling), outputs in face frames; "
                   "a short second mount on the type-2 flange then measures the connected face and the net load.")


#: One line for the operator: why the wizard ends with a validation pass.
VALIDATION_WHY = ("Validation: load each face again with fresh loads. They are not used in the fit: the results "
                  "headline these figures, which is what a new session will show.")


def completing_validation_why(faces) -> str:
    """One line for the operator: the second mount's validation pass (fresh loads on ``faces``)."""
    names = ", ".join(map(str, faces))
    return (f"Validation of the second mount: load face {names} again through the hole with fresh loads. They are not "
            f"used in the fit: face {names}'s figures on the results page come from them.")


def validation_rules(rules: CaptureRules) -> CaptureRules:
    """The capture rules of the validation pass: a quarter of the samples, fewer distinct loads."""
    return replace(rules, k=max(100, rules.k // 4), min_captures=max(6, rules.min_captures // 2))


@dataclass
class Stage:
    """One pass of the wizard on one mount: its tare and its captures per face.

    ``kind``: ``main`` (the method's mount), ``completing`` (the extra mount that measures the
    rest; ``why`` says why) or ``validation`` (fresh loads, not fitted, on the mount of the stage
    of kind ``of``: ``main`` or ``completing``; it uses that stage's tare).
    """

    kind: str
    flange: str
    connected_face: int
    faces: tuple
    rules: CaptureRules
    why: str = ""
    T_core_ati: np.ndarray = field(default_factory=lambda: np.eye(4))
    captures: dict = field(default_factory=dict)
    of: str = ""
    tare_counts: np.ndarray = field(default_factory=lambda: np.zeros((0, 36)))
    tare_reference: np.ndarray = field(default_factory=lambda: np.zeros((0, 6)))
    tare_still: bool = False

    def __post_init__(self):
        self.captures = {i: FaceCaptures(i, self.rules) for i in self.faces}

    @property
    def done(self) -> bool:
        return all(c.sufficient for c in self.captures.values())


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
    """State of one guided calibration: its stages (mounts and passes), tare and captures per face.

    The stages are the method's mount (``main``), a validation pass of fresh loads on it, and,
    where the method's mount leaves readings unmeasured, the extra mount that measures them
    (:func:`pito_core.calibration.completing_mount`). ``flange``, ``connected_face``, ``faces``,
    ``captures``, ``rules`` and the tare are those of the current stage.

    Signals: ``mount_changed`` (method, flange, connected face, or stage), ``face_changed`` (the
    face being loaded), ``captures_changed`` (face), ``tare_changed``, ``result_changed``.
    """

    mount_changed = Signal()
    face_changed = Signal(int)
    captures_changed = Signal(int)
    tare_changed = Signal()
    result_changed = Signal()

    def __init__(self, core: CubeCore | None = None, rules: CaptureRules | None = None, parent=None):
        super().__init__(parent)
        self.core = core or CubeCore()
        self.base_rules = rules or CaptureRules()
        # the PITO paper's recommended method (see RECOMMENDED_WHY in the method page)
        self.method = RECOMMENDED_METHOD
        self.main_flange = "face"
        self.main_connected_face = 6
        self.simulated = False
        self.current_face = 1
        self.stages: list[Stage] = []
        self.stage = 0
        self.calibration = None
        self.evaluation = None  # the headline: the validation pass (else the held-out split)
        self.heldout = None  # the secondary figure: held-out samples of the fitted captures
        self.accepted = False
        self.saved_path = None
        self._reset_captures()

    # ------------------------------------------------------------ choices
    def set_mount(self, method: str | None = None, flange: str | None = None, connected_face: int | None = None) -> None:
        if method is not None:
            spec = get_method(method)
            self.method = spec.name
            if self.main_flange not in spec.flanges:
                self.main_flange = spec.flanges[0] if "frame_hole" not in spec.flanges else "frame_hole"
        if flange is not None:
            if flange not in get_method(self.method).flanges:
                raise ValueError(f"flange: method '{self.method}' needs one of {get_method(self.method).flanges}, got {flange!r}")
            self.main_flange = flange
        if connected_face is not None:
            self.main_connected_face = int(connected_face)
        self._reset_captures()
        self.mount_changed.emit()

    @property
    def spec(self):
        return METHODS[self.method]

    @property
    def current(self) -> Stage:
        """The stage being run."""
        return self.stages[self.stage]

    @property
    def completing(self):
        """The extra mount this method needs (``CompletingMount``), or None."""
        return completing_mount(self.method, self.main_flange, self.main_connected_face)

    # the current stage's mount and data (the pages read these)
    flange = property(lambda self: self.current.flange)
    connected_face = property(lambda self: self.current.connected_face)
    faces = property(lambda self: self.current.faces)
    captures = property(lambda self: self.current.captures)
    rules = property(lambda self: self.current.rules)
    tare_counts = property(lambda self: self.current.tare_counts)
    tare_reference = property(lambda self: self.current.tare_reference)
    tare_still = property(lambda self: self.current.tare_still)

    @property
    def T_core_ati(self) -> np.ndarray:
        return self.current.T_core_ati

    @T_core_ati.setter
    def T_core_ati(self, value) -> None:
        self.current.T_core_ati = np.asarray(value, dtype=float)
        for st in self.stages:  # a validation pass runs on the mount it validates
            if st.kind == "validation" and st.of == self.current.kind:
                st.T_core_ati = self.current.T_core_ati

    def _reset_captures(self) -> None:
        flange, c = self.main_flange, self.main_connected_face
        faces = faces_to_load(self.method, flange, c)
        old_T = self.stages[0].T_core_ati if self.stages else np.eye(4)
        self.stages = [Stage("main", flange, c, faces, self.base_rules, T_core_ati=old_T),
                       Stage("validation", flange, c, faces, validation_rules(self.base_rules), VALIDATION_WHY,
                             T_core_ati=old_T, of="main")]
        extra = self.completing
        if extra is not None:  # the second mount, and fresh loads on it: every face gets a validation figure
            self.stages.append(Stage("completing", extra.flange, extra.connected_face, extra.faces, self.base_rules,
                                     extra.why))
            self.stages.append(Stage("validation", extra.flange, extra.connected_face, extra.faces,
                                     validation_rules(self.base_rules), completing_validation_why(extra.faces),
                                     of="completing"))
        self.stage = 0
        self.current_face = self.faces[0]
        self.calibration = None
        self.evaluation = None
        self.heldout = None
        self.accepted = False

    def set_stage(self, index: int) -> None:
        """Run stage ``index`` (its mount, tare and captures; what was kept in the others stays)."""
        if not 0 <= int(index) < len(self.stages):
            raise ValueError(f"index: expected a stage 0..{len(self.stages) - 1}, got {index!r}")
        self.stage = int(index)
        self.current_face = self.faces[0]
        self.mount_changed.emit()
        self.face_changed.emit(self.current_face)

    def skip_completing(self) -> None:
        """Leave the second mount out: the calibration will not measure what it would have (and says so)."""
        self.stages = [st for st in self.stages if "completing" not in (st.kind, st.of)]
        self.set_stage(len(self.stages) - 1)

    def set_current_face(self, face: int) -> None:
        if face not in self.captures:
            raise ValueError(f"face: expected one of {self.faces}, got {face!r}")
        self.current_face = int(face)
        self.face_changed.emit(self.current_face)

    def set_k(self, k: int) -> None:
        self.base_rules.k = int(k)
        self._sync_validation_rules()

    def _sync_validation_rules(self) -> None:
        for st in self.stages:
            if st.kind == "validation":
                st.rules = validation_rules(self.base_rules)
                for c in st.captures.values():
                    c.rules = st.rules

    # ------------------------------------------------------------ geometry
    def T_ati_face(self, face: int) -> np.ndarray:
        """``T_ati_face`` (4, 4): face ``face``'s frame in the reference frame of the current mount."""
        return invert_pose(self.T_core_ati) @ self.core.face_pose(face)

    # ------------------------------------------------------------ data
    def set_tare(self, counts, reference, still: bool) -> None:
        st = self.current
        st.tare_counts = np.asarray(counts, dtype=float)
        st.tare_reference = np.asarray(reference, dtype=float)
        st.tare_still = bool(still)
        self.tare_changed.emit()

    def _tare_stage(self, stage: Stage) -> Stage:
        """The stage whose tare ``stage`` uses (a validation pass: that of the mount it validates)."""
        return next(st for st in self.stages if st.kind == stage.of) if stage.kind == "validation" else stage

    @property
    def stage_tare_counts(self) -> np.ndarray:
        """``(n, 36)`` the counts at rest the current stage is tared with (a validation pass: its mount's)."""
        return self._tare_stage(self.current).tare_counts

    @property
    def has_tare(self) -> bool:
        st = self._tare_stage(self.current)
        return st.tare_counts.shape[0] > 0 and st.tare_still

    def face_done(self, face: int) -> bool:
        return self.captures[face].sufficient

    @property
    def all_faces_done(self) -> bool:
        return self.current.done

    @property
    def all_stages_done(self) -> bool:
        return all(st.done for st in self.stages)

    def clear_face(self, face: int) -> None:
        self.captures[face].clear()
        self.calibration = None
        self.evaluation = None
        self.heldout = None
        self.accepted = False
        self.captures_changed.emit(face)

    def stage_session(self, stage: Stage) -> CalibrationSession:
        """One stage's kept samples as a :class:`CalibrationSession`: its tare (unloaded), then each face's captures."""
        tare = self._tare_stage(stage)
        parts = [(tare.tare_counts, tare.tare_reference, np.zeros(tare.tare_counts.shape[0]), 0)]
        for face, fc in stage.captures.items():
            parts += [(c.counts, c.reference, c.time, face) for c in fc.captures]
        return session_from_parts(parts, stage.T_core_ati, stage.flange, stage.connected_face, self.core, meta={
            "simulated": self.simulated, "source": "pito-app calibration wizard", "method": self.method,
            "stage": stage.kind})

    def session(self) -> CalibrationSession:
        """The main mount's kept samples (the fit's main session)."""
        return self.stage_session(self.stages[0])

    def training_sessions(self) -> list:
        """Sessions the fit uses: the main mount's and the completing mount's (never the validation pass)."""
        return [self.stage_session(st) for st in self.stages if st.kind != "validation"]

    def validation_session(self) -> CalibrationSession | None:
        """The main mount's validation pass (fresh loads, not fitted), or None if it has no capture."""
        st = next((s for s in self.stages if s.kind == "validation" and s.of == "main"), None)
        if st is None or not any(fc.captures for fc in st.captures.values()):
            return None
        return self.stage_session(st)

    def validation_sessions(self) -> list:
        """Every validation pass with captures (the main mount's, then the second mount's): fresh loads, not fitted."""
        return [self.stage_session(st) for st in self.stages
                if st.kind == "validation" and any(fc.captures for fc in st.captures.values())]

    def set_result(self, calibration, evaluation, heldout=None) -> None:
        """A new fit (or none): not accepted, and not saved — a file saved before holds another calibration."""
        self.calibration = calibration
        self.evaluation = evaluation
        self.heldout = heldout
        self.accepted = False
        self.saved_path = None
        self.result_changed.emit()


def session_from_parts(parts, T_core_ati, flange, connected_face, core, meta) -> CalibrationSession:
    """A session from ``[(counts (n, 36), reference (n, 6), time (n,), loaded face or 0), ...]``.

    Samples at or beyond the cube's ADC range are dropped (the one saturation rule of
    :func:`pito_core.calibration.session_from_arrays`).
    """
    counts = np.concatenate([p[0] for p in parts])
    reference = np.concatenate([p[1] for p in parts])
    time = np.concatenate([p[2] for p in parts])
    loaded = np.zeros((counts.shape[0], 6), dtype=bool)
    k = 0
    for c, _, _, face in parts:
        if face:
            loaded[k:k + c.shape[0], face - 1] = True
        k += c.shape[0]
    return session_from_arrays(counts, reference, loaded, time, T_core_ati=T_core_ati, flange=flange,
                               connected_face=connected_face, core=core, meta=meta)

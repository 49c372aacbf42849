"""Step 5: loading, face by face — coverage, samples toward k, condition number, undo."""

from __future__ import annotations

import time

import numpy as np
from PySide6.QtWidgets import (
    QGridLayout, QHBoxLayout, QLabel, QProgressBar, QPushButton, QVBoxLayout,
)

from pito_core.frames import FACES, transform_wrench

from ..scene import ACTIVE_COLOR, CONNECTED_COLOR, CubeScene
from ..widgets.coverage import CoverageBars, CoverageModel, FULL_SCALE
from .page import WizardPage

__all__ = ["LoadPage"]


class LoadPage(WizardPage):
    title = "5 · Load each face"
    help = ("Press on the green face with the probe in every direction — push, pull sideways, twist — and hold "
            "each load still for a moment. Still, new loads are kept automatically; the bars show how far each "
            "axis has been loaded against full scale.")

    #: called with the face being loaded when it changes (the demo's simulated operator)
    operator = None

    def __init__(self, model, parent=None):
        super().__init__(model, parent)
        row = QHBoxLayout()
        left = QVBoxLayout()
        self.scene = CubeScene(model.core)
        self.scene.setMinimumSize(460, 380)
        self.scene.glyphs.force_scale = 0.004
        left.addWidget(self.scene, 1)
        chips = QHBoxLayout()
        self.chips = {}
        for i in FACES:
            b = QPushButton(f"face {i}")
            b.setCheckable(True)
            b.setObjectName("faceChip")
            b.clicked.connect(lambda _=False, f=i: self.model.set_current_face(f))
            chips.addWidget(b)
            self.chips[i] = b
        left.addLayout(chips)
        row.addLayout(left, 5)

        right = QVBoxLayout()
        self.face_title = QLabel()
        self.face_title.setObjectName("bigFace")
        right.addWidget(self.face_title)
        self.coverage_model = CoverageModel(model.rules.required)
        right.addWidget(QLabel("Coverage per axis and sign (kept loads, against full scale; white = live load)"))
        self.bars = CoverageBars(self.coverage_model)
        right.addWidget(self.bars, 1)
        grid = QGridLayout()
        self.samples = QProgressBar()
        self.samples.setFormat("%v / %m samples")
        self.kappa = QLabel("—")
        self.kappa.setObjectName("value")
        self.captures = QLabel("0")
        self.captures.setObjectName("value")
        self.state = QLabel("—")
        self.state.setObjectName("state")
        grid.addWidget(QLabel("Samples toward k"), 0, 0)
        grid.addWidget(self.samples, 0, 1)
        grid.addWidget(QLabel("Condition number of the kept loads κ"), 1, 0)
        grid.addWidget(self.kappa, 1, 1)
        grid.addWidget(QLabel("Captures kept"), 2, 0)
        grid.addWidget(self.captures, 2, 1)
        grid.addWidget(QLabel("Live"), 3, 0)
        grid.addWidget(self.state, 3, 1)
        right.addLayout(grid)
        buttons = QHBoxLayout()
        self.undo = QPushButton("Undo last capture")
        self.next_face = QPushButton("Next face ▸")
        self.next_face.setObjectName("primary")
        buttons.addWidget(self.undo)
        buttons.addStretch(1)
        buttons.addWidget(self.next_face)
        right.addLayout(buttons)
        row.addLayout(right, 4)
        self.body.addLayout(row, 1)

        self._dirty = 0
        self._face_since = -np.inf
        self.settle = 0.3  # s after a change of face before samples count for the new face
        self.undo.clicked.connect(self.undo_last)
        self.next_face.clicked.connect(self.goto_next_face)
        model.face_changed.connect(self._on_face)
        model.mount_changed.connect(self._on_mount)
        model.captures_changed.connect(lambda f: self.refresh())
        self._on_mount()

    # ------------------------------------------------------------ model → view
    def _on_mount(self) -> None:
        m = self.model
        self.scene.set_mount(m.flange, m.connected_face)
        for i, b in self.chips.items():
            b.setVisible(i in m.faces)
        self._on_face(m.current_face)

    def _on_face(self, face: int) -> None:
        m = self.model
        for fc in m.captures.values():
            fc.close()
        # samples taken before this moment belong to the previous face (they may still be in
        # flight): the new face's captures start with samples newer than the switch
        self._face_since = time.monotonic() + self.settle
        colors = {m.connected_face: CONNECTED_COLOR, face: ACTIVE_COLOR}
        self.scene.set_face_colors(colors)
        self.scene.look_at_mount(m.connected_face, face)
        self.face_title.setText(f"Load face {face}")
        if self.operator is not None and self.isVisible():
            self.operator(face)
        self.refresh()

    def refresh(self) -> None:
        m = self.model
        fc = m.captures[m.current_face]
        for i, b in self.chips.items():
            b.blockSignals(True)
            b.setChecked(i == m.current_face)
            b.blockSignals(False)
            if i in m.captures:
                b.setText(f"face {i} ✔" if m.captures[i].sufficient else f"face {i}")
        self.coverage_model.required = m.rules.required
        self.coverage_model.set_state(fc.coverage(), self.coverage_model.current)
        self.samples.setMaximum(m.rules.k)
        self.samples.setValue(min(fc.n_samples, m.rules.k))
        kappa = fc.condition_number()
        limit = m.rules.max_condition
        self.kappa.setText("— (load more directions)" if not np.isfinite(kappa)
                           else f"{kappa:.1f}  " + ("✔" if kappa <= limit else f"(needs ≤ {limit:g}: vary the loads)"))
        self.captures.setText(f"{len(fc.captures)} / {m.rules.min_captures} distinct still loads"
                              + (" ✔" if len(fc.captures) >= m.rules.min_captures else ""))
        self.undo.setEnabled(bool(fc.captures))
        done = fc.sufficient
        remaining = [f for f in m.faces if not m.captures[f].sufficient]
        self.next_face.setEnabled(done and bool(remaining) and remaining != [m.current_face])
        self.set_ready(m.all_faces_done)

    # ------------------------------------------------------------ actions
    def enter(self) -> None:
        self._on_face(self.model.current_face)
        if self.operator is not None:
            self.operator(self.model.current_face)

    def leave(self) -> None:
        if self.operator is not None:
            self.operator(None)

    def undo_last(self) -> None:
        fc = self.model.captures[self.model.current_face]
        if fc.undo():
            self.state.setText("last capture removed")
            self.model.captures_changed.emit(self.model.current_face)

    def goto_next_face(self) -> None:
        m = self.model
        faces = list(m.faces)
        k = faces.index(m.current_face)
        for f in faces[k + 1:] + faces[:k]:
            if not m.captures[f].sufficient:
                m.set_current_face(f)
                return

    # ------------------------------------------------------------ live data
    def face_wrench(self, reference) -> np.ndarray:
        """The reference load ``(n, 6)`` expressed on the face being loaded (face frame, N and N·m)."""
        return transform_wrench(reference, self.model.T_ati_face(self.model.current_face))

    def on_bundle(self, b) -> None:
        if b.time.size == 0:
            return
        m = self.model
        face = m.current_face
        fc = m.captures[face]
        good = np.isfinite(b.reference).all(axis=1) & (b.time >= self._face_since)
        if not good.any():
            return
        Wf = self.face_wrench(b.reference[good])
        live = Wf[-min(20, Wf.shape[0]):].mean(axis=0)
        self.coverage_model.set_current(live / FULL_SCALE)
        self._show_live_force(face, live)
        event = fc.feed(b.time[good], b.counts[good], b.reference[good], Wf)
        texts = {
            "waiting": "…",
            "moving": "moving — hold the load still",
            "no load": "no load — press on the face",
            "not new": "already kept — try another direction",
            "kept": f"✔ kept capture {len(fc.captures)}",
            "growing": f"✔ holding — capture {len(fc.captures)} growing",
        }
        self.state.setText(texts[event])
        if event in ("kept", "growing"):
            self._dirty += 1
            if event == "kept" or self._dirty >= 10:  # refresh the numbers a few times a second
                self._dirty = 0
                m.captures_changed.emit(face)

    def _show_live_force(self, face: int, wrench_face) -> None:
        """The live load as an arrow pushing on the face centre (core frame)."""
        T = self.model.core.face_pose(face)
        pts = np.full((6, 3), np.nan)
        normals = np.zeros((6, 3))
        forces = np.zeros((6, 3))
        valid = np.zeros(6, dtype=bool)
        k = face - 1
        pts[k] = T[:3, 3]
        normals[k] = T[:3, 2]
        forces[k] = T[:3, :3] @ wrench_face[:3]
        valid[k] = True
        tors = np.zeros(6)
        tors[k] = wrench_face[5]
        self.scene.glyphs.update(pts, normals, forces, tors, valid)
        self.scene.redraw()

"""Step 5: loading, face by face — coverage, samples toward k, condition number, undo."""

from __future__ import annotations

import time

import numpy as np
from PySide6.QtWidgets import (
    QGridLayout, QHBoxLayout, QLabel, QProgressBar, QPushButton, QVBoxLayout,
)

from pito_core.contact import ContactEstimate
from pito_core.devices import on_face
from pito_core.frames import FACES, transform_wrench

from ..scene import ACTIVE_COLOR, CONNECTED_COLOR, CubeScene
from ..widgets.coverage import AXIS_LABELS, CoverageBars, CoverageModel, FULL_SCALE
from .page import WizardPage

__all__ = ["LoadPage", "face_gates", "samples_text", "SAMPLES_TIP"]

#: why a face keeps more than k samples (the Samples row's tooltip)
SAMPLES_TIP = ("k (the method page) is the least number of samples a face needs. Every sample of a kept still load "
               "counts (1000 a second), and a face is done only when its coverage, distinct loads and condition "
               "number pass too, so a face usually ends with more than k; the fit uses all of them.")


def samples_text(n: int, k: int) -> str:
    """The Samples row: ``n`` kept against the least ``k`` (e.g. ``71 303 (≥ 1 000 ✔)``)."""
    def fmt(v):
        return f"{v:,}".replace(",", " ")
    return f"{fmt(n)} (≥ {fmt(k)} {'✔' if n >= k else 'needed'})"


def face_gates(fc) -> list[tuple[float, str]]:
    """What decides that a face is done (:attr:`FaceCaptures.sufficient`), as ``(fraction done
    0..1, what it waits on)`` per gate: conditioning, distinct still loads, coverage, samples."""
    r = fc.rules
    kappa = fc.condition_number()
    cov = fc.coverage()
    return [
        (0.0 if not np.isfinite(kappa) else min(1.0, r.max_condition / kappa),
         "κ " + ("∞" if not np.isfinite(kappa) else f"{kappa:.0f}") + f" → ≤ {r.max_condition:g}"),
        (min(1.0, len(fc.captures) / r.min_captures), f"still loads {len(fc.captures)} → {r.min_captures}"),
        (min(1.0, float(cov.min()) / r.required) if r.required > 0 else 1.0,
         f"coverage {cov.min():.2f} → {r.required:.2f}"),
        (min(1.0, fc.n_samples / r.k), f"samples {fc.n_samples:,} → at least {r.k:,}".replace(",", " ")),
    ]


class LoadPage(WizardPage):
    """Wizard step 5: load each free face in turn; still loads are kept as calibration samples.

    Coverage per axis and sign is the largest fraction of full scale reached
    (``pito_core.defaults.FULL_SCALE_FACE``: ±15 N, ±0.1 N·m, face frame ``[fx, fy, fz, tx, ty, tz]``).

    Parameters
    ----------
    model : app.wizard.model.WizardModel
        The wizard's state (method, mount, captures); the page reads and sets it.
    parent : QWidget, optional
    """
    title = "5 · Load each face"
    help = ("Press on the green face with the probe in every direction — push, pull sideways, twist — and hold "
            "each load still for a moment. Still, new loads are kept automatically; the bars show how far each "
            "axis has been loaded against full scale.")

    #: called with the face being loaded when it changes (the demo's simulated operator)
    operator = None

    def __init__(self, model, parent=None):
        super().__init__(model, parent)
        row = QHBoxLayout()
        row.addLayout(self._scene_column(model), 5)
        row.addLayout(self._status_column(model), 4)
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

    def _scene_column(self, model) -> QVBoxLayout:
        """The cube scene and a chip per face (a click makes it the current face)."""
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
        return left

    def _status_column(self, model) -> QVBoxLayout:
        """The stage note, face title, coverage bars, the gates' figures and the Undo / Next buttons."""
        right = QVBoxLayout()
        self.stage_note = QLabel()  # the validation pass or the second mount: what it is for, in one line
        self.stage_note.setObjectName("emphasis")
        self.stage_note.setWordWrap(True)
        right.addWidget(self.stage_note)
        self.face_title = QLabel()
        self.face_title.setObjectName("bigFace")
        right.addWidget(self.face_title)
        self.coverage_model = CoverageModel(model.rules.required)
        right.addWidget(QLabel("Coverage per axis and sign (kept loads against full scale)"))
        self.bars = CoverageBars(self.coverage_model)
        right.addWidget(self.bars, 1)
        right.addLayout(self._gates_grid())
        buttons = QHBoxLayout()
        self.undo = QPushButton("Undo last capture")
        self.next_face = QPushButton("Next face ▸")
        self.next_face.setObjectName("primary")
        buttons.addWidget(self.undo)
        buttons.addStretch(1)
        buttons.addWidget(self.next_face)
        right.addLayout(buttons)
        return right

    def _gates_grid(self) -> QGridLayout:
        """Label / value rows: the progress toward done, κ, still loads, coverage, samples, live state."""
        grid = QGridLayout()
        # the face is done when all four gates pass; the bar shows the one furthest behind
        self.progress = QProgressBar()
        self.progress.setRange(0, 100)
        self.samples = QLabel("—")
        self.samples.setObjectName("value")
        self.samples.setToolTip(SAMPLES_TIP)
        self.kappa = QLabel("—")
        self.kappa.setObjectName("value")
        self.captures = QLabel("0")
        self.captures.setObjectName("value")
        self.coverage_text = QLabel("—")
        self.coverage_text.setObjectName("value")
        self.state = QLabel("—")
        self.state.setObjectName("state")
        rows = (("Face done when all four are ✔", self.progress), ("Condition number of the kept loads κ", self.kappa),
                ("Distinct still loads", self.captures), ("Coverage (weakest axis)", self.coverage_text),
                ("Samples kept (at least k)", self.samples), ("Live", self.state))
        for r, (text, w) in enumerate(rows):
            grid.addWidget(QLabel(text), r, 0)
            grid.addWidget(w, r, 1)
        return grid

    # ------------------------------------------------------------ model → view
    def _on_mount(self) -> None:
        m = self.model
        self.scene.set_mount(m.flange, m.connected_face)
        self.stage_note.setText(m.current.why)
        self.stage_note.setVisible(bool(m.current.why))
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
        gates = face_gates(fc)
        fraction, name = min((g[0], g[1]) for g in gates)
        self.progress.setValue(int(round(100 * fraction)))
        self.progress.setFormat("✔ face done" if fc.sufficient else f"%p%  ·  next: {name}")
        kappa = fc.condition_number()
        limit = m.rules.max_condition
        self.kappa.setText("— (load more directions)" if not np.isfinite(kappa)
                           else f"{kappa:.1f}  " + ("✔" if kappa <= limit else f"(needs ≤ {limit:g}: vary the loads)"))
        self.captures.setText(f"{len(fc.captures)} / {m.rules.min_captures}"
                              + (" ✔" if len(fc.captures) >= m.rules.min_captures else ""))
        cov = fc.coverage()
        worst = np.unravel_index(np.argmin(cov), cov.shape)
        axis = AXIS_LABELS[worst[0]] + ("−" if worst[1] == 0 else "+")
        self.coverage_text.setText(f"{axis} {cov[worst]:.2f} / {m.rules.required:.2f} of full scale"
                                   + (" ✔" if cov.min() >= m.rules.required else ""))
        self.samples.setText(samples_text(fc.n_samples, m.rules.k))
        self.undo.setEnabled(bool(fc.captures))
        done = fc.sufficient
        remaining = [f for f in m.faces if not m.captures[f].sufficient]
        self.next_face.setEnabled(done and bool(remaining) and remaining != [m.current_face])
        self.set_ready(m.all_faces_done)

    # ------------------------------------------------------------ actions
    def showEvent(self, event):  # noqa: N802 - Qt's name
        super().showEvent(event)
        self.scene.frame_contacts()  # the view's aspect is known now: the probe's full-scale arrow on any face stays in view

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
        here = None  # the reference sees the load, the cube's gauges see which face carries it
        tare = m.stage_tare_counts
        if tare.shape[0]:
            skip = m.connected_face if m.flange == "face" and face != m.connected_face else None
            here = on_face(b.counts[good], tare.mean(axis=0), face, skip)
        event = fc.feed(b.time[good], b.counts[good], b.reference[good], Wf, here)
        texts = {
            "waiting": "…",
            "moving": "moving — hold the load still",
            "no load": "no load — press on the face",
            "not new": "already kept — try another direction",
            "wrong face": f"the load is on another face — load face {face}",
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
        self.scene.show_contacts(ContactEstimate(pts, normals, forces, tors, valid, frame="core"))
        self.scene.redraw()

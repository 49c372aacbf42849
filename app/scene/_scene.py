"""The 3D scene: the cube (or a patched object), the calibration mount, contact glyphs.

Everything is built once; per-frame updates only move actors (``user_matrix``) and toggle
their visibility, then ask for a frame. No mesh is rebuilt per frame (STYLE.md item 10). The
plotter draws into a native child window (:func:`~app.scene.native_plotter`), not a
``QOpenGLWidget``; :func:`~app.scene.grab_window` puts its frame into window grabs
(screenshots, tests). A scene made with ``threaded=True`` (the live view) draws in a thread of
its own (:mod:`app.render_thread`); otherwise a frame is a Qt repaint, which Qt coalesces.

All geometry is in the core frame, metres.
"""

from __future__ import annotations

import functools
import threading

import numpy as np
import pyvista as pv
from PySide6.QtCore import QTimer
from PySide6.QtWidgets import QVBoxLayout, QWidget
from vtkmodules.vtkRenderingCore import vtkBillboardTextActor3D

from pito_core.frames import FACES, CubeCore

from ..palette import FACE_COLORS
from ..render_thread import RenderThread
from ._backdrop import Backdrop
from ._colors import ACTIVE_COLOR, BACKGROUND, CONNECTED_COLOR, CORE_COLOR, PLATE_COLOR
from ._glyphs import ContactGlyphs
from ._mount import mount_meshes
from ._poses import VIEW_ANGLE, default_camera, framing_distance, mount_camera
from ._widget import MAX_FRAME_RATE, is_software_gl, native_plotter

__all__ = ["CubeScene", "PATCH_DISPLAY_CELLS"]

#: most triangles per patch drawn (display meshes are decimated to it, once per object)
PATCH_DISPLAY_CELLS = 1200


def _in_scene_thread(method):
    """Run a :class:`CubeScene` method where its VTK objects may be changed (:meth:`CubeScene.call`)."""

    @functools.wraps(method)
    def run(self, *args, **kwargs):
        return self.call(lambda: method(self, *args, **kwargs))

    return run


def closed_outward(mesh: pv.PolyData) -> bool:
    """True when ``mesh`` is a closed surface whose triangles face out (positive signed volume).

    Its back faces are then never seen from outside when it is opaque: they can be culled
    (``SetBackfaceCulling``), which spares software GL their setup and rasterization.
    """
    tri = mesh if mesh.is_all_triangles else mesh.triangulate()
    if tri.n_cells == 0 or not tri.is_manifold:
        return False
    p = tri.points[tri.regular_faces]  # (n, 3, 3)
    return float(np.einsum("ij,ij->", p[:, 0], np.cross(p[:, 1], p[:, 2]))) > 0.0


def _face_label(text: str, position) -> vtkBillboardTextActor3D:
    """A face number: white bold text on black, facing the camera, centred on ``position`` (m).

    A billboard text actor per face: a label-placement mapper re-places its labels on every
    render, a few ms of the GUI thread per frame.
    """
    lab = vtkBillboardTextActor3D()
    lab.SetInput(text)
    lab.SetPosition(*position)
    tp = lab.GetTextProperty()
    tp.SetFontSize(26)
    tp.BoldOn()
    tp.SetColor(1.0, 1.0, 1.0)
    tp.SetBackgroundColor(0.0, 0.0, 0.0)
    tp.SetBackgroundOpacity(1.0)
    tp.SetJustificationToCentered()
    tp.SetVerticalJustificationToCentered()
    return lab


#: How far a face's number sits off the face's normal, in cube edges (clear of an arrow along it).
LABEL_SIDE = 0.4


class CubeScene(QWidget):
    """A 3D view of the PITO cube (pyvista in a native VTK widget): face plates, mount, patches, contact glyphs.

    Parameters
    ----------
    core : CubeCore, optional
    parent : QWidget, optional
    threaded : bool
        Draw in a thread of its own (:class:`app.render_thread.RenderThread`, started when the
        view is first shown), so that a frame's wait for software GL overlaps the GUI thread's
        work: the live view. The methods below then run their VTK changes in that thread
        (waiting for them), :meth:`show_contacts` queues the glyphs' move for the next frame,
        and :meth:`sync` waits until everything queued has been applied.
    """

    def __init__(self, core: CubeCore | None = None, parent=None, threaded: bool = False):
        super().__init__(parent)
        self.core = core or CubeCore()
        self.threaded = bool(threaded)
        self.render_thread: RenderThread | None = None
        #: the OpenGL renderer is a software rasterizer (known once the drawing thread starts)
        self.software_gl: bool | None = None
        #: s: time of the newest sample the contact glyphs show (set when they move, in the drawing thread)
        self.contacts_time = float("nan")
        self._queued_contacts = None  # (contacts, time) waiting for the drawing thread's next frame
        self._queued_lock = threading.Lock()
        self.plotter = native_plotter(self)
        self.plotter.set_background(BACKGROUND)
        # one headlight, not pyvista's five-light kit: software GL shades every pixel once per light
        self.plotter.remove_all_lights()
        self.plotter.add_light(pv.Light(light_type="headlight"))  # flat: a gradient costs a full-screen pass in software GL
        # the translucent uncertainty ellipsoids by plain alpha blending, not VTK's order-independent
        # pass: that pass's full-window float buffers took a frame from 21 to 37 ms of CPU in software
        # GL whenever an ellipsoid showed; six separate convex ellipsoids need no ordering (the two
        # images differ by at most 4 of 255 levels; docs/performance.md, "Live window")
        self.plotter.renderer.SetUseOIT(False)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        layout.addWidget(self.plotter.interactor)
        self.frames_rendered = 0
        self.plotter.ren_win.AddObserver("EndEvent", self._count_frame)
        self._plates: dict[int, pv.Actor] = {}
        self._patches: dict[int, pv.Actor] = {}
        self.face_labels: dict[int, vtkBillboardTextActor3D] = {}
        self._add_cube()
        self._mount_actors: list = []
        self.glyphs = ContactGlyphs(self.plotter, self.core.edge)
        #: frame the camera for full-scale arrows (:meth:`frame_contacts`) when the object changes
        self.frame_glyphs = False
        self.plotter.add_axes(line_width=2, labels_off=False)
        #: the object's frame kept and restored while unchanged; the glyphs drawn over it (:mod:`._backdrop`)
        self.backdrop = Backdrop(self.plotter, self.glyphs.actors)
        self.reset_camera()

    def _add_cube(self) -> None:
        """The core, a plate on each face and the face numbers (once, when the scene is made)."""
        e = self.core.edge
        # opaque closed boxes: their back faces are culled (never seen; less work for software GL)
        core = self.plotter.add_mesh(pv.Cube(x_length=0.9 * e, y_length=0.9 * e, z_length=0.9 * e), color=CORE_COLOR,
                                     name="core", reset_camera=False)
        core.GetProperty().SetBackfaceCulling(True)
        for i in FACES:
            T = self.core.face_pose(i)
            plate = pv.Box(bounds=(-0.42 * e, 0.42 * e, -0.42 * e, 0.42 * e, -0.04 * e, 0.0)).transform(T, inplace=False)
            self._plates[i] = self.plotter.add_mesh(plate, color=PLATE_COLOR, name=f"plate_{i}", smooth_shading=False, reset_camera=False)
            self._plates[i].GetProperty().SetBackfaceCulling(True)
            self.face_labels[i] = _face_label(str(i), self.core.face_pose(i)[:3, 3] * 1.45)
            self.plotter.renderer.AddActor(self.face_labels[i])

    # ------------------------------------------------------------------ the drawing thread
    def _count_frame(self, *_):
        self.frames_rendered += 1

    def showEvent(self, event):  # noqa: N802 - Qt's name
        super().showEvent(event)
        rt = self.render_thread
        if rt is not None:
            rt.visible = True
            rt.request()
        elif self.threaded and not getattr(self, "_closed_scene", False):
            QTimer.singleShot(0, self._start_render_thread)

    def hideEvent(self, event):  # noqa: N802
        super().hideEvent(event)
        if self.render_thread is not None:
            self.render_thread.visible = False  # no frames for a hidden view

    def _start_render_thread(self) -> None:
        if self.render_thread is not None or getattr(self, "_closed_scene", False) or not self.isVisible():
            return
        self.plotter.ren_win.Render()  # the GL context exists (made here) before it is handed over
        rt = RenderThread(self.plotter.ren_win, self.plotter.iren.interactor, name="pito-render")
        self.software_gl = is_software_gl(self.plotter.ren_win)
        rt.max_rate = MAX_FRAME_RATE["software" if self.software_gl else "hardware"]
        self.plotter.interactor.render_lock = rt.lock
        rt.start()
        self.render_thread = rt

    def call(self, fn):
        """``fn()`` where this scene's VTK objects may be changed (the drawing thread, if any); returns its result."""
        rt = self.render_thread
        return fn() if rt is None else rt.call(fn)

    def sync(self) -> None:
        """Wait until every queued change (:meth:`show_contacts`) has been applied."""
        if self.render_thread is not None:
            self.render_thread.sync()

    def show_contacts(self, contacts, time: float = float("nan"), queue_only: bool = False) -> np.ndarray:
        """Move the glyphs to ``contacts`` (sample time ``time``, s) in the next frame; returns the shown mask (6,).

        With a drawing thread the move is queued (the caller does not wait) and
        :attr:`contacts_time` changes with it, so a frame never shows one without the other;
        this is thread-safe. ``queue_only``: do nothing without a drawing thread (a caller
        outside the GUI thread must not change VTK objects itself).
        """
        shown = self.glyphs.visible(contacts)
        rt = self.render_thread
        if rt is None:
            if queue_only:
                return shown
            self.glyphs.update(contacts)
            self.contacts_time = time
            return shown
        with self._queued_lock:  # only the latest waits for the frame: one move per frame
            first = self._queued_contacts is None
            self._queued_contacts = (contacts, time)
        if first:
            rt.post(self._move_queued_contacts)
        return shown

    def _move_queued_contacts(self) -> None:
        with self._queued_lock:
            queued, self._queued_contacts = self._queued_contacts, None
        if queued is not None:
            self.glyphs.update(queued[0])
            self.contacts_time = queued[1]

    # ------------------------------------------------------------------ state
    @_in_scene_thread
    def reset_camera(self, distance: float = 4.6) -> None:
        """The usual view, ``distance`` (in units of 1.35 edges) from the centre (:func:`default_camera`)."""
        self.plotter.camera_position = default_camera(self.core.edge, distance)
        self.plotter.camera.view_angle = VIEW_ANGLE

    @_in_scene_thread
    def look_at_mount(self, connected_face: int | None, active_face: int | None = None, distance: float = 4.8,
                      elevation: float | None = None) -> None:
        """Camera with the flange's face down (as on the bench), the active face towards the viewer (:func:`mount_camera`)."""
        if connected_face is None:
            self.reset_camera(distance)
            return
        self.plotter.camera_position = mount_camera(self.core.edge, connected_face, active_face, distance, elevation)
        self.plotter.camera.view_angle = VIEW_ANGLE
        self.redraw()

    def redraw(self) -> None:
        """Ask for a frame: from the drawing thread, else a repaint (Qt coalesces repaints)."""
        if self.render_thread is not None:
            self.render_thread.request()
        else:
            self.plotter.interactor.update()

    @_in_scene_thread
    def set_face_colors(self, colors: dict[int, str]) -> None:
        """Colour the face plates (face -> colour); faces not given get the neutral colour."""
        for i in FACES:
            self._plates[i].prop.color = colors.get(i, PLATE_COLOR)
        self.redraw()

    @_in_scene_thread
    def highlight(self, connected_face: int | None = None, active_face: int | None = None) -> None:
        """The flange's face in orange, the face to load in green."""
        colors = {}
        if connected_face is not None:
            colors[connected_face] = CONNECTED_COLOR
        if active_face is not None:
            colors[active_face] = ACTIVE_COLOR
        self.set_face_colors(colors)

    @_in_scene_thread
    def set_mount(self, flange: str | None, connected_face: int | None, flange_opacity: float = 1.0) -> None:
        """Draw the calibration flange and the reference sensor on ``connected_face`` (or none)."""
        for name in list(self._mount_actors):
            self.plotter.remove_actor(name, render=False)
        self._mount_actors = []
        if flange is None or connected_face is None:
            self.redraw()
            return
        T = self.core.face_pose(connected_face)
        for name, mesh, color in mount_meshes(flange, self.core.edge):
            actor_name = f"mount_{name}"
            self.plotter.add_mesh(mesh.transform(T, inplace=False), color=color, name=actor_name, reset_camera=False,
                                  smooth_shading=name == "ati", opacity=flange_opacity if name == "flange" else 1.0)
            self._mount_actors.append(actor_name)
        self.redraw()

    @_in_scene_thread
    def set_patches(self, meshes: dict[int, pv.PolyData] | None, opacity: float = 1.0) -> None:
        """Show patch display meshes (core frame, m) on the faces; ``None`` shows the bare cube."""
        for i in list(self._patches):
            self.plotter.remove_actor(f"patch_{i}", render=False)
        self._patches = {}
        for i, mesh in (meshes or {}).items():
            if mesh is None:
                continue
            if mesh.n_cells > PATCH_DISPLAY_CELLS:
                # fewer triangles on screen: software GL pays per vertex every frame; the
                # smooth-shaded patch looks the same at a quarter of the cells
                mesh = mesh.triangulate().decimate(1.0 - PATCH_DISPLAY_CELLS / mesh.n_cells)
            self._patches[i] = self.plotter.add_mesh(
                mesh, color=FACE_COLORS[i], opacity=opacity, name=f"patch_{i}", smooth_shading=True, reset_camera=False
            )
            # an opaque closed patch (the library's are): its back faces never show; culled, they cost
            # software GL nothing (a third of the scene's frame with pito_mixed's patches)
            self._patches[i].GetProperty().SetBackfaceCulling(opacity >= 1.0 and closed_outward(mesh))
        self._place_labels()
        if self.frame_glyphs:
            self.frame_contacts()
        self.redraw()

    @_in_scene_thread
    def set_caption(self, text: str) -> None:
        """A line of text in the view's top-left corner (replaced, not added, on each call)."""
        self.plotter.add_text(text, position="upper_left", font_size=11, color="#f0c060", name="caption")
        self.redraw()

    def label_offset(self, face: int) -> float:
        """How far out along ``face``'s normal its number is drawn, m: past the patch on it (the
        number stays clear of the patch and of contacts on it)."""
        c = np.asarray(self.core.face_pose(face)[:3, 3], dtype=float)  # the face centre: along its normal
        n = c / np.linalg.norm(c)
        reach = 0.5 * self.core.edge
        actor = self._patches.get(face)
        if actor is not None and actor.mapper is not None and actor.mapper.dataset is not None:
            pts = np.asarray(actor.mapper.dataset.points)
            if pts.size:
                reach = max(reach, float((pts @ n).max()))
        return reach + 0.3 * self.core.edge

    def _place_labels(self) -> None:
        """Each face's number past its patch, and off its normal towards the face's (−x, +y) corner: a
        push on the face comes along the normal, and its arrow would cover a number placed there."""
        for i, lab in self.face_labels.items():
            T = self.core.face_pose(i)
            c = np.asarray(T[:3, 3], dtype=float)
            side = (T[:3, 1] - T[:3, 0]) / np.sqrt(2.0)  # in the face's plane, towards its (−x, +y) corner
            lab.SetPosition(*(c / np.linalg.norm(c) * self.label_offset(i) + LABEL_SIDE * self.core.edge * side))

    def close_scene(self) -> None:
        """Release the GL resources now (not at some later garbage collection, which may fall
        in another GL widget's paint and crash)."""
        if not getattr(self, "_closed_scene", False):
            self._closed_scene = True
            rt, self.render_thread = self.render_thread, None
            if rt is not None:
                rt.stop()  # the GL context is this thread's again
                self.plotter.interactor.render_lock = None
            try:
                self.backdrop.release()
                self.plotter.interactor.Finalize()
            finally:
                self.plotter.close()

    def set_view_extent(self, radius: float) -> None:
        """Frame the camera on a sphere of ``radius`` m about the core centre."""
        self.reset_camera(distance=6.0 * max(radius, self.core.edge) / self.core.edge)

    def object_radius(self) -> float:
        """Radius of the object about the core centre, m: the core's corners and the patches' points."""
        r = 0.5 * np.sqrt(3.0) * self.core.edge
        for actor in self._patches.values():
            pts = np.asarray(actor.mapper.dataset.points) if actor.mapper is not None and actor.mapper.dataset is not None else None
            if pts is not None and pts.size:
                r = max(r, float(np.sqrt((pts ** 2).sum(axis=1).max())))
        return r

    def frame_contacts(self) -> None:
        """Camera that holds the object and full-scale force arrows on any face.

        A sphere of radius (object radius + the glyphs' reach) about the core centre fits in
        the view's narrower field of view, from the usual viewing direction. Called when the
        object or the arrow scale changes, so the framing follows the object.
        """
        w, h = self.plotter.interactor.width(), self.plotter.interactor.height()  # (Qt: in the GUI thread)
        self.call(lambda: self._frame_contacts(w, h))

    def _frame_contacts(self, w: int, h: int) -> None:
        distance = framing_distance(self.object_radius() + self.glyphs.reach(), w, h)
        self.reset_camera(distance=distance / (self.core.edge * 1.35))
        self._framed = True
        self.redraw()

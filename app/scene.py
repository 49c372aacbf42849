"""The 3D scene: the cube (or a patched object), the calibration mount, contact glyphs.

Everything is built once; per-frame updates only move actors (``user_matrix``) and toggle
their visibility, then ask for a frame. No mesh is rebuilt per frame (STYLE.md item 10). The
plotter draws into a native child window (:func:`native_plotter`), not a ``QOpenGLWidget``;
:func:`grab_window` puts its frame into window grabs (screenshots, tests). A scene made with
``threaded=True`` (the live view) draws in a thread of its own (:mod:`app.render_thread`);
otherwise a frame is a Qt repaint, which Qt coalesces.

All geometry is in the core frame, metres.
"""

from __future__ import annotations

import contextlib
import functools
import math
import threading

import numpy as np
import pyvista as pv
from PySide6.QtCore import QTimer
from PySide6.QtGui import QImage, QPainter
from PySide6.QtWidgets import QVBoxLayout, QWidget
from vtkmodules.qt.QVTKRenderWindowInteractor import QVTKRenderWindowInteractor

from pito_core.frames import FACES, CubeCore

from .palette import CONTACT_COLOR, FACE_COLORS, hex_rgb
from .render_thread import RenderThread

__all__ = ["CubeScene", "ContactGlyphs", "native_plotter", "grab_window", "grab_scene", "FACE_COLORS", "arrow_matrix", "ellipsoid_matrix", "FULL_SCALE_FORCE", "MAX_FRAME_RATE", "is_software_gl"]

#: N: arrows are drawn up to this force (a firm grasp, the arrows' full scale) and clamped beyond it
#: (marked by a white collar at the tail); the live view frames its camera to hold them
FULL_SCALE_FORCE = 12.0

#: most triangles per patch drawn (display meshes are decimated to it, once per object)
PATCH_DISPLAY_CELLS = 1200

PLATE_COLOR = "#b8c2cc"
CORE_COLOR = "#5b6570"
CONNECTED_COLOR = "#f0a030"
ACTIVE_COLOR = "#2ecc71"
FLANGE_COLOR = "#8a8f96"
ATI_COLOR = "#3a3f45"
#: Contact sphere of a contact that one fingertip cannot explain (``ObjectContacts.single_contact`` False)
FLAGGED_CONTACT_COLOR = "#ff3b6b"
BACKGROUND = "#1e2329"

pv.global_theme.multi_samples = 0  # MSAA halves the frame rate in software GL

#: Most frames a second a threaded scene draws, Hz (``RenderThread.max_rate``). With a GPU: a
#: display's refresh rate. In software OpenGL (Mesa's llvmpipe) a frame of the live view costs
#: ~14 ms of CPU at 680×740 px; unlimited frames took that CPU from the data path and the
#: plots and made every view later, not fresher (docs/performance.md §6).
MAX_FRAME_RATE = {"hardware": 60.0, "software": 50.0}


def is_software_gl(ren_win) -> bool:
    """True when ``ren_win``'s OpenGL renderer is a software rasterizer (llvmpipe, softpipe, swrast)."""
    try:
        caps = ren_win.ReportCapabilities().lower()
    except Exception:  # noqa: BLE001 - unknown: treat as hardware (no lower limit)
        return False
    return any(name in caps for name in ("llvmpipe", "softpipe", "swrast", "software rasterizer"))


def _rotation_from_x(direction: np.ndarray) -> np.ndarray:
    """``(3, 3)`` rotation taking +x onto the unit vector ``direction``.

    Scalar arithmetic: called for every glyph on every drawn frame, where ``np.cross`` and
    ``np.linalg.norm`` on 3-vectors cost more in call overhead than in arithmetic.
    """
    x0, x1, x2 = (float(v) for v in direction)
    n = math.sqrt(x0 * x0 + x1 * x1 + x2 * x2)
    x0, x1, x2 = x0 / n, x1 / n, x2 / n
    if abs(x2) < 0.9:  # y = (0, 0, 1) × x
        y0, y1, y2 = -x1, x0, 0.0
    else:  # y = (0, 1, 0) × x
        y0, y1, y2 = x2, 0.0, -x0
    m = math.sqrt(y0 * y0 + y1 * y1 + y2 * y2)
    y0, y1, y2 = y0 / m, y1 / m, y2 / m
    z0, z1, z2 = x1 * y2 - x2 * y1, x2 * y0 - x0 * y2, x0 * y1 - x1 * y0  # z = x × y
    return np.array([[x0, y0, z0], [x1, y1, z1], [x2, y2, z2]])


def arrow_matrix(tip, force, scale: float, width: float, max_length: float = np.inf, gap: float = 0.0) -> np.ndarray:
    """``(4, 4)`` pose of a unit +x arrow drawn as ``force`` pushing at ``tip``.

    Parameters
    ----------
    tip : array-like, shape (3,)
        Where the arrow ends (the contact point), m.
    force : array-like, shape (3,)
        The force, N (non-zero).
    scale : float
        Arrow length per newton, m/N.
    width : float
        Shaft scale, m (the unit arrow's radii are multiplied by this).
    max_length : float
        Longest arrow drawn, m (longer ones are clamped to it).
    gap : float
        The arrow ends this far before ``tip``, m (on the surface of the contact sphere).
    """
    force = np.asarray(force, dtype=float)
    length = min(math.sqrt(float(force @ force)) * scale, max_length)
    R = _rotation_from_x(force)
    M = np.eye(4)
    M[:3, :3] = R @ np.diag([length, width, width])
    M[:3, 3] = np.asarray(tip, dtype=float) - R[:, 0] * (length + gap)
    return M


def ellipsoid_matrix(center, covariance, n_sigma: float = 2.0) -> np.ndarray:
    """``(4, 4)`` pose of a unit sphere drawn as the ``n_sigma`` ellipsoid of ``covariance`` (m²)."""
    cov = np.asarray(covariance, dtype=float)
    w, V = np.linalg.eigh(0.5 * (cov + cov.T))
    M = np.eye(4)
    M[:3, :3] = V @ np.diag(n_sigma * np.sqrt(np.clip(w, 0.0, None)))
    M[:3, 3] = center
    return M


def _normal_frame_matrix(center, normal, radius: float) -> np.ndarray:
    """Pose of a unit disc (in its xy plane, normal +z) centred at ``center`` facing ``normal``."""
    R = _rotation_from_x(np.asarray(normal, dtype=float))
    R = R[:, [1, 2, 0]]  # z := normal
    M = np.eye(4)
    M[:3, :3] = R * radius
    M[:3, 3] = center
    return M


_hex_rgb = hex_rgb


class ContactGlyphs:
    """One contact sphere, force arrow, torsion ring and uncertainty ellipsoid per face.

    Created once; :meth:`update` moves them in place and hides the faces whose force is
    under ``threshold`` (N) or whose estimate is not valid. The contact is a white sphere
    drawn in an overlay layer (the same camera, its own depth buffer), so it stays visible
    from any camera angle, even behind the object; the arrow, in the face's colour (the
    colour of its curve in the plots), ends on the sphere's surface. Arrows longer than
    :data:`FULL_SCALE_FORCE` are clamped to it and get a white collar at the tail. Torsion
    rings float a little above the surface (a ring in the surface's plane z-fights with it).
    A contact that one fingertip cannot explain (``single_contact`` False: two fingers on
    one patch, or a load beyond a fingertip's friction; docs/contact.md) gets a red-pink
    sphere (:data:`FLAGGED_CONTACT_COLOR`) instead of the white one; ``flagged`` (6,) says which.

    Parameters
    ----------
    plotter : pyvista plotter
    edge : float
        Cube edge, m (sets glyph sizes).
    """

    def __init__(self, plotter, edge: float):
        import vtk

        self.plotter = plotter
        self.force_scale = 0.006  # m per N: 15 N -> 9 cm
        self.torque_scale = 0.25  # m per N·m: 0.1 N·m -> 2.5 cm ring radius
        self.threshold = 0.3  # N
        self.full_scale = FULL_SCALE_FORCE  # N
        self.show_torsion = True
        self.show_uncertainty = False
        self.radius = 0.07 * edge  # m, contact sphere
        self.lift = 0.04 * edge  # m, torsion rings above the surface
        unit_arrow = pv.Arrow(start=(0, 0, 0), direction=(1, 0, 0), tip_length=0.25, tip_radius=2.2, shaft_radius=1.0, scale=1.0)
        # pv.Arrow scales radii by `scale` (=1): radii are in "width" units, length is 1
        unit_sphere = pv.Sphere(radius=1.0, theta_resolution=20, phi_resolution=12)
        ring = pv.Disc(inner=0.82, outer=1.0, r_res=1, c_res=48)
        collar = pv.Disc(inner=0.0, outer=1.0, r_res=1, c_res=24)
        self._width = 0.0022 * edge / 0.05
        # the overlay: a second renderer on layer 1 sharing the scene's camera; it clears only
        # the depth buffer, so what it draws is never hidden by the object
        ren_win = plotter.ren_win
        ren_win.SetNumberOfLayers(max(2, ren_win.GetNumberOfLayers()))
        self.overlay = vtk.vtkRenderer()
        self.overlay.SetLayer(1)
        self.overlay.InteractiveOff()
        self.overlay.SetActiveCamera(plotter.renderer.GetActiveCamera())
        ren_win.AddRenderer(self.overlay)
        sphere_src = pv.Sphere(radius=self.radius, theta_resolution=16, phi_resolution=12)
        self.spheres, self.arrows, self.rings, self.ellipsoids, self.collars = {}, {}, {}, {}, {}
        for i in FACES:
            c = FACE_COLORS[i]
            sph = pv.Actor(mapper=pv.DataSetMapper(sphere_src.copy()))
            sph.prop.color = CONTACT_COLOR
            sph.prop.interpolation = "gouraud"
            sph.prop.ambient = 0.35
            self.overlay.AddActor(sph)
            self.spheres[i] = sph
            self.arrows[i] = plotter.add_mesh(unit_arrow.copy(), color=c, name=f"force_arrow_{i}", reset_camera=False)
            # opaque: a translucent actor costs every frame an extra pass in software GL (~1.6x)
            self.rings[i] = plotter.add_mesh(ring.copy(), color=c, name=f"torsion_ring_{i}", reset_camera=False)
            self.collars[i] = plotter.add_mesh(collar.copy(), color=CONTACT_COLOR, name=f"clamp_collar_{i}", reset_camera=False)
            self.collars[i].GetProperty().SetLighting(False)  # plain white from any side
            self.ellipsoids[i] = plotter.add_mesh(unit_sphere.copy(), color=c, opacity=0.25, name=f"uncertainty_{i}", reset_camera=False)
        self.shown = np.zeros(6, dtype=bool)
        self.clamped = np.zeros(6, dtype=bool)
        self.flagged = np.zeros(6, dtype=bool)
        self._sphere_flag: dict[int, bool] = {}
        self.updates = 0
        self._ring_sign: dict[int, int] = {}
        self._ring_colors = {i: (hex_rgb(FACE_COLORS[i]), tuple(0.45 * v for v in hex_rgb(FACE_COLORS[i]))) for i in FACES}
        self.actors = [a for d in (self.spheres, self.arrows, self.rings, self.ellipsoids, self.collars) for a in d.values()]
        self.hide()

    @property
    def max_length(self) -> float:
        """Longest arrow drawn, m (the full-scale force)."""
        return self.full_scale * self.force_scale

    def reach(self) -> float:
        """How far beyond a contact point a glyph can reach, m (arrow at full scale, sphere)."""
        return self.max_length + 2 * self.radius

    def hide(self) -> None:
        for a in self.actors:
            a.SetVisibility(False)
        self.shown = np.zeros(6, dtype=bool)
        self.clamped = np.zeros(6, dtype=bool)

    def shown_count(self) -> int:
        """Contacts on screen after the last update."""
        return int(self.shown.sum())

    def visible(self, contacts) -> np.ndarray:
        """Which faces' glyphs :meth:`update` shows for ``contacts`` (6,): valid, finite, at least ``threshold``."""
        points = np.asarray(contacts.point, dtype=float)
        fnorm = np.linalg.norm(np.asarray(contacts.force, dtype=float), axis=1)
        return np.asarray(contacts.valid, dtype=bool) & np.isfinite(fnorm) & (fnorm >= self.threshold) & np.isfinite(points).all(axis=1)

    def update(self, contacts) -> np.ndarray:
        """Move the glyphs to the latest contacts and return the shown mask (6,).

        Parameters
        ----------
        contacts : pito_core.contact.ObjectContacts
            The one contact record from the solver (core frame), fields of shape ``(6, …)``,
            face i at row i-1: ``point`` (m), ``normal`` (outward), ``force`` on the object
            (N), ``torsion`` about the normal (N·m), ``valid``, ``point_cov`` (m², or None).
        """
        points = np.asarray(contacts.point, dtype=float)
        normals, torsions = contacts.normal, contacts.torsion
        covariances = contacts.point_cov
        forces = np.asarray(contacts.force, dtype=float)
        shown = self.visible(contacts)
        clamped = shown & (np.linalg.norm(forces, axis=1) > self.full_scale)
        single = getattr(contacts, "single_contact", None)
        flagged = shown & ~np.asarray(single, dtype=bool) if single is not None else np.zeros(6, dtype=bool)
        for k, i in enumerate(FACES):
            on = bool(shown[k])
            self.spheres[i].SetVisibility(on)
            self.arrows[i].SetVisibility(on)
            self.collars[i].SetVisibility(bool(clamped[k]))
            tor = float(torsions[k]) if on else np.nan
            ring_on = bool(on and self.show_torsion and np.isfinite(tor) and abs(tor) * self.torque_scale > 1e-4)
            self.rings[i].SetVisibility(ring_on)
            cov_on = bool(on and self.show_uncertainty and covariances is not None and np.isfinite(covariances[k]).all())
            self.ellipsoids[i].SetVisibility(cov_on)
            if not on:
                continue
            self.spheres[i].SetPosition(*points[k])
            if self._sphere_flag.get(i, False) != bool(flagged[k]):  # (a colour set costs a pyvista round trip)
                self._sphere_flag[i] = bool(flagged[k])
                self.spheres[i].prop.color = FLAGGED_CONTACT_COLOR if flagged[k] else CONTACT_COLOR
            M = arrow_matrix(points[k], forces[k], self.force_scale, self._width, self.max_length, self.radius)
            self.arrows[i].user_matrix = M
            if clamped[k]:
                # a white collar around the tail of a clamped arrow: "more than full scale"
                tail = M[:3, 3]
                self.collars[i].user_matrix = _normal_frame_matrix(tail, forces[k], 4.0 * self._width)
            if ring_on:
                n = np.asarray(normals[k], dtype=float)
                n_norm = np.linalg.norm(n)
                centre = points[k] + (self.lift * n / n_norm if n_norm > 0 else 0.0)
                self.rings[i].user_matrix = _normal_frame_matrix(centre, normals[k], abs(tor) * self.torque_scale)
                # the sign of the torsion: full colour counter-clockwise (τ > 0), dimmed clockwise
                sign = 0 if tor > 0 else 1
                if self._ring_sign.get(i) != sign:  # (a colour set costs a pyvista round trip)
                    self._ring_sign[i] = sign
                    self.rings[i].prop.color = self._ring_colors[i][sign]
            if cov_on:
                self.ellipsoids[i].user_matrix = ellipsoid_matrix(points[k], covariances[k])
        self.shown = shown
        self.clamped = clamped
        self.flagged = flagged
        self.updates += 1
        return shown


class _SceneWidget(QVTKRenderWindowInteractor):
    """VTK's Qt widget whose event handlers hold ``render_lock`` when a :class:`RenderThread` draws the window.

    The handlers change VTK objects (the camera, the window's size) in the GUI thread; the
    lock keeps them out of a frame the render thread is drawing.
    """

    render_lock = None


def _under_render_lock(name: str):
    """``QVTKRenderWindowInteractor.<name>``, run holding the widget's ``render_lock`` when it has one."""
    base = getattr(QVTKRenderWindowInteractor, name)

    def handler(self, *args):
        with self.render_lock or contextlib.nullcontext():
            return base(self, *args)

    handler.__name__ = handler.__qualname__ = name
    return handler


for _name in ("resizeEvent", "mousePressEvent", "mouseReleaseEvent", "mouseMoveEvent", "wheelEvent",
              "keyPressEvent", "keyReleaseEvent", "enterEvent", "leaveEvent", "TimerEvent"):
    setattr(_SceneWidget, _name, _under_render_lock(_name))
del _name


def native_plotter(parent) -> pv.Plotter:
    """A pyvista plotter drawing straight into a native Qt child window.

    VTK's own ``QVTKRenderWindowInteractor`` (a ``QWidget`` with a native window, VTK owns the
    GL context) hosts the plotter's render window and forwards mouse and keys to its
    interactor. Unlike a ``QOpenGLWidget`` (pyvistaqt's ``QtInteractor``), it does not make Qt
    compose the whole top-level window with OpenGL on every frame: in software GL that
    composition cost more than the scene itself, and every plot repaint paid it too. The
    widget is ``plotter.interactor``; call :meth:`QWidget.update` on it to repaint.
    """
    plotter = pv.Plotter(off_screen=False, window_size=(640, 480))
    plotter.ren_win.SetMultiSamples(0)  # MSAA multiplies the fill cost in software GL
    # colour only to the window's back buffer: the default also copies VTK's depth buffer there
    # (a full-window shader pass, for GL drawn after VTK's, which this window has none of);
    # in software GL that pass was 2.5 of the 12 ms an idle frame took (679×740 px)
    plotter.ren_win.SetFrameBlitModeToBlitToCurrent()
    widget = _SceneWidget(parent, rw=plotter.ren_win, iren=plotter.iren.interactor)
    plotter.iren.interactor.Enable()  # the Qt widget drives it: no VTK event loop is started
    pv.set_new_attribute(plotter, "interactor", widget)
    return plotter


def grab_scene(scene) -> QImage:
    """The scene's last frame as a ``QImage`` (a native GL window is not in ``QWidget.grab``)."""
    from vtkmodules.util.numpy_support import vtk_to_numpy
    import vtk

    def read():  # a render and a read-back: GL calls, made where the scene draws
        f = vtk.vtkWindowToImageFilter()
        f.SetInput(scene.plotter.ren_win)
        f.SetInputBufferTypeToRGB()
        f.ReadFrontBufferOff()
        f.ShouldRerenderOn()
        f.Update()
        out = vtk.vtkImageData()
        out.DeepCopy(f.GetOutput())
        return out

    img = scene.call(read)
    w, h, _ = img.GetDimensions()
    arr = vtk_to_numpy(img.GetPointData().GetScalars()).reshape(h, w, 3)[::-1].copy()
    return QImage(arr.data, w, h, 3 * w, QImage.Format.Format_RGB888).copy()


def grab_window(widget):
    """``widget.grab()`` with every visible :class:`CubeScene`'s frame painted in (a ``QPixmap``)."""
    pix = widget.grab()
    painter = QPainter(pix)
    try:
        scenes = ([widget] if isinstance(widget, CubeScene) else []) + list(widget.findChildren(CubeScene))
        for scene in scenes:
            view = scene.plotter.interactor
            if not view.isVisible() or getattr(scene, "_closed_scene", False):
                continue
            pos = view.mapTo(widget, view.rect().topLeft())
            img = grab_scene(scene)
            painter.drawImage(pos.x(), pos.y(), img.scaled(view.width(), view.height()))
    finally:
        painter.end()
    return pix


def _in_scene_thread(method):
    """Run a :class:`CubeScene` method where its VTK objects may be changed (:meth:`CubeScene.call`)."""

    @functools.wraps(method)
    def run(self, *args, **kwargs):
        return self.call(lambda: method(self, *args, **kwargs))

    return run


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
        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        layout.addWidget(self.plotter.interactor)
        self.frames_rendered = 0
        self.plotter.ren_win.AddObserver("EndEvent", self._count_frame)
        e = self.core.edge
        self._plates: dict[int, pv.Actor] = {}
        self._patches: dict[int, pv.Actor] = {}
        self.plotter.add_mesh(pv.Cube(x_length=0.9 * e, y_length=0.9 * e, z_length=0.9 * e), color=CORE_COLOR, name="core", reset_camera=False)
        for i in FACES:
            T = self.core.face_pose(i)
            plate = pv.Box(bounds=(-0.42 * e, 0.42 * e, -0.42 * e, 0.42 * e, -0.04 * e, 0.0)).transform(T, inplace=False)
            self._plates[i] = self.plotter.add_mesh(plate, color=PLATE_COLOR, name=f"plate_{i}", smooth_shading=False, reset_camera=False)
        pts = np.array([self.core.face_pose(i)[:3, 3] * 1.45 for i in FACES])
        # face numbers: six billboard text actors (a label-placement mapper re-places its labels
        # on every render, a few ms of the GUI thread per frame)
        import vtk

        self.face_labels = {}
        for i, p in zip(FACES, pts):
            lab = vtk.vtkBillboardTextActor3D()
            lab.SetInput(str(i))
            lab.SetPosition(*p)
            tp = lab.GetTextProperty()
            tp.SetFontSize(26)
            tp.BoldOn()
            tp.SetColor(1.0, 1.0, 1.0)
            tp.SetBackgroundColor(0.0, 0.0, 0.0)
            tp.SetBackgroundOpacity(1.0)
            tp.SetJustificationToCentered()
            tp.SetVerticalJustificationToCentered()
            self.plotter.renderer.AddActor(lab)
            self.face_labels[i] = lab
        self._mount_actors: list = []
        self.glyphs = ContactGlyphs(self.plotter, e)
        #: frame the camera for full-scale arrows (:meth:`frame_contacts`) when the object changes
        self.frame_glyphs = False
        self.plotter.add_axes(line_width=2, labels_off=False)
        self.reset_camera()

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
        e = self.core.edge
        d = np.array([0.4, -1.0, 0.55])
        d *= distance * e / np.linalg.norm(d) * 1.35
        self.plotter.camera_position = [tuple(d), (0, 0, 0), (0, 0, 1)]
        self.plotter.camera.view_angle = 30.0

    @_in_scene_thread
    def look_at_mount(self, connected_face: int | None, active_face: int | None = None, distance: float = 4.8,
                      elevation: float | None = None) -> None:
        """Camera with the flange's face down (as on the bench), the active face towards the viewer."""
        from pito_core.frames import FACE_NORMALS

        e = self.core.edge
        if connected_face is None:
            self.reset_camera(distance)
            return
        up = -np.array(FACE_NORMALS[connected_face])
        if active_face is not None and active_face != connected_face and abs(np.dot(FACE_NORMALS[active_face], up)) < 0.5:
            front = np.array(FACE_NORMALS[active_face])
        else:
            front = np.array(next(FACE_NORMALS[i] for i in FACES if abs(np.dot(FACE_NORMALS[i], up)) < 0.5))
        side = np.cross(up, front)
        if elevation is None:
            top = active_face is not None and np.allclose(FACE_NORMALS[active_face], up)
            elevation = 0.9 if top else 0.55  # the top face: look from higher up
        direction = front + 0.55 * side + elevation * up
        direction /= np.linalg.norm(direction)
        centre = -up * 0.25 * e
        self.plotter.camera_position = [tuple(centre + distance * e * direction), tuple(centre), tuple(up)]
        self.plotter.camera.view_angle = 30.0
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
        e = self.core.edge
        T = self.core.face_pose(connected_face)
        meshes = []
        if flange == "face":
            meshes.append(("flange", pv.Cylinder(center=(0, 0, 0.08 * e), direction=(0, 0, 1), radius=0.38 * e, height=0.16 * e, resolution=48), FLANGE_COLOR))
            z0 = 0.16 * e
        else:
            z0 = 0.25 * e
            if flange == "frame_hole":
                plate = pv.Disc(inner=0.22 * e, outer=0.75 * e, r_res=1, c_res=48).extrude((0, 0, 0.08 * e), capping=True)
                plate = plate.translate((0, 0, z0 - 0.04 * e), inplace=False)
            else:
                plate = pv.Box(bounds=(-0.7 * e, 0.7 * e, -0.7 * e, 0.7 * e, z0 - 0.04 * e, z0 + 0.04 * e))
            meshes.append(("flange", plate, FLANGE_COLOR))
            # posts from the plate to the core frame's corners (the frame holds the core, not the face)
            for sx in (-1, 1):
                for sy in (-1, 1):
                    meshes.append((f"post{sx}{sy}", pv.Box(bounds=(sx * 0.6 * e - 0.05 * e, sx * 0.6 * e + 0.05 * e, sy * 0.6 * e - 0.05 * e, sy * 0.6 * e + 0.05 * e, -0.55 * e, z0)), FLANGE_COLOR))
            z0 += 0.04 * e
        meshes.append(("ati", pv.Cylinder(center=(0, 0, z0 + 0.2 * e), direction=(0, 0, 1), radius=0.3 * e, height=0.4 * e, resolution=48), ATI_COLOR))
        meshes.append(("stand", pv.Box(bounds=(-1.0 * e, 1.0 * e, -1.0 * e, 1.0 * e, z0 + 0.4 * e, z0 + 0.5 * e)), "#4a5560"))
        for name, mesh, color in meshes:
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
        if self.frame_glyphs:
            self.frame_contacts()
        self.redraw()

    @_in_scene_thread
    def set_caption(self, text: str) -> None:
        """A line of text in the view's top-left corner (replaced, not added, on each call)."""
        self.plotter.add_text(text, position="upper_left", font_size=11, color="#f0c060", name="caption")
        self.redraw()

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
        radius = self.object_radius() + self.glyphs.reach()
        half_v = np.radians(30.0) / 2
        aspect = min(1.0, max(0.6, w / h)) if w > 0 and h > 0 else 1.0
        half = min(half_v, np.arctan(np.tan(half_v) * aspect))
        distance = radius / np.sin(half)
        self.reset_camera(distance=distance / (self.core.edge * 1.35))
        self._framed = True
        self.redraw()

"""Frame stamps on pito-app's live window, read back off the screen by the live-window benchmark.

The time of the newest sample a view shows (host monotonic clock, s) is drawn as the colour
of a small square in that view, in the same paint as the data: a 10x10 px square in the 3D
scene's lower-left corner (a VTK 2D actor, set at the start of each render) and one in the
force plot's upper-left corner (set when the curves are given new data). A screen grabber
reads the colour back (24 bits = milliseconds modulo 2^24 ≈ 4.7 h) and compares it with its
own clock (CLOCK_MONOTONIC is shared by all processes): latency = when the stamp first shows
on the screen − when the sample was taken (device clock mapped to the host clock).
"""
from __future__ import annotations

import time

import numpy as np

STAMP_PX = 10


def encode(t: float) -> tuple[int, int, int]:
    v = int(round(t * 1000.0)) & 0xFFFFFF
    return (v >> 16) & 255, (v >> 8) & 255, v & 255


def decode(rgb, t_now: float) -> float:
    """Sample time (s) from a stamp's (r, g, b), the newest time ≤ ``t_now`` with those 24 bits."""
    r, g, b = (int(x) for x in rgb)
    v = (r << 16) | (g << 8) | b
    now_ms = int(t_now * 1000.0)
    return (now_ms - ((now_ms - v) & 0xFFFFFF)) / 1000.0


class WindowProbe:
    """Stamps on ``window.live``'s scene and force plot.

    The scene's stamp shows ``live.scene_time`` (s), the plot's ``force_plot.last_time`` (s);
    for a window that has neither (an older app), the probe keeps them itself by wrapping
    ``live.on_bundle`` and ``force_plot.refresh``.
    """

    def __init__(self, window):
        live = self.live = window.live
        self.scene_time = float("nan")
        self.renders = 0
        #: per scene frame: (the stamped sample time, frame start, frame end), s, monotonic clock
        self.frames: list[tuple[float, float, float]] = []
        self._frame = (float("nan"), 0.0)
        self.actor = _square_actor()
        call = getattr(live.scene, "call", None)
        call(self._attach) if call is not None else self._attach()
        self._own_scene_time = not hasattr(live, "scene_time")
        if self._own_scene_time:  # an older app: keep the newest sample's time here
            orig = live.on_bundle

            def on_bundle(b, _orig=orig):
                _orig(b)
                if not live.paused and b.time.size:
                    self.scene_time = float(b.time[-1])
            live.on_bundle = on_bundle
        self._stamp_plot(live.force_plot)

    def _attach(self) -> None:
        """The scene's stamp with the glyphs, drawn every frame (the object's renderer is redrawn
        only when it changes); the frame's start and end noted. Run where the scene's VTK objects
        may be changed (its drawing thread, if any)."""
        scene = self.live.scene
        backdrop = getattr(scene, "backdrop", None)
        renderer = backdrop.glyph_renderer if backdrop is not None else scene.plotter.renderer
        renderer.AddViewProp(self.actor)
        scene.plotter.ren_win.AddObserver("StartEvent", self._before_render)
        scene.plotter.ren_win.AddObserver("EndEvent", self._after_render)

    def _stamp_plot(self, fp) -> None:
        """The force plot's stamp: a rect item in the view's scene (view pixels, upper-left corner),
        coloured after each refresh with the newest time the plot shows."""
        # deferred: Qt loads only in the app's process (`pito --help` imports this module)
        from PySide6.QtGui import QBrush, QColor, QPen
        from PySide6.QtWidgets import QGraphicsRectItem

        self.rect = QGraphicsRectItem(0, 0, STAMP_PX, STAMP_PX)
        self.rect.setPen(QPen(QColor(0, 0, 0, 0)))
        self.rect.setBrush(QBrush(QColor(0, 0, 0)))
        self.rect.setZValue(1e9)
        fp.scene().addItem(self.rect)
        self.rect.setPos(0, 0)
        orig_refresh = fp.refresh

        def refresh(*a, _orig=orig_refresh, **k):
            out = _orig(*a, **k)
            t = getattr(fp, "last_time", None)
            if t is None:
                d = fp.buffer.view()
                t = float(d[-1, 0]) if d.shape[0] else None
            if t is not None and np.isfinite(t):
                self.rect.setBrush(QBrush(QColor(*encode(t))))
            return out
        fp.refresh = refresh

    def _before_render(self, *_):
        self.renders += 1
        t = self.scene_time if self._own_scene_time else getattr(self.live, "scene_time", float("nan"))
        self._frame = (t, time.monotonic())
        if np.isfinite(t):
            r, g, b = encode(t)
            self.actor.GetProperty().SetColor(r / 255.0, g / 255.0, b / 255.0)

    def _after_render(self, *_):
        if len(self.frames) < 100_000:  # ~40 min of frames
            self.frames.append((*self._frame, time.monotonic()))

    def regions(self) -> dict:
        """Screen rectangles (x, y, w, h) px of the scene and the plots, and the stamps' pixels."""
        from PySide6.QtCore import QPoint  # deferred with Qt (``__init__``)

        live = self.live

        def rect(w):
            p = w.mapToGlobal(QPoint(0, 0))
            return [p.x(), p.y(), w.width(), w.height()]
        scene = rect(live.scene.plotter.interactor)
        fp = rect(live.force_plot)
        eq = rect(live.equilibrium)
        x0, y0 = min(fp[0], eq[0]), min(fp[1], eq[1])
        x1, y1 = max(fp[0] + fp[2], eq[0] + eq[2]), max(fp[1] + fp[3], eq[1] + eq[3])
        # stamp centres, screen px (the scene's is at its lower-left corner)
        dpr = live.scene.plotter.interactor.devicePixelRatioF()
        return {"scene": scene, "plots": [x0, y0, x1 - x0, y1 - y0],
                "scene_stamp": [scene[0] + STAMP_PX // 2, scene[1] + scene[3] - int(STAMP_PX / dpr) // 2 - 1],
                "plot_stamp": [fp[0] + STAMP_PX // 2, fp[1] + STAMP_PX // 2]}


def _square_actor():
    """A black ``STAMP_PX`` square as a VTK 2D actor in display pixels (lower-left corner)."""
    import vtk  # deferred: VTK loads only in the app's process (`pito --help` imports this module)

    pts = vtk.vtkPoints()
    for x, y in ((0, 0), (STAMP_PX, 0), (STAMP_PX, STAMP_PX), (0, STAMP_PX)):
        pts.InsertNextPoint(x, y, 0)
    poly = vtk.vtkPolyData()
    poly.SetPoints(pts)
    cells = vtk.vtkCellArray()
    cells.InsertNextCell(4)
    for k in range(4):
        cells.InsertCellPoint(k)
    poly.SetPolys(cells)
    mapper = vtk.vtkPolyDataMapper2D()
    mapper.SetInputData(poly)
    actor = vtk.vtkActor2D()
    actor.SetMapper(mapper)
    actor.GetProperty().SetColor(0, 0, 0)
    return actor

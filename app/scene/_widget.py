"""The native GL window the scene draws into, and what the drawing thread needs to know of it.

:func:`native_plotter` puts a pyvista plotter in VTK's own Qt widget (a native child window,
not a ``QOpenGLWidget``); its event handlers take the drawing thread's lock
(:mod:`app.render_thread`). :func:`is_software_gl` and :data:`MAX_FRAME_RATE` set how often
that thread draws.
"""

from __future__ import annotations

import contextlib

import pyvista as pv
from vtkmodules.qt.QVTKRenderWindowInteractor import QVTKRenderWindowInteractor

__all__ = ["native_plotter", "is_software_gl", "MAX_FRAME_RATE"]

#: Most frames a second a threaded scene draws, Hz (``RenderThread.max_rate``). With a GPU: a
#: display's refresh rate. In software OpenGL (Mesa's llvmpipe) a frame of the live view costs
#: ~14 ms of CPU at 680×740 px; unlimited frames took that CPU from the data path and the
#: plots and made every view later, not fresher (docs/performance.md, "Live window").
MAX_FRAME_RATE = {"hardware": 60.0, "software": 50.0}


def is_software_gl(ren_win) -> bool:
    """True when ``ren_win``'s OpenGL renderer is a software rasterizer (llvmpipe, softpipe, swrast)."""
    try:
        caps = ren_win.ReportCapabilities().lower()
    except Exception:  # noqa: BLE001 - unknown: treat as hardware (no lower limit)
        return False
    return any(name in caps for name in ("llvmpipe", "softpipe", "swrast", "software rasterizer"))


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
    # pyvista checks once per process that a display exists (``xset -q``, else an off-screen OpenGL
    # context: 0.5 s of software GL at start-up where xset is missing) only to warn; this widget
    # lives in a Qt window on a display, so the answer is known: set pyvista's cached result
    from pyvista.plotting.plotter import _warn_xserver  # deferred: pyvista.plotting loads matplotlib

    if not hasattr(_warn_xserver, "has_support"):
        _warn_xserver.has_support = True
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

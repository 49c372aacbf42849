"""Pictures of the scene: its last frame, and a window grab with every scene's frame painted in.

A native GL window is not in ``QWidget.grab()``; screenshots and tests use :func:`grab_window`.
"""

from __future__ import annotations

from PySide6.QtGui import QImage, QPainter
from vtkmodules.util.numpy_support import vtk_to_numpy
from vtkmodules.vtkCommonDataModel import vtkImageData
from vtkmodules.vtkRenderingCore import vtkWindowToImageFilter

from ._scene import CubeScene

__all__ = ["grab_scene", "grab_window"]


def grab_scene(scene: CubeScene) -> QImage:
    """The scene's last frame as a ``QImage`` (a native GL window is not in ``QWidget.grab``)."""

    def read():  # a render and a read-back: GL calls, made where the scene draws
        f = vtkWindowToImageFilter()
        f.SetInput(scene.plotter.ren_win)
        f.SetInputBufferTypeToRGB()
        f.ReadFrontBufferOff()
        f.ShouldRerenderOn()
        f.Update()
        out = vtkImageData()
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

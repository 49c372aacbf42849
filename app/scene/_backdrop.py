"""The scene's still part drawn once and kept, colour and depth; each frame draws only the glyphs over it.

The object (core, plates, patches, face numbers, mount) changes only when the camera, the
window's size or one of its actors changes, but a frame drew it again every time: in software
GL (llvmpipe) that was ~8.5 of a live frame's ~12 ms. :class:`Backdrop` puts the contact
glyphs in a renderer of their own, a layer above the object's that keeps its depth buffer, and
copies the object's frame (colour and depth, one ``glBlitFramebuffer``) into a framebuffer of
its own after drawing it. While nothing the object's frame depends on has changed, the next
frame copies it back instead of drawing the object, then draws the glyphs, depth-tested
against it as before. The image is the same but for single pixels where a glyph meets the
object at equal depth (the glyphs now win the tie; docs/performance.md, "Live window").

What the object's frame depends on, checked before every frame (a cheap tuple of VTK
modification times): the window's size, the camera (any interaction moves it), the object
renderer and its list of props, every prop's redraw time (visibility, colour, pose, mesh) and
the lights. Any change draws the object again and keeps the new frame.

The object is drawn every frame, with the glyphs in its renderer as before, whenever the
layered image could differ from the single renderer's: a visible translucent actor (the mount
page's see-through flange: glyphs behind it must be blended under it) or a 2D overlay (a
caption is drawn over the glyphs).
"""

from __future__ import annotations

from vtkmodules.vtkCommonCore import VTK_UNSIGNED_CHAR
from vtkmodules.vtkRenderingCore import vtkActor2D
from vtkmodules.vtkRenderingOpenGL2 import vtkOpenGLFramebufferObject, vtkOpenGLRenderer

__all__ = ["Backdrop"]

_GL_READ_FRAMEBUFFER, _GL_DRAW_FRAMEBUFFER = 0x8CA8, 0x8CA9
_GL_COLOR_BUFFER_BIT, _GL_DEPTH_BUFFER_BIT = 0x4000, 0x0100
_GL_NEAREST, _GL_SCISSOR_TEST = 0x2600, 0x0C11


def _items(collection) -> list:
    """The items of a VTK collection (props, lights, renderers), in order."""
    return list(collection)


class Backdrop:
    """Keeps the object's frame (colour and depth) and restores it while it is unchanged.

    Parameters
    ----------
    plotter : pyvista plotter
        Its renderer (layer 0) draws the object; the glyphs move to a renderer on layer 1
        (:attr:`glyph_renderer`); renderers already on layer 1 (the axes) go to layer 2.
    glyph_actors : list of vtkProp
        The actors that move every frame (they leave ``plotter.renderer``). Anything else that
        changes every frame (e.g. the live-window benchmark's frame stamp) belongs in
        :attr:`glyph_renderer` too: a change in the object's renderer draws it again.

    Attributes
    ----------
    enabled : bool
        False draws the object every frame (the glyphs stay layered).
    restored, drawn : int
        Frames that restored the object's frame / drew it.
    """

    def __init__(self, plotter, glyph_actors):
        self.ren_win = plotter.ren_win
        self.renderer = plotter.renderer
        self.glyph_actors = list(glyph_actors)
        self._glyph_set = set(self.glyph_actors)
        self.enabled = True
        self.restored = 0
        self.drawn = 0
        ren, rw = self.renderer, self.ren_win
        top = max(r.GetLayer() for r in _items(rw.GetRenderers()))
        rw.SetNumberOfLayers(max(rw.GetNumberOfLayers(), top + 2, 3))
        for r in _items(rw.GetRenderers()):
            if r is not ren and r.GetLayer() >= 1:
                r.SetLayer(r.GetLayer() + 1)  # the axes stay on top of the glyphs
        g = vtkOpenGLRenderer()
        g.SetLayer(1)
        g.SetPreserveDepthBuffer(True)  # depth-tested against the object's frame (kept colour too: layer > 0)
        g.SetInteractive(False)  # the interactor's renderer stays the object's
        self._camera = ren.GetActiveCamera()
        g.SetActiveCamera(self._camera)
        g.SetAutomaticLightCreation(False)
        self._lights = _items(ren.GetLights())
        for light in self._lights:
            g.AddLight(light)  # the same headlight
        g.SetTwoSidedLighting(ren.GetTwoSidedLighting())
        g.SetLightFollowCamera(ren.GetLightFollowCamera())
        g.SetAmbient(ren.GetAmbient())
        g.SetUseOIT(ren.GetUseOIT())
        g.SetUseDepthPeeling(ren.GetUseDepthPeeling())
        g.SetUseFXAA(ren.GetUseFXAA())
        rw.AddRenderer(g)
        self.glyph_renderer = g
        props = _items(ren.GetViewProps())
        first = min((props.index(a) for a in self.glyph_actors if a in props), default=0)
        self._anchor = props[first - 1] if first > 0 else None  # the prop the glyphs followed in the object's renderer
        self._layered = False
        self._layer_glyphs(True)
        self._fbo: vtkOpenGLFramebufferObject | None = None
        self._key: tuple | None = None  # the object's state when the kept frame was drawn
        self._restore = False  # this frame restores the kept frame
        self._observers = [
            (rw, rw.AddObserver("StartEvent", self._frame_start)),
            (g, g.AddObserver("StartEvent", self._glyphs_start)),
            (ren, ren.AddObserver("ResetCameraClippingRangeEvent", self._clip_all)),
        ]

    # ------------------------------------------------------------------ layering
    def _layer_glyphs(self, layered: bool) -> None:
        """Glyphs in their own renderer (``layered``) or in the object's, as with no backdrop."""
        if layered == self._layered:
            return
        if layered:
            for a in self.glyph_actors:
                self.renderer.RemoveActor(a)
                self.glyph_renderer.AddActor(a)
        else:  # back where they were, after the props made before them: translucent ones blend in that order
            props = self.renderer.GetViewProps()
            at = props.IsItemPresent(self._anchor) if self._anchor is not None else 0  # (1-based; 0: absent)
            for j, a in enumerate(self.glyph_actors):
                self.glyph_renderer.RemoveActor(a)
                self.renderer.AddActor(a)
                props.RemoveItem(a)
                props.InsertItem(at - 1 + j, a)  # after item at - 1 + j (0-based; -1: first)
        self._layered = layered
        self._key = None

    def _layerable(self) -> bool:
        """The layered image equals the single renderer's: no visible translucent actor or 2D overlay in the object."""
        for p in _items(self.renderer.GetViewProps()):
            if p.GetVisibility() and p not in self._glyph_set and (isinstance(p, vtkActor2D) or p.HasTranslucentPolygonalGeometry()):
                return False
        return True

    def _clip_all(self, *_) -> None:
        """The camera's clipping range over the glyphs' bounds too (a single renderer's reset covered them)."""
        if not self._layered:
            return
        a = self.renderer.ComputeVisiblePropBounds()
        b = self.glyph_renderer.ComputeVisiblePropBounds()
        if b[0] > b[1]:  # no glyph shown
            return
        u = b if a[0] > a[1] else [min(a[k], b[k]) if k % 2 == 0 else max(a[k], b[k]) for k in range(6)]
        self.renderer.ResetCameraClippingRange(*u)

    # ------------------------------------------------------------------ per frame (in the drawing thread)
    def _state(self) -> tuple:
        """What the object's frame depends on (modification times; equal tuples: the same frame)."""
        ren = self.renderer
        props = ren.GetViewProps()
        return (
            tuple(self.ren_win.GetSize()),
            ren.GetActiveCamera().GetMTime(),
            ren.GetMTime(),
            props.GetMTime(),
            ren.GetLights().GetMTime(),
            *(p.GetRedrawMTime() for p in _items(props)),
            *(light.GetMTime() for light in _items(ren.GetLights())),
        )

    def _frame_start(self, *_) -> None:
        ren, g = self.renderer, self.glyph_renderer
        cam = ren.GetActiveCamera()
        if g.GetActiveCamera() is self._camera and cam is not self._camera:  # the object's camera was replaced: follow
            g.SetActiveCamera(cam)  # (not when both were: vtkWindowToImageFilter renders with copies, then deletes them)
            self._camera = cam
        lights = _items(ren.GetLights())
        if len(lights) != len(self._lights) or any(a is not b for a, b in zip(lights, self._lights)):
            g.RemoveAllLights()
            for light in lights:
                g.AddLight(light)
            self._lights = lights
        key = self._state()
        if key != self._key or not self.enabled:
            self._layer_glyphs(self._layerable())
        self._restore = self.enabled and self._layered and self._fbo is not None and key == self._key
        self.renderer.SetDraw(not self._restore)

    def _glyphs_start(self, *_) -> None:
        rw = self.ren_win
        state = rw.GetState()
        if self._restore:
            state.PushReadFramebufferBinding()
            self._fbo.Bind(_GL_READ_FRAMEBUFFER)
            self._fbo.ActivateReadBuffer(0)
            rw.BlitToRenderFramebuffer(True)  # colour and depth
            state.PopReadFramebufferBinding()
            self.renderer.SetDraw(True)
            self.restored += 1
        else:
            self.drawn += 1
            if self.enabled and self._layered:
                self._keep()
        # (taken after this frame's own change, the renderer's Draw flag; none when nothing was kept)
        self._key = self._state() if self.enabled and self._layered else None

    def _keep(self) -> None:
        """Copy the object's frame (colour and depth), just drawn, into the kept framebuffer."""
        rw = self.ren_win
        state = rw.GetState()
        w, h = rw.GetSize()
        state.PushFramebufferBindings()
        try:
            if self._fbo is None:
                self._fbo = vtkOpenGLFramebufferObject()
                self._fbo.SetContext(rw)
                # as the window's own render framebuffer: uchar RGBA, its depth format, no MSAA
                self._fbo.PopulateFramebuffer(w, h, True, 1, VTK_UNSIGNED_CHAR, True, rw.GetRenderBufferTargetDepthSize(),
                                              0, bool(rw.GetStencilCapable()))
            else:
                self._fbo.Resize(w, h)
            rw.GetRenderFramebuffer().Bind(_GL_READ_FRAMEBUFFER)
            rw.GetRenderFramebuffer().ActivateReadBuffer(0)
            self._fbo.Bind(_GL_DRAW_FRAMEBUFFER)
            self._fbo.ActivateDrawBuffer(0)
            scissor = state.GetEnumState(_GL_SCISSOR_TEST)
            state.vtkglDisable(_GL_SCISSOR_TEST)  # (a blit is clipped by the scissor box)
            state.vtkglBlitFramebuffer(0, 0, w, h, 0, 0, w, h, _GL_COLOR_BUFFER_BIT | _GL_DEPTH_BUFFER_BIT, _GL_NEAREST)
            if scissor:
                state.vtkglEnable(_GL_SCISSOR_TEST)
        finally:
            state.PopFramebufferBindings()

    def invalidate(self) -> None:
        """Draw the object again in the next frame (its state is checked anyway; for what it cannot see)."""
        self._key = None

    def release(self) -> None:
        """Free the kept framebuffer (GL: call where the window's context is current) and the observers."""
        for obj, tag in self._observers:
            obj.RemoveObserver(tag)
        self._observers = []
        if self._fbo is not None:
            self._fbo.ReleaseGraphicsResources(self.ren_win)
            self._fbo = None
        self._key = None

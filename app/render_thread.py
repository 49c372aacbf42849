"""A VTK render window drawn by a thread of its own, beside Qt's GUI thread.

Why: in software OpenGL (llvmpipe, the machines pito is measured on) a frame of the live 3D
view takes 10–20 ms of wall time, and most of it the calling thread spends *waiting* for
llvmpipe's rasterizer threads to finish the frame and for the X server to take it. Drawn in
the GUI thread, that wait came in series with everything else the GUI thread does per frame
(the plots' refresh and paint, the bundle bookkeeping), so the window drew at most ~27
frames/s although the CPUs were not saturated. Here the GUI thread only changes what the
scene shows and asks for a frame; this thread renders, and the two overlap. VTK's wrapped
calls release the interpreter lock while they run, so a render does not block Python in the
GUI thread.

The rules that make it safe (OpenGL contexts and VTK objects are not thread-safe):

- **Every GL call is made in this thread** once it runs: the window's context is released
  by the GUI thread at :meth:`RenderThread.start` and made current again in the caller's
  thread by :meth:`RenderThread.stop`. The interactor's own renders are turned off
  (``EnableRenderOff``): a paint event or a mouse drag then only asks this thread for a frame.
- **VTK objects of the window are changed in this thread, or under** :attr:`RenderThread.lock`:
  :meth:`~RenderThread.post` queues a change to run just before the next render (the GUI
  thread does not wait); :meth:`~RenderThread.call` runs one here and waits for its result
  (for rare changes: a new object, a new camera); the Qt widget's mouse, key and resize
  handlers hold the lock (:func:`app.scene.native_plotter`). The thread holds the lock while
  it runs queued changes and renders.
- Work queued with :meth:`~RenderThread.post` runs in order, before the frame it belongs to.
"""

from __future__ import annotations

import collections
import threading
import time
import traceback
from typing import Any, Callable

__all__ = ["RenderThread"]


class RenderThread:
    """Renders ``ren_win`` in a thread of its own on request.

    Parameters
    ----------
    ren_win : vtkRenderWindow
        The window (its GL context must exist: render it once in the calling thread first).
    interactor : vtkRenderWindowInteractor
        Its interactor (renders through it are turned into requests).
    name : str
        The thread's name (shown by ``py-spy``, ``top -H``).

    Attributes
    ----------
    lock : threading.RLock
        Held while the thread runs queued changes and renders; hold it to touch the window's
        VTK objects from another thread.
    visible : bool
        False skips rendering (queued changes still run): set it when the view is hidden.
    frames : int
        Frames rendered by the thread.
    max_rate : float or None
        Most frames a second (Hz; None: no limit). A request sooner after the last frame's
        start waits for its turn; then the frame waits for the next request (new data), at
        most half a frame period, so that it starts as data arrive and shows them at their
        freshest. Each frame draws the newest data, so a lower rate does not make the view
        older: it saves the CPU of frames nobody could tell apart.
    errors : list of str
        Exceptions raised by queued changes or renders (the thread keeps running); ``on_error``
        (a callable taking the message, called in this thread) is told of each too.
    """

    def __init__(self, ren_win, interactor, name: str = "pito-render"):
        self.ren_win = ren_win
        self.interactor = interactor
        self.name = name
        self.lock = threading.RLock()
        self.visible = True
        self.frames = 0
        self.max_rate: float | None = None
        self._last_start = -1e9
        self.errors: list[str] = []
        self.on_error: Callable[[str], None] | None = None
        self._jobs: collections.deque = collections.deque()
        self._wake = threading.Event()
        self._stop = False
        self._stopped = False  # stop() has run: no more changes
        self._thread: threading.Thread | None = None
        self._observer: int | None = None

    # ------------------------------------------------------------------ state
    @property
    def running(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    def in_thread(self) -> bool:
        """True when called from the render thread itself."""
        return self._thread is not None and threading.current_thread() is self._thread

    # ------------------------------------------------------------------ start and stop
    def start(self) -> None:
        """Hand the window to the thread (call in the thread that created the context)."""
        if self._thread is not None:
            return
        with self.lock:
            self.ren_win.ReleaseCurrent()
            self.interactor.EnableRenderOff()
            self._observer = self.interactor.AddObserver("RenderEvent", self._render_requested)
        self._stop = False
        self._thread = threading.Thread(target=self._run, name=self.name, daemon=True)
        self._thread.start()

    def stop(self, timeout: float = 5.0) -> None:
        """Stop the thread; the window's context is current in the caller's thread after (idempotent)."""
        th = self._thread
        if th is None:
            return
        self._stopped = True
        self._stop = True
        self._wake.set()
        th.join(timeout)
        with self.lock:  # (a thread stuck in a render past the timeout still holds it: wait)
            self._thread = None
            if self._observer is not None:
                self.interactor.RemoveObserver(self._observer)
                self._observer = None
            self.interactor.EnableRenderOn()
            self.ren_win.MakeCurrent()
            self._run_jobs()  # changes queued after the thread's last round run here

    # ------------------------------------------------------------------ requests (any thread)
    def request(self) -> None:
        """Ask for a frame (returns at once; requests made before the frame starts are one frame)."""
        if not self.in_thread():  # in the thread, a frame follows the running change anyway
            self._wake.set()

    def post(self, fn: Callable[[], Any]) -> None:
        """Run ``fn()`` in the render thread before the next frame, and ask for that frame.

        Before :meth:`start` it runs now, in the caller's thread; after :meth:`stop` it is
        dropped (the view is closing; another thread must not change its objects then).
        """
        if self._stopped:
            return
        if self._thread is None or self.in_thread():
            fn()
            return
        self._jobs.append(fn)
        self._wake.set()

    def call(self, fn: Callable[[], Any]) -> Any:
        """Run ``fn()`` in the render thread, wait for it and return its result (or raise its exception).

        Runs in the caller's thread when no thread runs, when the caller is the render thread,
        or when the caller holds :attr:`lock` (the thread could not run it: it waits for the lock).
        """
        if not self.running or self.in_thread() or self.lock._is_owned():
            return fn()
        done = threading.Event()
        box: dict = {}

        def job():
            try:
                box["value"] = fn()
            except BaseException as exc:  # noqa: BLE001 - handed back to the caller, raised there
                box["error"] = exc
            finally:
                done.set()

        self._jobs.append(job)
        self._wake.set()
        while not done.wait(1.0):
            if not self.running:  # stopped meanwhile: stop() ran the queue, or will; run it here if not
                with self.lock:
                    self._run_jobs()
        if "error" in box:
            raise box["error"]
        return box.get("value")

    def sync(self) -> None:
        """Wait until every change posted so far has run (and the frame it asked for has begun)."""
        self.call(lambda: None)

    # ------------------------------------------------------------------ the thread
    def _render_requested(self, *_):
        self.request()

    def _report(self, where: str, exc: BaseException) -> None:
        message = f"{where}: {type(exc).__name__}: {exc}"
        self.errors.append(message + "\n" + "".join(traceback.format_exception(exc))[-2000:])
        if self.on_error is not None:
            try:
                self.on_error(message)
            except Exception:  # noqa: BLE001 - a broken error hook must not end the rendering
                pass

    def _run_jobs(self) -> None:
        while self._jobs:
            fn = self._jobs.popleft()
            try:
                fn()
            except Exception as exc:  # noqa: BLE001 - reported; the view keeps drawing
                self._report("scene change", exc)

    def _run(self) -> None:
        try:
            while True:
                self._wake.wait()
                rate = self.max_rate
                if rate:
                    wait = self._last_start + 1.0 / rate - time.monotonic()
                    if wait > 0 and not self._stop:
                        time.sleep(wait)  # (changes and requests keep coming in meanwhile)
                        # what was asked meanwhile is up to a period old: start with the next request
                        self._wake.clear()
                        self._wake.wait(0.5 / rate)
                self._wake.clear()
                if self._stop:
                    break
                with self.lock:
                    self._run_jobs()
                    if not self.visible:
                        continue
                    self._last_start = time.monotonic()
                    try:
                        self.ren_win.Render()
                        self.frames += 1
                    except Exception as exc:  # noqa: BLE001 - reported; the next request tries again
                        self._report("render", exc)
        finally:
            with self.lock:
                self.ren_win.ReleaseCurrent()

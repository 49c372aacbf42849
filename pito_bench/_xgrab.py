"""Grab rectangles of an X display (libX11 and libXext through ctypes): ``(h, w, 4)`` BGRA arrays.

Used by the live-window benchmark to look at pito-app's window from outside its process.
With the MIT-SHM extension (local displays, Xvfb included) the server copies a rectangle
straight into shared memory (``XShmGetImage``): no pixels cross the X socket, and a grab of
the 3D view costs the server one copy instead of a copy, a socket transfer and a client
copy. Without it, ``XGetImage`` (~1 ms a rectangle). A whole 1600×1000 screen through
Pillow's ``ImageGrab`` costs ~30 ms, too slow to sample a 30 fps window.

The grabber shares the machine with the app it measures; what it costs is CPU the app does
not get, so it is kept small (the benchmark reports the grab rate it reached).
"""
import ctypes
import ctypes.util

import numpy as np

_x = ctypes.cdll.LoadLibrary(ctypes.util.find_library("X11"))
_xext_name = ctypes.util.find_library("Xext")
_xext = ctypes.cdll.LoadLibrary(_xext_name) if _xext_name else None
_libc = ctypes.CDLL(ctypes.util.find_library("c"), use_errno=True)


class XImage(ctypes.Structure):
    _fields_ = [("width", ctypes.c_int), ("height", ctypes.c_int), ("xoffset", ctypes.c_int),
                ("format", ctypes.c_int), ("data", ctypes.c_void_p), ("byte_order", ctypes.c_int),
                ("bitmap_unit", ctypes.c_int), ("bitmap_bit_order", ctypes.c_int), ("bitmap_pad", ctypes.c_int),
                ("depth", ctypes.c_int), ("bytes_per_line", ctypes.c_int), ("bits_per_pixel", ctypes.c_int)]


class XShmSegmentInfo(ctypes.Structure):
    _fields_ = [("shmseg", ctypes.c_ulong), ("shmid", ctypes.c_int), ("shmaddr", ctypes.c_void_p),
                ("readOnly", ctypes.c_int)]


_x.XOpenDisplay.restype = ctypes.c_void_p
_x.XOpenDisplay.argtypes = [ctypes.c_char_p]
_x.XCloseDisplay.argtypes = [ctypes.c_void_p]
_x.XDefaultRootWindow.restype = ctypes.c_ulong
_x.XDefaultRootWindow.argtypes = [ctypes.c_void_p]
_x.XDefaultScreen.argtypes = [ctypes.c_void_p]
_x.XDefaultVisual.restype = ctypes.c_void_p
_x.XDefaultVisual.argtypes = [ctypes.c_void_p, ctypes.c_int]
_x.XDefaultDepth.argtypes = [ctypes.c_void_p, ctypes.c_int]
_x.XGetImage.restype = ctypes.POINTER(XImage)
_x.XGetImage.argtypes = [ctypes.c_void_p, ctypes.c_ulong, ctypes.c_int, ctypes.c_int, ctypes.c_uint, ctypes.c_uint,
                         ctypes.c_ulong, ctypes.c_int]
_x.XDestroyImage.argtypes = [ctypes.POINTER(XImage)]
_x.XDestroyImage.restype = ctypes.c_int
_x.XSync.argtypes = [ctypes.c_void_p, ctypes.c_int]
if _xext is not None:
    _xext.XShmQueryExtension.argtypes = [ctypes.c_void_p]
    _xext.XShmCreateImage.restype = ctypes.POINTER(XImage)
    _xext.XShmCreateImage.argtypes = [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_uint, ctypes.c_int, ctypes.c_void_p,
                                      ctypes.POINTER(XShmSegmentInfo), ctypes.c_uint, ctypes.c_uint]
    _xext.XShmAttach.argtypes = [ctypes.c_void_p, ctypes.POINTER(XShmSegmentInfo)]
    _xext.XShmDetach.argtypes = [ctypes.c_void_p, ctypes.POINTER(XShmSegmentInfo)]
    _xext.XShmGetImage.argtypes = [ctypes.c_void_p, ctypes.c_ulong, ctypes.POINTER(XImage), ctypes.c_int, ctypes.c_int,
                                   ctypes.c_ulong]
_libc.shmget.argtypes = [ctypes.c_int, ctypes.c_size_t, ctypes.c_int]
_libc.shmat.restype = ctypes.c_void_p
_libc.shmat.argtypes = [ctypes.c_int, ctypes.c_void_p, ctypes.c_int]
_libc.shmdt.argtypes = [ctypes.c_void_p]
_libc.shmctl.argtypes = [ctypes.c_int, ctypes.c_int, ctypes.c_void_p]
ZPixmap = 2
AllPlanes = 0xFFFFFFFF
IPC_PRIVATE, IPC_CREAT, IPC_RMID = 0, 0o1000, 0


class _ShmRect:
    """One rectangle's shared-memory image: :meth:`grab` fills it and returns a view (no copy)."""

    def __init__(self, dpy, w: int, h: int):
        scr = _x.XDefaultScreen(dpy)
        self.dpy, self.info = dpy, XShmSegmentInfo()
        self.img = _xext.XShmCreateImage(dpy, _x.XDefaultVisual(dpy, scr), _x.XDefaultDepth(dpy, scr), ZPixmap, None,
                                         ctypes.byref(self.info), w, h)
        if not self.img:
            raise OSError("XShmCreateImage failed")
        im = self.img.contents
        size = im.bytes_per_line * im.height
        self.info.shmid = _libc.shmget(IPC_PRIVATE, size, IPC_CREAT | 0o600)
        if self.info.shmid < 0:
            raise OSError(ctypes.get_errno(), "shmget failed")
        addr = _libc.shmat(self.info.shmid, None, 0)
        _libc.shmctl(self.info.shmid, IPC_RMID, None)  # freed when both sides detach, even after a crash
        if addr in (None, ctypes.c_void_p(-1).value):
            raise OSError(ctypes.get_errno(), "shmat failed")
        self.info.shmaddr = addr
        im.data = addr
        self.info.readOnly = 0
        if not _xext.XShmAttach(dpy, ctypes.byref(self.info)):
            raise OSError("XShmAttach failed")
        _x.XSync(dpy, 0)
        buf = (ctypes.c_ubyte * size).from_address(addr)
        self.view = np.frombuffer(buf, dtype=np.uint8).reshape(im.height, im.bytes_per_line)[:, : 4 * w].reshape(h, w, 4)

    def grab(self, root, x: int, y: int) -> np.ndarray:
        if not _xext.XShmGetImage(self.dpy, root, self.img, int(x), int(y), AllPlanes):
            raise OSError("XShmGetImage failed")
        return self.view

    def close(self) -> None:
        _xext.XShmDetach(self.dpy, ctypes.byref(self.info))
        _x.XSync(self.dpy, 0)
        _libc.shmdt(self.info.shmaddr)


class Grabber:
    """A connection to ``display`` (e.g. ``":57"``); :meth:`grab` one rectangle (px).

    ``shm``: use MIT-SHM when the server has it (default); :attr:`uses_shm` says whether it does.
    With shared memory, the array :meth:`grab` returns is overwritten by the next grab of a
    rectangle of the same size: copy it to keep it.
    """

    def __init__(self, display: str, shm: bool = True):
        self.dpy = _x.XOpenDisplay(display.encode())
        if not self.dpy:
            raise OSError(f"cannot open X display {display}")
        self.root = _x.XDefaultRootWindow(self.dpy)
        self.uses_shm = bool(shm and _xext is not None and _xext.XShmQueryExtension(self.dpy))
        self._shm: dict[tuple[int, int], _ShmRect] = {}

    def grab(self, x, y, w, h) -> np.ndarray:
        if self.uses_shm:
            key = (int(w), int(h))
            if key not in self._shm:
                self._shm[key] = _ShmRect(self.dpy, *key)
            return self._shm[key].grab(self.root, x, y)
        img = _x.XGetImage(self.dpy, self.root, int(x), int(y), int(w), int(h), AllPlanes, ZPixmap)
        if not img:
            raise OSError("XGetImage failed")
        im = img.contents
        buf = (ctypes.c_ubyte * (im.bytes_per_line * im.height)).from_address(im.data)
        a = np.frombuffer(buf, dtype=np.uint8).reshape(im.height, im.bytes_per_line)[:, : 4 * im.width]
        out = a.reshape(im.height, im.width, 4).copy()
        _x.XDestroyImage(img)
        return out

    def close(self) -> None:
        for r in self._shm.values():
            r.close()
        self._shm.clear()
        if self.dpy:
            _x.XCloseDisplay(self.dpy)
            self.dpy = None

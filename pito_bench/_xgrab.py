"""Grab rectangles of an X display with ``XGetImage`` (libX11 through ctypes): ``(h, w, 4)`` BGRA arrays.

Used by the live-window benchmark to look at pito-app's window from outside its process. A
rectangle costs ~1 ms (a whole 1600×1000 screen through Pillow's ``ImageGrab`` costs ~30 ms,
too slow to sample a 30 fps window).
"""
import ctypes
import ctypes.util

import numpy as np

_x = ctypes.cdll.LoadLibrary(ctypes.util.find_library("X11"))


class XImage(ctypes.Structure):
    _fields_ = [("width", ctypes.c_int), ("height", ctypes.c_int), ("xoffset", ctypes.c_int),
                ("format", ctypes.c_int), ("data", ctypes.c_void_p), ("byte_order", ctypes.c_int),
                ("bitmap_unit", ctypes.c_int), ("bitmap_bit_order", ctypes.c_int), ("bitmap_pad", ctypes.c_int),
                ("depth", ctypes.c_int), ("bytes_per_line", ctypes.c_int), ("bits_per_pixel", ctypes.c_int)]


_x.XOpenDisplay.restype = ctypes.c_void_p
_x.XOpenDisplay.argtypes = [ctypes.c_char_p]
_x.XDefaultRootWindow.restype = ctypes.c_ulong
_x.XDefaultRootWindow.argtypes = [ctypes.c_void_p]
_x.XGetImage.restype = ctypes.POINTER(XImage)
_x.XGetImage.argtypes = [ctypes.c_void_p, ctypes.c_ulong, ctypes.c_int, ctypes.c_int, ctypes.c_uint, ctypes.c_uint,
                         ctypes.c_ulong, ctypes.c_int]
_x.XDestroyImage.argtypes = [ctypes.POINTER(XImage)]
_x.XDestroyImage.restype = ctypes.c_int
ZPixmap = 2
AllPlanes = 0xFFFFFFFF


class Grabber:
    """A connection to ``display`` (e.g. ``":57"``); :meth:`grab` one rectangle (px)."""

    def __init__(self, display: str):
        self.dpy = _x.XOpenDisplay(display.encode())
        if not self.dpy:
            raise OSError(f"cannot open X display {display}")
        self.root = _x.XDefaultRootWindow(self.dpy)

    def grab(self, x, y, w, h) -> np.ndarray:
        img = _x.XGetImage(self.dpy, self.root, int(x), int(y), int(w), int(h), AllPlanes, ZPixmap)
        if not img:
            raise OSError("XGetImage failed")
        im = img.contents
        buf = (ctypes.c_ubyte * (im.bytes_per_line * im.height)).from_address(im.data)
        a = np.frombuffer(buf, dtype=np.uint8).reshape(im.height, im.bytes_per_line)[:, : 4 * im.width]
        out = a.reshape(im.height, im.width, 4).copy()
        _x.XDestroyImage(img)
        return out

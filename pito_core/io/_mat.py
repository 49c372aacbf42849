"""A MATLAB v5 ``.mat`` file written column block by column block, in bounded memory.

Why our own writer: ``scipy.io.savemat`` takes whole arrays, so an hour's recording (3.6·10⁶ rows
of 36 gauges) would be held in memory two or three times over. A v5 file stores each matrix
column-major at a known offset once its size is known, so rows can be written as they are read
(one seek per column and block). The file is uncompressed (a compressed v5 element is one zlib
stream of the whole matrix, which cannot be written by rows); ``scipy.io.loadmat`` and MATLAB
read it. Format: MathWorks, "MAT-File Format" (Level 5), the header, tags and array flags.
"""

from __future__ import annotations

import struct

import numpy as np

__all__ = ["Mat5Writer"]

# data types (mi*) and array classes (mx*) of the v5 format
_MI = {np.dtype("int8"): 1, np.dtype("uint8"): 2, np.dtype("int16"): 3, np.dtype("uint16"): 4,
       np.dtype("int32"): 5, np.dtype("uint32"): 6, np.dtype("float32"): 7, np.dtype("float64"): 9,
       np.dtype("int64"): 12, np.dtype("uint64"): 13}
_MX = {np.dtype("int8"): 8, np.dtype("uint8"): 9, np.dtype("int16"): 10, np.dtype("uint16"): 11,
       np.dtype("int32"): 12, np.dtype("uint32"): 13, np.dtype("float32"): 7, np.dtype("float64"): 6,
       np.dtype("int64"): 14, np.dtype("uint64"): 15}
_MI_MATRIX, _MI_UINT32, _MI_INT32, _MI_INT8, _MI_UTF8 = 14, 6, 5, 1, 16
_MX_CHAR = 4
_LIMIT = 2**32 - 1  # an element's byte count is a uint32


def _pad(n: int) -> int:
    return (8 - n % 8) % 8


class _Matrix:
    """Where one matrix's data lie in the file: ``(rows, cols)``, dtype, first data byte."""

    def __init__(self, name: str, shape: tuple[int, int], dtype: np.dtype, at: int):
        self.name, self.shape, self.dtype, self.at = name, shape, dtype, at


class Mat5Writer:
    """Write a v5 ``.mat`` file: declare each matrix's shape, then fill it by row blocks.

    Parameters
    ----------
    fh : binary file opened for writing (``"w+b"``), positioned at 0.
    text : str
        The header's descriptive text (≤ 116 ASCII characters).

    Examples
    --------
    >>> w = Mat5Writer(fh, "pito recording")          # doctest: +SKIP
    >>> counts = w.matrix("pito_counts", (n, 36), np.int32)
    >>> w.fill(counts, 0, block)                      # rows 0 .. len(block) - 1
    >>> w.close()
    """

    def __init__(self, fh, text: str):
        self.fh = fh
        head = text.encode("ascii", "replace")[:116].ljust(116, b" ")
        fh.write(head + b"\0" * 8 + struct.pack("<H", 0x0100) + b"IM")
        self.end = 128

    def _element(self, name: str, mx: int, shape: tuple[int, int], mi: int, nbytes: int) -> int:
        """Write a matrix element's tag and sub-elements; return the byte where its data go."""
        if nbytes > _LIMIT - 64:
            raise ValueError(f"{name}: {nbytes} bytes is beyond a MATLAB v5 variable's 4 GiB; "
                             "export a recording this long to NWB or CSV")
        bname = name.encode("ascii")
        sub = (struct.pack("<II", _MI_UINT32, 8) + struct.pack("<BBxxI", mx, 0, 0)
               + struct.pack("<II", _MI_INT32, 8) + struct.pack("<ii", *shape)
               + struct.pack("<II", _MI_INT8, len(bname)) + bname + b"\0" * _pad(len(bname))
               + struct.pack("<II", mi, nbytes))
        size = len(sub) + nbytes + _pad(nbytes)
        self.fh.seek(self.end)
        self.fh.write(struct.pack("<II", _MI_MATRIX, size) + sub)
        at = self.end + 8 + len(sub)
        self.end = self.end + 8 + size
        return at

    def matrix(self, name: str, shape: tuple[int, int], dtype) -> _Matrix:
        """Declare an ``(rows, cols)`` matrix of ``dtype``; its values are zero until filled."""
        dtype = np.dtype(dtype)
        if dtype not in _MX:
            raise ValueError(f"{name}: dtype {dtype} has no MATLAB v5 class here")
        rows, cols = (int(v) for v in shape)
        at = self._element(name, _MX[dtype], (rows, cols), _MI[dtype], rows * cols * dtype.itemsize)
        return _Matrix(name, (rows, cols), dtype, at)

    def fill(self, m: _Matrix, start: int, block) -> None:
        """Rows ``start .. start + len(block) − 1`` of ``m`` from ``block`` ``(n,)`` or ``(n, cols)``."""
        b = np.asarray(block, dtype=m.dtype).reshape(-1, m.shape[1])
        rows, cols = m.shape
        if start < 0 or start + b.shape[0] > rows:
            raise ValueError(f"{m.name}: rows {start}..{start + b.shape[0]} outside 0..{rows}")
        size = m.dtype.itemsize
        for j in range(cols):  # column-major: one contiguous run per column
            self.fh.seek(m.at + (j * rows + start) * size)
            self.fh.write(np.ascontiguousarray(b[:, j]).tobytes())

    def value(self, name: str, value) -> None:
        """A whole small matrix: a number, a 1-D or 2-D array, or a string (``char``, one row)."""
        if isinstance(value, str):
            data = value.encode("utf-8")  # as scipy.io.savemat: UTF-8 bytes, one row of len(value) characters
            at = self._element(name, _MX_CHAR, (1, len(value)), _MI_UTF8, len(data))
            self.fh.seek(at)
            self.fh.write(data)
            return
        a = np.asarray(value)
        if a.ndim > 2:
            raise ValueError(f"{name}: expected a number, a 1-D or a 2-D array")
        a = a.reshape(1, 1) if a.ndim == 0 else a.reshape(-1, 1) if a.ndim == 1 else a
        m = self.matrix(name, a.shape, a.dtype)
        self.fill(m, 0, a)

    def close(self) -> None:
        """Size the file to its last element (matrices never filled stay zero)."""
        self.fh.truncate(self.end)
        self.fh.flush()

"""Work-arounds for defects of the Qt bindings, applied once at import of :mod:`app`.

PySide6 6.12.0 drops one reference to ``True`` at every ``Signal.emit`` (measured: the
refcount of ``True`` falls by exactly one per emit). CPython ≥ 3.12 makes ``True``,
``False`` and ``None`` immortal, so nothing happens there; on 3.11 the interpreter aborts
with "bool_dealloc: deallocating True or False" after a few thousand emits — seconds of a
live display. The fix here probes for the leak and, only if it is present on a CPython
without immortal objects, gives those three singletons a reference count no program can
exhaust (what CPython 3.12 does for them).
"""

from __future__ import annotations

import sys

__all__ = ["signal_emit_leaks", "protect_singletons"]

_PROTECTED = False


def signal_emit_leaks(n: int = 64) -> bool:
    """Whether ``Signal.emit`` leaks references to ``True``/``False``/``None`` (probe of ``n`` emits)."""
    from PySide6.QtCore import QObject, Signal

    class _Probe(QObject):
        sig = Signal(object)

    p = _Probe()
    p.sig.connect(lambda _x: None)
    before = [sys.getrefcount(o) for o in (True, False, None)]
    for _ in range(n):
        p.sig.emit(p)
    after = [sys.getrefcount(o) for o in (True, False, None)]
    # give back what the probe took
    _bump(n, [max(0, b - a) for b, a in zip(before, after)])
    return any(b - a >= n // 2 for b, a in zip(before, after))


def _bump(n, deltas) -> None:
    import ctypes

    for obj, d in zip((True, False, None), deltas):
        if d:
            ctypes.c_ssize_t.from_address(id(obj)).value += d


def protect_singletons() -> bool:
    """Apply the fix if needed; returns whether it was applied."""
    global _PROTECTED
    if _PROTECTED or sys.version_info >= (3, 12) or sys.implementation.name != "cpython":
        return _PROTECTED
    if not signal_emit_leaks():
        return False
    _bump(1, [1 << 40] * 3)
    _PROTECTED = True
    return True

"""``ContactEstimate``: the one contact record, from the solver to the glyphs and the exports.

:func:`~pito_core.contact.solve` gives one per patch (a batch of wrenches in the patch's
face frame); :func:`~pito_core.contact.solve_object` one per object (the same fields with a
face axis, in the core frame); the pipeline's bundles, the app's glyphs and every export
read it.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, fields

import numpy as np

__all__ = ["ContactEstimate", "CONTACT_FRAMES"]


class _Deferred:
    """An array field computed on its first read: its ``shape`` now, its values from ``make()`` once.

    ``solve`` decides ``single_contact`` at once and leaves ``single_contact_p`` to this (the
    p-values cost more than the decision; most callers never read them). ``make`` works on
    copies the solve took, so later writes into the estimate's arrays do not change it.
    Indexing and ``reshape`` stay deferred; anything else reads the values (``np.asarray``).
    """

    __slots__ = ("shape", "_make", "_value", "__weakref__")

    def __init__(self, shape, make):
        self.shape = tuple(shape)
        self._make = make
        self._value = None

    def value(self) -> np.ndarray:
        if self._make is not None:
            self._value = self._make()
            self._make = None  # drop the copies it held
        return self._value

    @property
    def ndim(self) -> int:
        return len(self.shape)

    def __len__(self) -> int:
        return self.shape[0]

    def map(self, fn, shape) -> _Deferred:
        """The deferred ``fn(values)`` of shape ``shape``."""
        return _Deferred(shape, lambda: fn(self.value()))

    def __getitem__(self, index) -> _Deferred:
        shape = np.broadcast_to(np.empty((), np.int8), self.shape)[index].shape  # no copy but a mask's
        return self.map(lambda v: v[index], shape)

    def reshape(self, shape) -> _Deferred:
        shape = tuple(int(k) for k in shape)
        if -1 in shape:
            rest = int(np.prod([k for k in shape if k != -1]))
            shape = tuple(int(np.prod(self.shape)) // max(rest, 1) if k == -1 else k for k in shape)
        if int(np.prod(shape)) != int(np.prod(self.shape)):
            raise ValueError(f"cannot reshape an array of shape {self.shape} into shape {shape}")
        return self.map(lambda v: v.reshape(shape), shape)

    def __array__(self, dtype=None, copy=None):
        return np.asarray(self.value(), dtype=dtype)

    def __reduce__(self):  # pickled (e.g. to a Dask client) as its values
        return (np.asarray, (self.value(),))


class _CopyPool:
    """Float buffers for the copies a deferred field keeps, reused once it no longer needs them.

    A solve that defers its p-values keeps a copy of what they are computed from; taken from
    fresh memory every time, its pages cost more than the copy (and a heap that grows and
    shrinks by it every call faults on the solve's own arrays too). A buffer comes back here
    when its deferred values are read or the deferred field is gone (``weakref.finalize``);
    at most ``keep`` buffers of at most ``largest`` floats (32 MB) wait here.
    """

    def __init__(self, keep: int = 2, largest: int = 1 << 22):
        self._free: list = []
        self._lock = threading.Lock()
        self.keep, self.largest = keep, largest

    def take(self, size: int) -> np.ndarray:
        """A buffer of ``size`` floats (a free one at most twice that size, else a new one)."""
        with self._lock:
            fits = [i for i, b in enumerate(self._free) if size <= len(b) <= 2 * size + 4096]
            if fits:
                return self._free.pop(min(fits, key=lambda i: len(self._free[i])))[:size]
        return np.empty(size)

    def give(self, buf: np.ndarray) -> None:
        base = buf if buf.base is None else buf.base
        if len(base) > self.largest:
            return
        with self._lock:
            if len(self._free) >= self.keep:
                self._free.pop(0)
            self._free.append(base)


#: the copies of deferred p-values (``_solve._deferred_p``)
COPIES = _CopyPool()


def _values(v):
    """``v``'s values: a deferred field read, anything else as it is."""
    return v.value() if isinstance(v, _Deferred) else v


#: The frames a :class:`ContactEstimate` can be in: ``"face"`` (``solve``: the frame of the
#: wrenches, a face frame) and ``"core"`` (``solve_object``: the core frame, with a face axis).
CONTACT_FRAMES = ("face", "core")


@dataclass
class ContactEstimate:
    """Contacts estimated from a batch of wrenches.

    Every array field has the batch shape ``B`` in front: ``solve`` gives ``B`` = the
    wrenches' leading shape (``(N,)``; ``()`` for one wrench), in the frame of the wrenches
    (``frame = "face"``); ``solve_object`` gives ``B = (..., 6)``, the face axis last
    (face i at index i − 1), in the core frame (``frame = "core"``). docs/conventions.md
    names the frames.

    Attributes
    ----------
    point : ndarray, shape B + (3,)
        Contact point, m (NaN where not valid).
    normal : ndarray, shape B + (3,)
        Outward unit normal of the surface at the contact.
    force : ndarray, shape B + (3,)
        Force applied by the finger on the object, N (``force · normal < 0``).
    torsion : ndarray, shape B
        Moment about the normal at the contact, N·m (0 for ``point_contact``).
    valid : ndarray of bool, shape B
        A pushing contact on the patch exists and the force exceeds the threshold.
    point_cov : ndarray, shape B + (3, 3), or None
        Cramér–Rao covariance of ``point`` (m²) when a ``wrench_cov`` was given.
    force_cov : ndarray, shape B + (3, 3), or None
        Cramér–Rao covariance of ``force`` (N²).
    torsion_var : ndarray, shape B, or None
        Cramér–Rao variance of ``torsion`` ((N·m)²).
    facet : ndarray of int, shape B, or None
        Mesh facet holding the contact (−1 where not valid or the face's patch is not a
        mesh); None when no patch is a mesh.
    single_contact : ndarray of bool, shape B, or None
        One soft-finger contact on the patch can produce the measured wrench within its
        noise (pushing, inside the friction limit surface, on the patch; for
        ``point_contact`` also the χ² residual). False where there is no force. Trust a
        contact where ``valid & single_contact`` (:meth:`flagged` gives the rest). See
        ``docs/contact.md``.
    single_contact_p : ndarray, shape B, or None
        The score deciding it, in [0, 1]: the smallest p-value over the single contact's
        limits (``Φ(margin / σ)`` per limit; with ``point_contact`` also ``P(χ²₁ ≥ r²)`` for
        the residual, and the smallest is doubled, capped at 1: Bonferroni);
        ``single_contact = single_contact_p >= alpha`` (default 0.05). NaN where no force.
        ``solve`` computes it on the first read (the decision ``single_contact`` needs only
        the limits' signs on most rows; the p-values cost more than the decision).
    single_contact_reason : ndarray of int8, shape B, or None
        :class:`SingleContactReason` code of the failing limit: 0 ``NONE`` (plausible),
        1 ``NO_FORCE``, 2 ``NO_SOLUTION``, 3 ``OUTSIDE``, 4 ``PULLING``, 5 ``FRICTION``,
        6 ``TORSION``, 7 ``RESIDUAL``; ``reason_names`` gives the short names.
    frame : str
        ``"face"`` or ``"core"`` (:data:`CONTACT_FRAMES`).

    The three ``single_contact*`` fields are None only in records made without the test
    (``solve(..., single_contact=False)``, or built by hand for display).
    """

    point: np.ndarray
    normal: np.ndarray
    force: np.ndarray
    torsion: np.ndarray
    valid: np.ndarray
    point_cov: np.ndarray | None = None
    force_cov: np.ndarray | None = None
    torsion_var: np.ndarray | None = None
    facet: np.ndarray | None = None
    single_contact: np.ndarray | None = None
    single_contact_p: np.ndarray | None = None
    single_contact_reason: np.ndarray | None = None
    frame: str = "face"

    def __post_init__(self):
        if self.frame not in CONTACT_FRAMES:
            raise ValueError(f"frame: expected one of {CONTACT_FRAMES}, got {self.frame!r}")

    def _arrays(self):
        """``(name, array or None)`` of every array field (a deferred ``single_contact_p`` not read)."""
        return ((name, self.__dict__[_P_STORE] if name == "single_contact_p" else getattr(self, name))
                for name in _ARRAY_FIELDS)

    def flagged(self) -> np.ndarray:
        """Bool, shape B: valid contacts that one fingertip cannot explain (False without the test)."""
        if self.single_contact is None:
            return np.zeros(np.shape(self.valid), bool)
        return np.asarray(self.valid) & ~np.asarray(self.single_contact)

    def __getitem__(self, index) -> ContactEstimate:
        """The estimate at ``index`` of the leading batch axes (e.g. ``c[-1]``: the last sample's six faces).

        ``index`` is applied to the front of every array (an int, a slice, a mask, or a
        tuple of them); it never reaches the vector axes.
        """
        return ContactEstimate(**{k: None if v is None else v[index] for k, v in self._arrays()}, frame=self.frame)

    @staticmethod
    def concatenate(estimates) -> ContactEstimate:
        """Estimates of the same frame joined along their first batch axis (blocks of samples, in order).

        A field None in one of them is None in the result.
        """
        estimates = list(estimates)
        if not estimates:
            raise ValueError("estimates: expected at least one ContactEstimate")
        frame = estimates[0].frame
        if any(e.frame != frame for e in estimates):
            raise ValueError(f"estimates: expected one frame, got {sorted({e.frame for e in estimates})}")
        out = {}
        for k, _ in estimates[0]._arrays():
            parts = [getattr(e, k) for e in estimates]
            out[k] = None if any(p is None for p in parts) else np.concatenate(parts)
        return ContactEstimate(**out, frame=frame)

    def _reshape(self, lead: tuple) -> ContactEstimate:
        """The estimate of a flat batch ``(N,)`` with batch shape ``lead`` instead."""
        return ContactEstimate(**{k: None if v is None else v.reshape(lead + v.shape[1:]) for k, v in self._arrays()},
                               frame=self.frame)


#: the array fields of :class:`ContactEstimate`, in order (all but ``frame``)
_ARRAY_FIELDS = tuple(f.name for f in fields(ContactEstimate) if f.name != "frame")
#: where ``single_contact_p`` keeps its array or its :class:`_Deferred` values
_P_STORE = "_single_contact_p"


def _get_p(self):
    v = self.__dict__[_P_STORE]
    if isinstance(v, _Deferred):
        v = self.__dict__[_P_STORE] = v.value()
    return v


def _set_p(self, v):
    self.__dict__[_P_STORE] = v


# a property in place of the plain field, set after the dataclass is made (the generated __init__
# assigns through it; a property in the class body would be taken for the field's default)
ContactEstimate.single_contact_p = property(_get_p, _set_p, doc="See the class docstring (read on first access).")

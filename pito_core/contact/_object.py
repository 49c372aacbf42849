"""``solve_object``: contacts on every face of an assembly, in the core frame."""

from __future__ import annotations

import weakref
from functools import lru_cache

import numpy as np

from ..frames import FACES, check_vectors
from ._crb import check_wrench_cov
from ._estimate import ContactEstimate, _Deferred
from ._patches import Assembly, load_assembly
from ._solve import DEFAULT_FORCE_THRESHOLD, _check_threshold, _solve_patches

__all__ = ["solve_object"]


@lru_cache(maxsize=16)
def _library_assembly(name: str) -> Assembly:
    """Library assemblies by name, loaded once (a live solver calls ``solve_object`` per tick)."""
    return load_assembly(name)


def solve_object(assembly, face_wrenches, force_threshold=DEFAULT_FORCE_THRESHOLD, *,
                 point_contact=False, wrench_cov=None, single_contact: bool = True) -> ContactEstimate:
    """Contacts on all six patches of an object, expressed in the core frame.

    Parameters
    ----------
    assembly : Assembly or str
        The object, or a library assembly name (loaded once and cached).
    face_wrenches : array-like, shape (..., 6, 6)
        Wrench on each face in that face's frame, ``[:, i-1, :]`` for face i,
        ``[fx, fy, fz, tx, ty, tz]`` N and N·m (as ``Calibration.wrenches``). NaN rows
        (faces without output) give no contact.
    force_threshold : float
        Minimum force in N for a contact.
    point_contact : bool
        Use the point-contact (``τ = 0``) estimate.
    wrench_cov : array-like, shape (6, 6), (6, 6, 6) or (..., 6, 6, 6), optional
        Wrench noise covariance (face frames; N², N²·m, N²·m²): shared, per face, or per
        sample and face as ``Calibration.wrenches(counts, return_cov=True)`` returns it
        (leading shape that of ``face_wrenches``). Faces whose covariance is NaN (no
        output) get no covariance.
    single_contact : bool
        Run the single-contact test (default); False leaves its three fields None.

    Returns
    -------
    ContactEstimate
        ``frame = "core"``; fields of shape ``(..., 6, …)`` with the leading shape of
        ``face_wrenches``, face i at index i − 1: points (m) and vectors in the core frame,
        covariances rotated to it.
    """
    if isinstance(assembly, str):
        assembly = _library_assembly(assembly)
    if not isinstance(assembly, Assembly):
        raise ValueError(f"assembly: expected an Assembly or a library name, got {type(assembly).__name__}")
    w = check_vectors(face_wrenches, 6, "face_wrenches")
    if w.ndim < 2 or w.shape[-2] != 6:
        raise ValueError(f"face_wrenches: expected shape (..., 6, 6), got {w.shape}")
    lead = w.shape[:-2]
    covs = None if wrench_cov is None else _face_covs(wrench_cov, lead)
    thr = _check_threshold(force_threshold)
    flat = w.reshape((-1, 6, 6))
    M = len(flat)
    poses, groups = _layout(assembly)
    blocks = [flat.reshape(-1, 6) if len(faces) == 6  # one patch on every face (the bare cube): the rows as they lie
              else flat[:, faces[0] if len(faces) == 1 else faces, :].reshape(-1, 6)  # (M·k, 6), sample-major
              for _, faces in groups]
    covs = None if covs is None else [_group_cov(covs, faces, M) for _, faces in groups]
    est = _solve_patches([patch for patch, _ in groups], blocks, thr, covs, point_contact, single_contact)
    return _to_core(_by_face(est, [faces for _, faces in groups], M), poses, lead)


def _by_face(est: ContactEstimate, faces: list, M: int) -> dict:
    """The face-frame fields of the groups' rows one after the other, ``(Σ M·k, …)``, as ``{name: (M, 6, …)}``.

    Facets are −1 on the faces whose patch is not a mesh (None if no patch is one).
    """
    order = [i for f in faces for i in f]  # the face of each column, groups side by side
    inv = None if order == sorted(order) else np.argsort(order)
    spans, start = [], 0  # each group's rows
    for f in faces:
        spans.append((start, start + M * len(f), len(f)))
        start += M * len(f)

    def arrange(v):
        if len(faces) == 1:
            a = v.reshape((M, 6) + v.shape[1:])
        else:
            a = np.concatenate([v[i:j].reshape((M, k) + v.shape[1:]) for i, j, k in spans], axis=1)
        return a if inv is None else a[:, inv]

    out = {}
    for name, v in est._arrays():
        if v is not None:  # a deferred field (single_contact_p) stays deferred
            out[name] = v.map(arrange, (M, 6) + v.shape[1:]) if isinstance(v, _Deferred) else arrange(v)
    return out


def _to_core(out: dict, poses: tuple, lead: tuple) -> ContactEstimate:
    """Face-frame fields ``(M, 6, …)`` → a core-frame :class:`ContactEstimate` of batch shape ``lead + (6,)``."""
    R, t = poses  # (6, 3, 3), (6, 3): T_core_face of every face
    out["point"] = _rotate(out["point"], R)
    out["point"] += t
    out["normal"] = _rotate(out["normal"], R)
    out["force"] = _rotate(out["force"], R)
    Rt = np.swapaxes(R, 1, 2)
    for k in ("point_cov", "force_cov"):
        if k in out:
            out[k] = R @ out[k] @ Rt
    return ContactEstimate(**{k: v.reshape(lead + v.shape[1:]) for k, v in out.items()}, frame="core")


def _rotate(x, R) -> np.ndarray:
    """``x_core = R_f x_face`` of vectors ``x (M, 6, 3)`` with every face's rotation ``R (6, 3, 3)``.

    Component by component (``(x0 R_k0 + x2 R_k2) + x1 R_k1``: einsum's arithmetic here, a
    quarter of its time); a cube's face rotations are signed permutations, so the result is
    exact whatever the order.
    """
    out = np.empty(x.shape)
    x0, x1, x2 = x[..., 0], x[..., 1], x[..., 2]
    for k in range(3):
        o = out[..., k]
        np.multiply(x0, R[:, k, 0], out=o)
        o += x2 * R[:, k, 2]
        o += x1 * R[:, k, 1]
    return out


def _face_covs(wrench_cov, lead: tuple) -> np.ndarray:
    """Every face's wrench covariance, checked once: ``(6, 6, 6)``, or ``(6, M, 6, 6)`` per sample.

    A face whose covariance is NaN throughout (no output: its wrenches are NaN, no contact)
    gets the identity.
    """
    covs = np.asarray(wrench_cov, dtype=float)
    if covs.shape == (6, 6):
        covs = np.broadcast_to(covs, (6, 6, 6))
    elif covs.shape == lead + (6, 6, 6) and lead:  # per sample and face (Calibration.wrenches)
        covs = np.moveaxis(covs.reshape((-1, 6, 6, 6)), 1, 0)  # (6, M, 6, 6)
    elif covs.shape != (6, 6, 6):
        raise ValueError(f"wrench_cov: expected shape (6, 6), (6, 6, 6) or {lead + (6, 6, 6)}, got {covs.shape}")
    absent = np.isnan(covs).reshape(6, -1).all(axis=1)
    if absent.any():
        covs = covs.copy()
        covs[absent] = np.eye(6)
    flat = covs.reshape(-1, 6, 6)
    check_wrench_cov(flat, len(flat))
    return covs


def _group_cov(covs, faces: list, M: int):
    """The covariance of a group's rows ``(M·k, 6)``: shared ``(6, 6)`` if the faces share one, else per row."""
    if covs is None:
        return None
    per = covs[faces]  # (k, 6, 6) or (k, M, 6, 6)
    if per.ndim == 3 and (per == per[0]).all():
        return per[0]
    per = np.broadcast_to(per, (M,) + per.shape) if per.ndim == 3 else np.swapaxes(per, 0, 1)  # (M, k, 6, 6)
    return per.reshape(-1, 6, 6)


def _params(obj) -> tuple:
    """A hashable key of an object's parameters: arrays and numbers by value, anything else by identity."""
    if obj is None:
        return (None,)
    key = [type(obj)]
    for name, v in sorted(vars(obj).items()):
        if isinstance(v, np.ndarray):
            key.append((name, v.dtype.str, v.shape, v.tobytes()))
        elif v is None or isinstance(v, (int, float, str, bool)):
            key.append((name, v))
        else:
            key.append((name, id(v)))
    return tuple(key)


def _face_groups(assembly: Assembly) -> list:
    """``(patch, [face index, ...])``: faces whose patches solve alike (same surface, boundary, friction).

    One ``solve`` per group instead of one per face: the live view solves the six faces of one
    sample per display tick, where numpy's per-call cost, not the arithmetic, dominates.
    """
    groups: dict = {}
    for i in FACES:
        p = assembly.patches[i]
        if hasattr(p, "surface") and hasattr(p, "boundary"):
            key = (_params(p.surface), _params(p.boundary), p.mu, p.torsion_radius)
        else:
            key = (id(p),)
        groups.setdefault(key, (p, []))[1].append(i - 1)
    return list(groups.values())


#: assembly → (what its layout was made from, (face rotations and origins, face groups))
_LAYOUTS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _layout(assembly: Assembly) -> tuple:
    """``((R (6, 3, 3), t (6, 3)), groups)`` of an assembly: made again when its core or a patch changes."""
    made_from = [assembly.core]
    for p in (assembly.patches[i] for i in FACES):
        made_from += [p, *(getattr(p, k, None) for k in ("surface", "boundary", "mu", "torsion_radius"))]
    got = _LAYOUTS.get(assembly)
    if got is not None and all(a is b or (type(a) is float and a == b) for a, b in zip(got[0], made_from)):
        return got[1]
    T = np.stack([assembly.core.face_pose(i) for i in FACES])  # T_core_face
    layout = ((T[:, :3, :3].copy(), T[:, :3, 3].copy()), _face_groups(assembly))
    _LAYOUTS[assembly] = (made_from, layout)
    return layout

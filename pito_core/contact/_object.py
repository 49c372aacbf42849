"""``solve_object``: contacts on every face of an assembly, in the core frame."""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from ..frames import FACES, check_vectors
from ._estimate import ContactEstimate
from ._patches import Assembly, load_assembly
from ._solve import DEFAULT_FORCE_THRESHOLD, solve

__all__ = ["solve_object"]


@lru_cache(maxsize=16)
def _library_assembly(name: str) -> Assembly:
    """Library assemblies by name, loaded once (a live solver calls ``solve_object`` per tick)."""
    return load_assembly(name)


def solve_object(assembly, face_wrenches, force_threshold=DEFAULT_FORCE_THRESHOLD, *,
                 point_contact=False, wrench_cov=None) -> ContactEstimate:
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
    covs = None
    if wrench_cov is not None:
        covs = np.asarray(wrench_cov, dtype=float)
        if covs.shape == (6, 6):
            covs = np.broadcast_to(covs, (6, 6, 6))
        elif covs.shape == lead + (6, 6, 6) and lead:  # per sample and face (Calibration.wrenches)
            covs = np.moveaxis(covs.reshape((-1, 6, 6, 6)), 1, 0)  # (6, M, 6, 6)
        elif covs.shape != (6, 6, 6):
            raise ValueError(f"wrench_cov: expected shape (6, 6), (6, 6, 6) or {lead + (6, 6, 6)}, got {covs.shape}")
    flat = w.reshape((-1, 6, 6))
    M = len(flat)
    face_frame = {}
    for patch, faces in _face_groups(assembly):
        rows = flat[:, faces, :].reshape(-1, 6)  # (M·k, 6), sample-major: rows are solved independently
        est = solve(patch, rows, force_threshold, point_contact=point_contact,
                    wrench_cov=_group_cov(covs, faces, M))
        for j, i in enumerate(faces):
            face_frame[i] = est[j::len(faces)] if len(faces) > 1 else est
    per_face = []
    for i in FACES:
        est = face_frame[i - 1]
        T = assembly.core.face_pose(i)  # T_core_face
        R, t = T[:3, :3], T[:3, 3]
        est.point = np.einsum("ij,kj->ik", est.point, R) + t
        est.normal = np.einsum("ij,kj->ik", est.normal, R)
        est.force = np.einsum("ij,kj->ik", est.force, R)
        for k in ("point_cov", "force_cov"):
            if getattr(est, k) is not None:
                setattr(est, k, R @ getattr(est, k) @ R.T)
        per_face.append(est)
    return _stack_faces(per_face, lead)


def _face_cov(covs, i: int):
    """Face index ``i``'s wrench covariance ``(6, 6)`` or ``(M, 6, 6)`` (None without one)."""
    if covs is None:
        return None
    cov_i = covs[i]
    if np.isnan(cov_i).all():
        cov_i = np.broadcast_to(np.eye(6), (6, 6))  # a face without output: NaN wrenches, no contact
    return cov_i


def _group_cov(covs, faces: list, M: int):
    """The covariance of a group's rows ``(M·k, 6)``: shared ``(6, 6)`` if the faces share one, else per row."""
    per = [_face_cov(covs, i) for i in faces]
    if per[0] is None:
        return None
    if all(c.ndim == 2 and np.array_equal(c, per[0]) for c in per):
        return per[0]
    return np.stack([np.broadcast_to(c, (M, 6, 6)) for c in per], axis=1).reshape(-1, 6, 6)


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


def _stack_faces(per_face: list, lead: tuple) -> ContactEstimate:
    """Six core-frame estimates of ``M`` samples → one of shape ``lead + (6, …)`` (``lead`` flattens to M)."""
    res = {}
    for k, _ in per_face[0]._arrays():
        v = [getattr(e, k) for e in per_face]
        if all(a is None for a in v):
            res[k] = None
            continue
        if k == "facet":  # faces whose patch is not a mesh: no facet
            v = [np.full(len(per_face[0].valid), -1, np.intp) if a is None else a for a in v]
        a = np.stack(v, axis=1)  # (M, 6, ...)
        res[k] = a.reshape(lead + a.shape[1:])
    return ContactEstimate(**res, frame="core")

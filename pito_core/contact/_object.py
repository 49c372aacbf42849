"""``solve_object``: contacts on every face of an assembly, in the core frame."""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from ..frames import FACES, check_vectors
from ._patches import Assembly, load_assembly
from ._solve import DEFAULT_FORCE_THRESHOLD, solve

__all__ = ["ObjectContacts", "solve_object"]


@dataclass
class ObjectContacts:
    """Up to six contacts (one per face), core frame. Face i at index ``i − 1``.

    Attributes
    ----------
    point : ndarray, shape (..., 6, 3)
        Contact points, m (NaN where not valid).
    normal : ndarray, shape (..., 6, 3)
        Outward unit normals.
    force : ndarray, shape (..., 6, 3)
        Finger forces, N.
    torsion : ndarray, shape (..., 6)
        Torsion about the normal, N·m.
    valid : ndarray, shape (..., 6), bool
    point_cov : ndarray, shape (..., 6, 3, 3) or None
        Cramér–Rao covariance of the points, m² (when ``wrench_cov`` is given).
    single_contact : ndarray, shape (..., 6), bool, or None
        One fingertip on that face's patch can produce its wrench within the noise
        (``ContactEstimate.single_contact``; False where no force). Trust a contact where
        ``valid & single_contact``.
    single_contact_p : ndarray, shape (..., 6), or None
        The p-value in [0, 1] that decides it (NaN where no force).
    single_contact_reason : ndarray, shape (..., 6), int8, or None
        ``SingleContactReason`` code (0 plausible, 1 no force, 2 no solution, 3 outside,
        4 pulling, 5 friction, 6 torsion, 7 residual).

    The three ``single_contact*`` fields are None only in records made without the test
    (e.g. built by hand for display).
    """

    point: np.ndarray
    normal: np.ndarray
    force: np.ndarray
    torsion: np.ndarray
    valid: np.ndarray
    point_cov: np.ndarray | None = None
    single_contact: np.ndarray | None = None
    single_contact_p: np.ndarray | None = None
    single_contact_reason: np.ndarray | None = None

    def flagged(self) -> np.ndarray:
        """``(..., 6)`` bool: valid contacts that one fingertip cannot explain (False without the test)."""
        if self.single_contact is None:
            return np.zeros(np.shape(self.valid), bool)
        return np.asarray(self.valid) & ~np.asarray(self.single_contact)


@lru_cache(maxsize=16)
def _library_assembly(name: str) -> Assembly:
    """Library assemblies by name, loaded once (a live solver calls ``solve_object`` per tick)."""
    return load_assembly(name)


def solve_object(assembly, face_wrenches, force_threshold=DEFAULT_FORCE_THRESHOLD, *,
                 point_contact=False, wrench_cov=None) -> ObjectContacts:
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
    ObjectContacts
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
    out = {k: [] for k in ("point", "normal", "force", "torsion", "valid", "point_cov", "single_contact",
                           "single_contact_p", "single_contact_reason")}
    for i in FACES:
        cov_i = None if covs is None else covs[i - 1]
        if cov_i is not None and np.isnan(cov_i).all():
            cov_i = np.broadcast_to(np.eye(6), (6, 6))  # a face without output: NaN wrenches, no contact
        est = solve(assembly.patches[i], w[..., i - 1, :].reshape(-1, 6), force_threshold,
                    point_contact=point_contact, wrench_cov=cov_i)
        T = assembly.core.face_pose(i)
        R, t = T[:3, :3], T[:3, 3]
        out["point"].append(np.einsum("ij,kj->ik", est.point, R) + t)
        out["normal"].append(np.einsum("ij,kj->ik", est.normal, R))
        out["force"].append(np.einsum("ij,kj->ik", est.force, R))
        out["torsion"].append(est.torsion)
        out["valid"].append(est.valid)
        out["single_contact"].append(est.single_contact)
        out["single_contact_p"].append(est.single_contact_p)
        out["single_contact_reason"].append(est.single_contact_reason)
        if est.point_cov is not None:
            out["point_cov"].append(R @ est.point_cov @ R.T)
    res = {}
    for k, v in out.items():
        if not v:
            res[k] = None
            continue
        a = np.stack(v, axis=1)  # (M, 6, ...)
        res[k] = a.reshape(lead + a.shape[1:])
    return ObjectContacts(**res)

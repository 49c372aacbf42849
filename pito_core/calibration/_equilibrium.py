"""Equilibrium of a free grasp: the sum of the faces' wrenches against the object's weight."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..frames import invert_pose, wrench_adjoint

__all__ = ["Equilibrium", "equilibrium"]


@dataclass
class Equilibrium:
    """Equilibrium of a free grasp, per sample (SI units).

    Attributes
    ----------
    force_sum : ndarray (N, 3)
        ΣF_i of the loads on the faces, core frame, N.
    force_sum_norm : ndarray (N,)
        ‖ΣF_i‖, N — equals the weight ``m g`` in quasi-static equilibrium.
    weight : float
        ``m g``, N.
    torque_cog : ndarray (N, 3)
        ΣT_i about the centre of gravity, core frame, N·m.
    torque_cog_norm : ndarray (N,)
        ‖ΣT_i‖ about the centre of gravity, N·m — zero in quasi-static equilibrium.
    """

    force_sum: np.ndarray
    force_sum_norm: np.ndarray
    weight: float
    torque_cog: np.ndarray
    torque_cog_norm: np.ndarray


def equilibrium(face_wrenches, core, mass, cog=(0.0, 0.0, 0.0), g=9.81) -> Equilibrium:
    """Equilibrium check of a free grasp from the wrench on each face.

    Parameters
    ----------
    face_wrenches : array-like, shape (N, 6, 6)
        Wrench on each face in face frames, N and N·m (NaN faces are skipped).
    core : CubeCore
    mass : float
        Mass of the object (core + patches), kg.
    cog : array-like, shape (3,)
        Centre of gravity in the core frame, m.
    g : float
        Gravitational acceleration, m/s².

    Returns
    -------
    Equilibrium
    """
    W = np.asarray(face_wrenches, dtype=float)
    if W.ndim != 3 or W.shape[1:] != (6, 6):
        raise ValueError(f"face_wrenches: expected shape (N, 6, 6), got {W.shape}")
    if not float(mass) > 0:
        raise ValueError(f"mass: expected a positive mass in kg, got {mass!r}")
    cog = np.asarray(cog, dtype=float)
    if cog.shape != (3,):
        raise ValueError(f"cog: expected shape (3,), got {cog.shape}")
    T_cog = np.eye(4)
    T_cog[:3, 3] = cog
    # wrench in face frame -> frame at the cog with core axes: T_face_cog = inv(T_core_face) @ T_core_cog
    X = np.stack([wrench_adjoint(invert_pose(T) @ T_cog) for T in core.face_poses()])
    total = np.einsum("fij,nfj->ni", X, np.nan_to_num(W))
    return Equilibrium(
        force_sum=total[:, :3],
        force_sum_norm=np.linalg.norm(total[:, :3], axis=1),
        weight=float(mass) * g,
        torque_cog=total[:, 3:],
        torque_cog_norm=np.linalg.norm(total[:, 3:], axis=1),
    )

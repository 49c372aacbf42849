"""Cramér–Rao covariance of the contact estimate under Gaussian wrench noise.

Parameters of the soft-finger model, per sample: two tangent coordinates ``θ`` of the
contact point on the surface (``dc = T dθ``, ``T = [t1 t2]`` orthonormal tangents at
``c``), the force ``f`` (3) and the torsion ``τ`` (1). The modelled wrench is
``w = [f, c × f + τ n(c)]``; its Jacobian (6 × 6, columns ``θ1, θ2, fx, fy, fz, τ``) is

    ∂w/∂θj = [0, tj × f + τ S tj],   ∂w/∂f = [I, [c]×],   ∂w/∂τ = [0, n],

with ``S`` the shape operator (``dn = S dc``; 0 on a plane or a facet, ``(I − nnᵀ)/r``
on a sphere, ``(I − nnᵀ) A / |A p|`` on an ellipsoid). With wrench noise covariance
``Σ`` the Fisher information is ``Jᵀ Σ⁻¹ J``. For the soft-finger model ``J`` is square,
so the bound is ``J⁻¹ Σ J⁻ᵀ`` (reached by the closed-form solution at small noise). For
the point-contact model (``τ = 0`` known) the last column is dropped and the bound is
``(Jᵀ Σ⁻¹ J)⁻¹`` (5 × 5, reached by the weighted least-squares estimate). The covariance
of the point is ``T Cov_θθ Tᵀ`` (3 × 3, rank 2, in the tangent plane).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._quadric import _cross
from ._surfaces import tangent_basis

__all__ = ["ContactCovariance", "wrench_jacobian", "covariance_from_jacobian", "check_wrench_cov"]


@dataclass
class ContactCovariance:
    """Cramér–Rao covariances of one batch of contacts (same frame as the inputs).

    Attributes
    ----------
    point_cov : ndarray, shape (N, 3, 3)
        Covariance of the contact point, m².
    force_cov : ndarray, shape (N, 3, 3)
        Covariance of the force, N².
    torsion_var : ndarray, shape (N,)
        Variance of the torsion, (N·m)² (0 for the point-contact model).
    param_cov : ndarray, shape (N, 6, 6) or (N, 5, 5)
        Full covariance of ``[θ1, θ2, fx, fy, fz(, τ)]`` (tangent coordinates in m).
    tangents : ndarray, shape (N, 3, 2)
        The tangent basis ``T`` the coordinates ``θ`` refer to.
    """

    point_cov: np.ndarray
    force_cov: np.ndarray
    torsion_var: np.ndarray
    param_cov: np.ndarray
    tangents: np.ndarray


def check_wrench_cov(wrench_cov, n: int) -> np.ndarray:
    """Validate a wrench noise covariance: ``(6, 6)`` or ``(N, 6, 6)``, symmetric, PSD."""
    S = np.asarray(wrench_cov, dtype=float)
    if S.shape != (6, 6) and S.shape != (n, 6, 6):
        raise ValueError(f"wrench_cov: expected shape (6, 6) or ({n}, 6, 6), got {S.shape}")
    if not np.all(np.isfinite(S)):
        raise ValueError("wrench_cov: expected finite values, got NaN or inf")
    St = np.swapaxes(S, -1, -2)
    if not (np.abs(S - St) <= 1e-9 * np.abs(St)).all():  # np.allclose(S, Sᵀ, rtol=1e-9, atol=0) of finite S
        raise ValueError("wrench_cov: expected a symmetric matrix")
    if np.any(np.linalg.eigvalsh(S) <= 0):
        raise ValueError("wrench_cov: expected a positive definite matrix (N², (N·m)²)")
    return S


def wrench_jacobian(point, normal, shape_op, force, torsion, point_contact=False):
    """Jacobian of the modelled wrench with respect to the contact parameters.

    Parameters
    ----------
    point, normal, force : ndarray, shape (N, 3)
        Contact point (m), outward unit normal, force (N), in the wrench's frame.
    shape_op : ndarray, shape (N, 3, 3)
        Shape operator ``S`` (``dn = S dc``), 1/m.
    torsion : ndarray, shape (N,)
        Torsion about the normal, N·m (ignored if ``point_contact``).
    point_contact : bool
        Drop the torsion column (``τ = 0`` known).

    Returns
    -------
    J : ndarray, shape (N, 6, 6) or (N, 6, 5)
        Rows ``[fx, fy, fz, tx, ty, tz]``, columns ``[θ1, θ2, fx, fy, fz(, τ)]``.
    T : ndarray, shape (N, 3, 2)
        Tangent basis.
    """
    N = len(point)
    T = tangent_basis(normal)
    k = 5 if point_contact else 6
    J = np.zeros((N, 6, k))
    for j in range(2):
        t = T[:, :, j]
        col = _cross(t, force)
        if not point_contact:
            col += torsion[:, None] * np.einsum("nab,nb->na", shape_op, t)
        J[:, 3:, j] = col
    J[:, 0, 2] = J[:, 1, 3] = J[:, 2, 4] = 1.0
    cx, cy, cz = point[:, 0], point[:, 1], point[:, 2]
    # d(c × f)/df = [c]×
    J[:, 3, 3], J[:, 3, 4] = -cz, cy
    J[:, 4, 2], J[:, 4, 4] = cz, -cx
    J[:, 5, 2], J[:, 5, 3] = -cy, cx
    if not point_contact:
        J[:, 3:, 5] = normal
    return J, T


def _safe_inv(M: np.ndarray) -> np.ndarray:
    try:
        return np.linalg.inv(M)
    except np.linalg.LinAlgError:  # a singular sample (e.g. tangent force): pseudo-inverse
        return np.linalg.pinv(M)


def covariance_from_jacobian(J, T, wrench_cov) -> ContactCovariance:
    """Cramér–Rao covariances from the Jacobian ``J`` and the noise ``wrench_cov``.

    ``J (N, 6, 6)`` gives ``J⁻¹ Σ J⁻ᵀ``; ``J (N, 6, 5)`` gives ``(Jᵀ Σ⁻¹ J)⁻¹``.
    Rows with non-finite ``J`` get NaN.
    """
    N, _, k = J.shape
    finite = np.isfinite(J).all(axis=(1, 2))
    all_finite = finite.all()
    Jf = J if all_finite else np.where(finite[:, None, None], J, _EYE6[:, :k])
    S = np.broadcast_to(wrench_cov, (N, 6, 6))
    if k == 6:
        Ji = _safe_inv(Jf)
        C = Ji @ S @ np.swapaxes(Ji, 1, 2)
    else:
        W = _safe_inv(S) if wrench_cov.ndim == 3 else np.linalg.inv(wrench_cov)
        Fi = np.swapaxes(Jf, 1, 2) @ W @ Jf
        C = _safe_inv(Fi)
    C = 0.5 * (C + np.swapaxes(C, 1, 2))
    if not all_finite:
        C[~finite] = np.nan
    Tq = T if all_finite else np.where(finite[:, None, None], T, np.nan)
    point_cov = Tq @ C[:, :2, :2] @ np.swapaxes(Tq, 1, 2)
    torsion_var = C[:, 5, 5] if k == 6 else np.where(finite, 0.0, np.nan)
    return ContactCovariance(point_cov, C[:, 2:5, 2:5].copy(), torsion_var, C, Tq)


#: the 6 × 6 identity (stands in for a non-finite Jacobian)
_EYE6 = np.eye(6)

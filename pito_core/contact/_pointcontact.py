"""Point-contact estimate (``τ = 0`` known): weighted least squares on all six equations.

With ``τ = 0`` the model ``w = [f, c × f]`` has five parameters (two on the surface, the
force) for six measurements. Under Gaussian wrench noise of covariance ``Σ`` the maximum
likelihood estimate minimises ``(w − ŵ)ᵀ Σ⁻¹ (w − ŵ)``. We start from the closed-form
soft-finger solution (exact on noise-free data, within the noise otherwise) and take a
fixed number of vectorised Gauss–Newton steps over ``[θ1, θ2, f]`` (tangent steps are
mapped back onto the surface by the surface's retraction). The estimate reaches the
Cramér–Rao bound ``(Jᵀ Σ⁻¹ J)⁻¹`` at small noise (tested by Monte Carlo).
"""

from __future__ import annotations

import numpy as np

from ._crb import wrench_jacobian
from ._quadric import _cross

__all__ = ["refine_point_contact", "DEFAULT_WRENCH_COV"]

#: Noise covariance assumed by the point-contact estimate when none is given:
#: 1 N² on forces, (0.01 m · 1 N)² on moments (a moment arm of 1 cm).
DEFAULT_WRENCH_COV = np.diag([1.0, 1.0, 1.0, 1e-4, 1e-4, 1e-4])

#: Gauss–Newton steps (quadratic convergence from a start within the noise).
GN_ITERATIONS = 6


def refine_point_contact(c, f, w, W, normal_fn, retract_fn, iterations=GN_ITERATIONS):
    """Weighted least-squares point contact from a start ``c, f``.

    Parameters
    ----------
    c, f : ndarray, shape (N, 3)
        Starting contact point (m, on the surface) and force (N). Rows must be finite.
    w : ndarray, shape (N, 6)
        Measured wrenches ``[fx, fy, fz, tx, ty, tz]``, N and N·m.
    W : ndarray, shape (6, 6) or (N, 6, 6)
        Inverse of the wrench noise covariance.
    normal_fn, retract_fn : callable
        ``(N, 3) -> (N, 3)``: outward unit normal at surface points; map a point near
        the surface onto it.

    Returns
    -------
    c, n, f : ndarray, shape (N, 3)
        Contact point (m), outward normal, force (N).
    """
    c = c.copy()
    f = f.copy()
    N = len(c)
    zeros_S = np.zeros((N, 3, 3))
    zeros_tau = np.zeros(N)
    for _ in range(iterations):
        n = normal_fn(c)
        J, T = wrench_jacobian(c, n, zeros_S, f, zeros_tau, point_contact=True)
        e = w.copy()
        e[:, :3] -= f
        e[:, 3:] -= _cross(c, f)
        JtW = np.swapaxes(J, 1, 2) @ W
        H = JtW @ J
        b = np.einsum("nij,nj->ni", JtW, e)
        try:
            step = np.linalg.solve(H, b[:, :, None])[:, :, 0]
        except np.linalg.LinAlgError:
            step = np.einsum("nij,nj->ni", np.linalg.pinv(H), b)
        f += step[:, 2:5]
        c = retract_fn(c + np.einsum("nij,nj->ni", T, step[:, :2]))
    return c, normal_fn(c), f

"""Where the Cramér–Rao bound cannot be reached: a normal force within the noise, exact ambiguity (mesh).

The CRB is a local, small-noise bound. Two scenarios of the contact benchmark leave its
regime, and these functions measure by how much:

* **Normal force within the noise.** On a plane the moments fix only the products
  ``x f_n`` and ``y f_n``: the point is a ratio whose denominator, the normal force, is
  measured with Gaussian noise. The contacts ``(c/k, k f_n, τ')`` (``τ'`` absorbing the
  change of ``m_z``) give wrenches that differ only in ``f_n``, by ``|k − 1| f_n ≤ f_n``,
  while ``|c/k − c|`` grows without bound as ``k → 0``: the Hammersley–Chapman–Robbins
  bound ``sup_k |Δc|² / (exp(d_k²) − 1)``, ``d_k = |k − 1| f_n / σ_n``, is infinite. No unbiased
  estimator of the point has a finite variance; the tail that makes it so has a
  probability of order ``exp(−(f_n/σ_n)²/2)``, invisible in a finite run when ``f_n ≫ σ_n``
  and dominant when ``f_n`` is a few σ. ``normal_snr_split`` gives the share of samples
  below 5 σ and the error ratio on the others.
* **Mesh, two exact solutions.** A facet's plane gives an exact soft-finger solution for
  any wrench; when two facets' solutions both lie inside their triangles and push, two
  different contacts give the same wrench: no estimator can tell them apart and none is
  unbiased. We count those samples by brute force over all facets and give the error
  ratio on the others.
"""

from __future__ import annotations

import numpy as np

__all__ = ["normal_snr_split", "mesh_exact_solutions", "ratio_ci", "plane_second_order_ratio", "facet_of"]


def facet_of(surface, point) -> np.ndarray:
    """Index ``(n,)`` of the mesh facet closest to each of ``point (n, 3)`` (m): a true contact's facet."""
    import trimesh  # deferred: ~0.1 s to load, and this module loads with `pito --help`

    _, _, tri = trimesh.proximity.closest_point(surface.mesh, np.asarray(point, float))
    return np.asarray(tri, int)


def ratio_ci(sq_err, crb_tr, seed=0, n_boot=400, level=0.95) -> tuple[float, float]:
    """Percentile-bootstrap interval of ``sqrt(mean sq_err) / sqrt(mean crb_tr)`` over samples.

    Parameters
    ----------
    sq_err, crb_tr : ndarray, shape (n,)
        Squared point errors (m²) and CRB traces (m²) of the same samples (resampled together).
    n_boot : int
        Bootstrap resamples. ``level`` is the two-sided coverage.

    Returns
    -------
    (lo, hi) : floats, the interval of the error/CRB ratio (NaN if fewer than 2 samples).
    """
    sq_err, crb_tr = np.asarray(sq_err, float), np.asarray(crb_tr, float)
    n = len(sq_err)
    if n < 2:
        return float("nan"), float("nan")
    idx = np.random.default_rng(seed).integers(0, n, (n_boot, n))
    r = np.sqrt(sq_err[idx].mean(axis=1) / crb_tr[idx].mean(axis=1))
    a = (1 - level) / 2
    return float(np.quantile(r, a)), float(np.quantile(r, 1 - a))


def plane_second_order_ratio(surface, c, f, cov) -> tuple[np.ndarray, np.ndarray]:
    """The plane's closed-form (maximum-likelihood) point error to fourth order in the noise.

    On a plane with unit normal ``n`` and offset ``d = n · p`` the soft-finger model is exactly
    determined, and its unique solution is ``ĉ = (n × m + d f) / (f · n) = (N + ν) / (D + δ)``
    with ``(ν, δ)`` linear in the Gaussian wrench noise. With ``u = ν − c δ`` (tangent),
    ``ĉ − c = u / (D + δ)`` and, expanding ``1 / (1 + δ/D)`` and taking Gaussian moments
    (``E[|u|² δ] = 0``, ``E[|u|² δ²] = E|u|² σ_δ² + 2 |Cov(u, δ)|²``),

    ``E|ĉ − c|² = E|u|²/D² · (1 + 3 σ_δ²/D²) + 6 |Cov(u, δ)|²/D⁴ + O(σ⁶)``,

    whose first term ``E|u|²/D²`` is the CRB trace. Returns ``(mse (n,), crb (n,))``, m².
    """
    nrm, d = surface.normal, float(surface.normal @ surface.point)
    nx = np.array([[0, -nrm[2], nrm[1]], [nrm[2], 0, -nrm[0]], [-nrm[1], nrm[0], 0]])
    P = np.c_[d * np.eye(3), nx]  # ν = P ε  (3, 6)
    q = np.r_[nrm, 0, 0, 0]  # δ = q · ε
    D = f @ nrm
    var_d = float(q @ cov @ q)
    cov_nd = P @ cov @ q  # Cov(ν, δ) (3,)
    Snn = P @ cov @ P.T
    # u = ν − c δ:  E|u|² = tr Σνν − 2 c·Cov(ν, δ) + |c|² σ_δ²;  Cov(u, δ) = Cov(ν, δ) − c σ_δ²
    Euu = np.trace(Snn) - 2 * c @ cov_nd + np.sum(c * c, axis=1) * var_d
    cud = cov_nd[None] - c * var_d
    crb = Euu / D**2
    mse = crb * (1 + 3 * var_d / D**2) + 6 * np.sum(cud * cud, axis=1) / D**4
    return mse, crb

def normal_snr_split(est_point, c, f, nrm, crb_tr, ok, sigma_n, snr=5.0) -> dict:
    """Share of samples whose normal force is below ``snr`` σ of its noise, and the error ratio on the rest."""
    fn = -np.einsum("ij,ij->i", f, nrm)
    strong = fn >= snr * sigma_n
    keep = ok & strong
    if not keep.any():
        return {"share_fn_below_5sigma": float(1.0 - strong.mean()), "crb_ratio_fn_5sigma": float("nan")}
    sq = np.sum((est_point[keep] - c[keep]) ** 2, axis=1)
    return {"share_fn_below_5sigma": float(1.0 - strong.mean()),
            "crb_ratio_fn_5sigma": float(np.sqrt(np.mean(sq) / np.mean(crb_tr[keep]))),
            "crb_ratio_fn_5sigma_ci": ratio_ci(sq, crb_tr[keep])}


def mesh_exact_solutions(surface, w, chunk=256) -> np.ndarray:
    """Number of facets ``(n,)`` whose exact soft-finger solution of ``w (n, 6)`` is inside and pushes."""
    tri = np.asarray(surface.mesh.triangles, dtype=float)
    nrm = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    dd = np.einsum("jk,jk->j", nrm, tri[:, 0])
    e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    g11, g12, g22 = (e1 * e1).sum(1), (e1 * e2).sum(1), (e2 * e2).sum(1)
    det = g11 * g22 - g12**2
    out = np.zeros(len(w), int)
    for s in range(0, len(w), chunk):
        f, m = w[s:s + chunk, :3], w[s:s + chunk, 3:]
        fn = f @ nrm.T  # (b, J)
        with np.errstate(divide="ignore", invalid="ignore"):
            c = (np.cross(nrm[None], m[:, None]) + dd[None, :, None] * f[:, None]) / fn[..., None]
        q = c - tri[None, :, 0]
        b1, b2 = (q * e1).sum(-1), (q * e2).sum(-1)
        u = (g22 * b1 - g12 * b2) / det
        v = (g11 * b2 - g12 * b1) / det
        tol = 1e-9
        ok = (fn < 0) & (u >= -tol) & (v >= -tol) & (u + v <= 1 + tol)
        out[s:s + chunk] = ok.sum(1)
    return out

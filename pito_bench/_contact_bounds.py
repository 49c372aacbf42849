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

__all__ = ["normal_snr_split", "mesh_exact_solutions"]

def normal_snr_split(est_point, c, f, nrm, crb_tr, ok, sigma_n, snr=5.0) -> dict:
    """Share of samples whose normal force is below ``snr`` σ of its noise, and the error ratio on the rest."""
    fn = -np.einsum("ij,ij->i", f, nrm)
    strong = fn >= snr * sigma_n
    keep = ok & strong
    if not keep.any():
        return {"share_fn_below_5sigma": float(1.0 - strong.mean()), "crb_ratio_fn_5sigma": float("nan")}
    err = np.sqrt(np.mean(np.sum((est_point[keep] - c[keep]) ** 2, axis=1)))
    return {"share_fn_below_5sigma": float(1.0 - strong.mean()),
            "crb_ratio_fn_5sigma": float(err / np.sqrt(np.mean(crb_tr[keep])))}


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

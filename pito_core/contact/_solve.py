"""``solve``: one entry point over every surface, and the ``ContactEstimate`` it returns."""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from ..defaults import IDENTIFY_FORCE_N
from ..frames import check_vectors
from ._crb import ContactCovariance, check_wrench_cov, covariance_from_jacobian, wrench_jacobian
from ._pointcontact import DEFAULT_WRENCH_COV, refine_point_contact
from ._quadric import solve_ellipsoid, solve_plane, solve_sphere
from ._surfaces import Ellipsoid, MeshSurface, Plane, Sphere, Surface

__all__ = ["ContactEstimate", "solve", "contact_crb", "DEFAULT_FORCE_THRESHOLD"]

#: Forces below this magnitude (N) give no contact (``valid = False``); ``pito_core.defaults``.
DEFAULT_FORCE_THRESHOLD = IDENTIFY_FORCE_N


@dataclass
class ContactEstimate:
    """Contacts estimated from a batch of wrenches (frame of the wrenches).

    Attributes
    ----------
    point : ndarray, shape (N, 3)
        Contact point, m (NaN where not valid).
    normal : ndarray, shape (N, 3)
        Outward unit normal of the surface at the contact.
    force : ndarray, shape (N, 3)
        Force applied by the finger, N (``force · normal < 0``).
    torsion : ndarray, shape (N,)
        Moment about the normal at the contact, N·m (0 for ``point_contact``).
    valid : ndarray, shape (N,), bool
        A pushing contact on the patch exists and the force exceeds the threshold.
    point_cov : ndarray, shape (N, 3, 3) or None
        Cramér–Rao covariance of ``point`` (m²) when a ``wrench_cov`` was given.
    force_cov : ndarray, shape (N, 3, 3) or None
        Cramér–Rao covariance of ``force`` (N²).
    torsion_var : ndarray, shape (N,) or None
        Cramér–Rao variance of ``torsion`` ((N·m)²).
    facet : ndarray, shape (N,), int or None
        Mesh facet holding the contact (−1 where not valid); None for analytic surfaces.

    A single ``(6,)`` wrench gives the same fields without the leading N.
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

    def _reshape(self, lead: tuple) -> ContactEstimate:
        out = {}
        for fld in fields(self):
            v = getattr(self, fld.name)
            out[fld.name] = None if v is None else v.reshape(lead + v.shape[1:])
        return ContactEstimate(**out)


def _check_surface(surface):
    boundary = None
    if hasattr(surface, "surface") and hasattr(surface, "boundary"):  # a Patch
        boundary = surface.boundary
        surface = surface.surface
    if not isinstance(surface, Surface):
        raise ValueError(
            f"surface: expected a Plane, Sphere, Ellipsoid, MeshSurface or Patch, "
            f"got {type(surface).__name__}"
        )
    return surface, boundary


def _check_threshold(force_threshold) -> float:
    try:
        t = float(force_threshold)
    except (TypeError, ValueError):
        raise ValueError(f"force_threshold: expected a force >= 0 in N, got {force_threshold!r}") from None
    if not np.isfinite(t) or t < 0:
        raise ValueError(f"force_threshold: expected a force >= 0 in N, got {force_threshold!r}")
    return t


def _solve_surface(surface, f, m):
    """Closed-form (or exact mesh) soft-finger solve: ``c, n, tau, ok, facet``."""
    if isinstance(surface, Plane):
        return (*solve_plane(f, m, surface.point, surface.normal), None)
    if isinstance(surface, Sphere):
        return (*solve_sphere(f, m, surface.center, surface.radius), None)
    if isinstance(surface, Ellipsoid):
        return (*solve_ellipsoid(f, m, surface.center, surface.semi_axes, surface.rotation), None)
    if isinstance(surface, MeshSurface):
        return surface._index.solve(f, m)
    raise ValueError(f"surface: unsupported surface type {type(surface).__name__}")


def solve(
    surface,
    wrench,
    force_threshold=DEFAULT_FORCE_THRESHOLD,
    *,
    point_contact: bool = False,
    wrench_cov=None,
    boundary=None,
) -> ContactEstimate:
    """Contact point, normal, force and torsion from the wrench on a patch.

    Soft-finger model (Bicchi, Salisbury & Brock): ``m = c × f + τ n(c)`` with the finger
    pushing into the surface (``f · n < 0``). Never raises on data: rows without a
    contact get ``valid = False`` and NaN fields.

    Parameters
    ----------
    surface : Plane, Sphere, Ellipsoid, MeshSurface or Patch
        The patch surface in the wrench's (face) frame. A ``Patch`` also supplies its
        boundary.
    wrench : array-like, shape (..., 6)
        ``[fx, fy, fz, tx, ty, tz]`` in N and N·m, moment about the frame origin.
        NaN rows are allowed (no contact).
    force_threshold : float
        Minimum force magnitude in N for a contact.
    point_contact : bool
        Assume ``τ = 0`` and use the six equations' redundancy (weighted least squares
        with ``wrench_cov``, or ``DEFAULT_WRENCH_COV`` if None).
    wrench_cov : array-like, shape (6, 6) or (N, 6, 6), optional
        Wrench noise covariance (N², N²·m, (N·m)²). If given, the Cramér–Rao covariances
        ``point_cov``, ``force_cov``, ``torsion_var`` are filled in.
    boundary : PatchBoundary, optional
        Contacts outside it are not valid (default: the patch's own, if any).

    Returns
    -------
    ContactEstimate
        Fields of shape ``(..., 3)``, ``(...,)`` (and ``(..., 3, 3)`` covariances).
    """
    surface, patch_boundary = _check_surface(surface)
    if boundary is None:
        boundary = patch_boundary
    thr = _check_threshold(force_threshold)
    w = check_vectors(wrench, 6, "wrench")
    lead = w.shape[:-1]
    w = w.reshape(-1, 6)
    N = len(w)
    S = None if wrench_cov is None else check_wrench_cov(wrench_cov, N)

    f_all = w[:, :3]
    m_all = w[:, 3:]
    f2 = np.einsum("ij,ij->i", f_all, f_all)
    strong = f2 >= max(thr * thr, 1e-300)  # NaN rows are False
    all_strong = bool(strong.all())
    if N and not strong.any():  # nobody pushes on this patch (most faces, most of the time): nothing to solve
        out = _assemble(N, strong, False, *_NO_ROWS, np.empty(0, bool),
                        np.empty(0, np.intp) if isinstance(surface, MeshSurface) else None,
                        None if S is None else ContactCovariance(*_NO_COV))
        return out if len(lead) == 1 else out._reshape(lead)
    f = f_all if all_strong else f_all[strong]
    m = m_all if all_strong else m_all[strong]

    c, n, tau, ok, facet = _solve_surface(surface, np.ascontiguousarray(f), np.ascontiguousarray(m))
    force = f.copy()
    if point_contact and len(c):
        sel = np.flatnonzero(ok)
        if len(sel):
            ws = (w if all_strong else w[strong])[sel]
            Wn = np.linalg.inv(S if S is not None else DEFAULT_WRENCH_COV)
            if Wn.ndim == 3:
                Wn = (Wn if all_strong else Wn[strong])[sel]
            if isinstance(surface, MeshSurface):
                nf = n[sel]
                normal_fn = lambda p: nf  # noqa: E731 - the facet's plane
                retract_fn = lambda p: p  # noqa: E731 - tangent steps stay on it
            else:
                normal_fn, retract_fn = surface._normal, surface._retract
            with np.errstate(invalid="ignore", divide="ignore"):
                cs, ns, fs = refine_point_contact(c[sel], f[sel], ws, Wn, normal_fn, retract_fn)
            c[sel], n[sel], force[sel] = cs, ns, fs
            ok[sel] &= np.einsum("ij,ij->i", fs, ns) < 0  # still pushing in
        tau = np.zeros(len(c))
    if boundary is not None and len(c):
        ok &= boundary._contains(c)
    ok &= np.isfinite(c).all(axis=1)

    cov = None
    if S is not None:
        Ss = S if S.ndim == 2 or all_strong else S[strong]
        with np.errstate(invalid="ignore", divide="ignore"):  # NaN rows stay NaN
            shape = surface._shape_operator(c, n)
            J, T = wrench_jacobian(c, n, shape, force, tau, point_contact=point_contact)
            J[~ok] = np.nan
            cov = covariance_from_jacobian(J, T, Ss)

    out = _assemble(N, strong, all_strong, c, n, force, tau, ok, facet, cov)
    if len(lead) == 1:
        return out
    return out._reshape(lead)


#: ``c, n, force, tau`` of no rows; a :class:`ContactCovariance` of no rows
_NO_ROWS = (np.empty((0, 3)), np.empty((0, 3)), np.empty((0, 3)), np.empty(0))
_NO_COV = (np.empty((0, 3, 3)), np.empty((0, 3, 3)), np.empty(0), np.empty((0, 6, 6)), np.empty((0, 3, 2)))


def _assemble(N, strong, all_strong, c, n, force, tau, ok, facet, cov) -> ContactEstimate:
    bad = ~ok
    any_bad = bool(bad.any())

    def full(x, fill=np.nan, dtype=float):
        if any_bad:
            x[bad] = fill  # every array here is freshly computed (ours to write)
        if all_strong:
            return x
        out = np.full((N,) + x.shape[1:], fill, dtype=dtype)
        out[strong] = x
        return out

    est = ContactEstimate(
        point=full(c),
        normal=full(n),
        force=full(np.array(force, dtype=float)),
        torsion=full(np.asarray(tau, dtype=float)),
        valid=full(ok, False, bool),
    )
    if facet is not None:
        est.facet = full(facet, -1, np.intp)
    if cov is not None:
        est.point_cov = full(cov.point_cov)
        est.force_cov = full(cov.force_cov)
        est.torsion_var = full(cov.torsion_var)
    return est


def contact_crb(surface, point, force, wrench_cov, *, torsion=None, normal=None, point_contact=False):
    """Cramér–Rao covariance of contact estimates, per sample (for the benchmark and app).

    Parameters
    ----------
    surface : Plane, Sphere, Ellipsoid, MeshSurface or Patch
        The patch surface (face frame).
    point : array-like, shape (N, 3)
        Contact points on the surface, m.
    force : array-like, shape (N, 3)
        Contact forces, N.
    wrench_cov : array-like, shape (6, 6) or (N, 6, 6)
        Wrench noise covariance, order ``[fx, fy, fz, tx, ty, tz]``.
    torsion : array-like, shape (N,), optional
        Torsions, N·m (0 if omitted).
    normal : array-like, shape (N, 3), optional
        Outward unit normals (default: the surface's; for a mesh pass the facet normal).
    point_contact : bool
        Bound for the point-contact model (``τ = 0`` known) instead of the soft finger.

    Returns
    -------
    ContactCovariance
        ``point_cov (N, 3, 3)`` m², ``force_cov (N, 3, 3)`` N², ``torsion_var (N,)``.
    """
    surface, _ = _check_surface(surface)
    c = check_vectors(point, 3, "point").reshape(-1, 3)
    f = check_vectors(force, 3, "force").reshape(-1, 3)
    if f.shape != c.shape:
        raise ValueError(f"force: expected shape {c.shape} like point, got {f.shape}")
    N = len(c)
    tau = np.zeros(N) if torsion is None else np.asarray(torsion, dtype=float).reshape(-1)
    if tau.shape != (N,):
        raise ValueError(f"torsion: expected shape ({N},), got {tau.shape}")
    if normal is None:
        n = surface._normal(c)
    else:
        n = check_vectors(normal, 3, "normal").reshape(-1, 3)
        n = n / np.linalg.norm(n, axis=1, keepdims=True)
    S = check_wrench_cov(wrench_cov, N)
    J, T = wrench_jacobian(c, n, surface._shape_operator(c, n), f, tau, point_contact=point_contact)
    return covariance_from_jacobian(J, T, S)

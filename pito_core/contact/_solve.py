"""``solve``: one entry point over every surface; it returns a ``ContactEstimate`` (face frame)."""

from __future__ import annotations

import numpy as np

from ..defaults import IDENTIFY_FORCE_N
from ..frames import check_vectors
from ._crb import ContactCovariance, check_wrench_cov, covariance_from_jacobian, wrench_jacobian
from ._estimate import ContactEstimate, _Deferred
from ._plausibility import (
    DEFAULT_FRICTION,
    DEFAULT_TORSION_RADIUS,
    SINGLE_CONTACT_ALPHA,
    SingleContactReason,
    param_variance,
    single_contact_test,
)
from ._pointcontact import DEFAULT_WRENCH_COV, refine_point_contact
from ._quadric import solve_ellipsoid, solve_plane, solve_sphere
from ._soft_screen import deferred_soft_p, soft_finger_flags
from ._surfaces import Ellipsoid, MeshSurface, Plane, Sphere, Surface, check_positive

__all__ = ["solve", "contact_crb", "DEFAULT_FORCE_THRESHOLD"]

#: Forces below this magnitude (N) give no contact (``valid = False``); ``pito_core.defaults``.
DEFAULT_FORCE_THRESHOLD = IDENTIFY_FORCE_N


def _check_surface(surface, with_friction=False):
    boundary = None
    friction = (DEFAULT_FRICTION, DEFAULT_TORSION_RADIUS)
    if hasattr(surface, "surface") and hasattr(surface, "boundary"):  # a Patch
        boundary = surface.boundary
        friction = (surface.mu, surface.torsion_radius)
        surface = surface.surface
    if not isinstance(surface, Surface):
        raise ValueError(
            f"surface: expected a Plane, Sphere, Ellipsoid, MeshSurface or Patch, "
            f"got {type(surface).__name__}"
        )
    if with_friction:
        return surface, boundary, friction
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
    mu=None,
    torsion_radius=None,
    alpha=SINGLE_CONTACT_ALPHA,
    single_contact: bool = True,
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
    mu : float, optional
        Fingertip friction coefficient for the single-contact test (default: the patch's,
        else ``DEFAULT_FRICTION``).
    torsion_radius : float, optional
        Effective torsional radius of the fingertip, m (default: the patch's, else
        ``DEFAULT_TORSION_RADIUS``); the largest torsion is ``μ · torsion_radius · f_n``.
    alpha : float
        Significance level: ``single_contact = single_contact_p >= alpha``. The test
        uses ``wrench_cov`` (or ``DEFAULT_WRENCH_COV`` if None) as the wrench's noise.
    single_contact : bool
        Run the single-contact test (default). False leaves the three ``single_contact*``
        fields None (the bare solver: no Jacobian is built unless ``wrench_cov`` asks for
        the covariances).

    Returns
    -------
    ContactEstimate
        Fields of shape ``(..., 3)``, ``(...,)`` (and ``(..., 3, 3)`` covariances).
    """
    surface, patch_boundary, (mu_p, e_p) = _check_surface(surface, with_friction=True)
    if boundary is None:
        boundary = patch_boundary
    mu = check_positive(mu_p if mu is None else mu, "mu", "a positive number")
    e = check_positive(e_p if torsion_radius is None else torsion_radius, "torsion_radius")
    alpha = _check_alpha(alpha)
    thr = _check_threshold(force_threshold)
    w = check_vectors(wrench, 6, "wrench")
    lead = w.shape[:-1]
    w = w.reshape(-1, 6)
    S = None if wrench_cov is None else check_wrench_cov(wrench_cov, len(w))
    out = _solve_checked([(surface, boundary, mu, e, len(w))], w, thr, S, point_contact=point_contact,
                         single_contact=single_contact, alpha=alpha)
    if len(lead) == 1:
        return out
    return out._reshape(lead)


def _solve_patches(patches, blocks, force_threshold, covs, point_contact, single_contact=True) -> ContactEstimate:
    """``solve(patch, w, force_threshold, point_contact=…, wrench_cov=S)`` of several patches in one pass.

    For ``solve_object``: ``blocks`` are each patch's rows ``w (N_k, 6)`` and ``covs`` their
    covariances (checked: ``(6, 6)`` or ``(N_k, 6, 6)``), or None. Returns the flat estimate of
    the blocks' rows one after the other.
    """
    parts = []
    for patch, w in zip(patches, blocks):
        surface, boundary, (mu, e) = _check_surface(patch, with_friction=True)
        parts.append((surface, boundary, check_positive(mu, "mu", "a positive number"),
                      check_positive(e, "torsion_radius"), len(w)))
    w = blocks[0] if len(blocks) == 1 else np.concatenate(blocks)
    S = None
    if covs is not None:
        if all(c.ndim == 2 and np.array_equal(c, covs[0]) for c in covs):
            S = covs[0]
        else:
            S = np.concatenate([np.broadcast_to(c, (len(b), 6, 6)) for c, b in zip(covs, blocks)])
    return _solve_checked(parts, w, _check_threshold(force_threshold), S, point_contact=point_contact,
                          single_contact=single_contact, alpha=SINGLE_CONTACT_ALPHA)


def _solve_checked(parts, w, thr, S, *, point_contact, single_contact, alpha):
    """The body of ``solve`` on checked arguments: wrenches ``w (N, 6)``, covariance ``S`` or None.

    ``parts``: ``(surface, boundary, mu, torsion_radius, rows)`` of consecutive blocks of ``w``,
    one per patch (``solve``: one). Each block's closed form, shape operator and boundary are
    its own; the Jacobian, the single-contact test and the covariances run over all rows at
    once (``solve_object``: one sample's faces in one pass). Returns the flat estimate ``(N, …)``.
    """
    N = len(w)
    f_all = w[:, :3]
    m_all = w[:, 3:]
    f2 = np.einsum("ij,ij->i", f_all, f_all)
    strong = f2 >= max(thr * thr, 1e-300)  # NaN rows are False
    n_strong = np.count_nonzero(strong)
    all_strong = n_strong == N
    mesh = any(isinstance(part[0], MeshSurface) for part in parts)
    if N and not n_strong:  # nobody pushes on this patch (most faces, most of the time): nothing to solve
        return _assemble(N, strong, False, *_NO_ROWS, np.empty(0, bool), np.empty(0, np.intp) if mesh else None,
                         None if S is None else ContactCovariance(*_NO_COV), _NO_TEST if single_contact else None)
    f = f_all if all_strong else f_all[strong]
    m = m_all if all_strong else m_all[strong]
    ws = w if all_strong else w[strong]
    Sn = S if S is not None else DEFAULT_WRENCH_COV  # the noise the test and the weights assume
    if Sn.ndim == 3 and not all_strong:
        Sn = Sn[strong]
    # each block's pushing rows stay consecutive: (surface, boundary, slice of the pushing rows)
    surfaces, start, stop = [], 0, 0
    for surface, boundary, _, _, rows in parts:
        k = rows if all_strong else np.count_nonzero(strong[start:start + rows])
        surfaces.append((surface, boundary, slice(stop, stop + k)))
        start, stop = start + rows, stop + k
    mu, e = (parts[0][j] if len({part[j] for part in parts}) == 1 else  # one number, or one per row
             np.concatenate([np.full(sl.stop - sl.start, part[j]) for part, (_, _, sl) in zip(parts, surfaces)])
             for j in (2, 3))

    c, n, force, tau, ok, facet, cov, test = _solve_rows(
        surfaces, f, m, ws, Sn, with_cov=S is not None, point_contact=point_contact, single_contact=single_contact,
        mesh=mesh, mu=mu, torsion_radius=e, alpha=alpha, f2=f2 if all_strong else f2[strong])
    return _assemble(N, strong, all_strong, c, n, force, tau, ok, facet, cov, test)


def _solve_rows(surfaces, f, m, ws, Sn, *, with_cov, point_contact, single_contact, mesh, mu, torsion_radius,
                alpha, f2=None):
    """Solve the rows that push hard enough: ``c, n, force, tau, ok, facet, cov, test``.

    ``surfaces``: ``(surface, boundary, rows)`` of consecutive blocks (a slice each);
    ``f``, ``m``, ``ws``: their force ``(n, 3)`` N, moment ``(n, 3)`` N·m and wrench ``(n, 6)``;
    ``Sn``: the wrench noise covariance ``(6, 6)`` or ``(n, 6, 6)`` the weights and the test
    assume; ``mu``, ``torsion_radius``: numbers, or per row ``(n,)``; ``facet`` only with a
    ``mesh`` among the surfaces (−1 on the other blocks); ``cov`` only ``with_cov`` (a
    covariance given by the caller), ``test`` only with ``single_contact``.
    """
    e = torsion_radius
    blocks = [b for b in surfaces if b[2].stop > b[2].start]  # the blocks with rows to solve
    force = np.array(f, order="C")  # ours: the kernels read it, the point-contact refinement writes it
    c, n, tau, ok, facet = _solve_blocks(surfaces, blocks, force, m, mesh)
    W = np.linalg.inv(Sn) if point_contact else None
    if point_contact and len(c):
        for surface, _, sl in blocks:
            sel = sl.start + np.flatnonzero(ok[sl])
            if len(sel):
                _refine(surface, c, n, force, ok, sel, ws[sel], W if W.ndim == 2 else W[sel])
        tau = np.zeros(len(c))
    ok &= np.isfinite(np.einsum("ij,j->i", c, _ZERO3))  # isfinite(c).all(axis=1): 0 · ±inf and 0 · NaN are NaN

    test = cov = None
    if single_contact and not point_contact:  # the soft finger's test in closed form, p on first read (_soft_screen)
        zmin = np.empty(len(c))
        single, reason = soft_finger_flags(c, n, force, tau, Sn, blocks, mu, e, alpha, ok, m, f2=f2, zmin=zmin)
        test = single, deferred_soft_p(blocks, c, n, tau, ws, Sn, mu, e, zmin), reason
    elif single_contact or with_cov:
        with np.errstate(invalid="ignore", divide="ignore"):  # NaN rows stay NaN
            shape = _shape(surfaces, blocks, c, n)
            J, T = wrench_jacobian(c, n, shape, force, tau, point_contact=point_contact)
            if single_contact:  # point contact: the parameters' covariance, and the χ² residual
                variance = param_variance(covariance_from_jacobian(J, T, Sn).param_cov)
                boundary = surfaces[0][1] if len(surfaces) == 1 else [(b, sl) for _, b, sl in blocks]
                test = single_contact_test(c, n, force, tau, ws, variance, T, shape, W, boundary=boundary, mu=mu,
                                           torsion_radius=e, alpha=alpha, point_contact=point_contact)
    for _, boundary, sl in blocks:
        if boundary is not None:
            ok[sl] &= boundary._contains(c[sl])
    if with_cov:
        if single_contact and not point_contact:
            with np.errstate(invalid="ignore", divide="ignore"):
                J, T = wrench_jacobian(c, n, _shape(surfaces, blocks, c, n), force, tau, point_contact=point_contact)
        J[~ok] = np.nan
        cov = covariance_from_jacobian(J, T, Sn)
    return c, n, force, tau, ok, facet, cov, test


def _solve_blocks(surfaces, blocks, force, m, mesh):
    """The closed forms (or the mesh) block by block: ``c, n, tau, ok, facet`` of the rows ``force``, ``m``."""
    mc = np.ascontiguousarray(m) if mesh else m  # the closed forms take strided moments
    if len(surfaces) == 1:
        return _solve_surface(surfaces[0][0], force, mc)
    solved = [_solve_surface(s, force[sl], mc[sl]) for s, _, sl in blocks]
    c, n, tau, ok = (np.concatenate([r[k] for r in solved]) for k in range(4))
    facet = np.full(len(c), -1, np.intp) if mesh else None
    for r, (_, _, sl) in zip(solved, blocks):
        if r[4] is not None:
            facet[sl] = r[4]
    return c, n, tau, ok, facet


def _shape(surfaces, blocks, c, n):
    """Shape operators ``(n, 3, 3)`` of the solved rows, block by block."""
    if len(surfaces) == 1:
        return surfaces[0][0]._shape_operator(c, n)
    return np.concatenate([s._shape_operator(c[sl], n[sl]) for s, _, sl in blocks])


def _refine(surface, c, n, force, ok, sel, ws, Wn):
    """Point contact (``τ = 0``): weighted least squares from the closed form, rows ``sel`` in place."""
    if isinstance(surface, MeshSurface):
        nf = n[sel]
        normal_fn = lambda p: nf  # noqa: E731 - the facet's plane
        retract_fn = lambda p: p  # noqa: E731 - tangent steps stay on it
    else:
        normal_fn, retract_fn = surface._normal, surface._retract
    with np.errstate(invalid="ignore", divide="ignore"):
        cs, ns, fs = refine_point_contact(c[sel], force[sel], ws, Wn, normal_fn, retract_fn)
    c[sel], n[sel], force[sel] = cs, ns, fs
    ok[sel] &= np.einsum("ij,ij->i", fs, ns) < 0  # still pushing in


def _check_alpha(alpha) -> float:
    try:
        a = float(alpha)
    except (TypeError, ValueError):
        raise ValueError(f"alpha: expected a significance level in (0, 1), got {alpha!r}") from None
    if not 0.0 < a < 1.0:
        raise ValueError(f"alpha: expected a significance level in (0, 1), got {alpha!r}")
    return a


#: ``c, n, force, tau`` of no rows; a :class:`ContactCovariance` of no rows
_NO_ROWS = (np.empty((0, 3)), np.empty((0, 3)), np.empty((0, 3)), np.empty(0))
_NO_COV = (np.empty((0, 3, 3)), np.empty((0, 3, 3)), np.empty(0), np.empty((0, 6, 6)), np.empty((0, 3, 2)))
#: zeros (3,): ``x @ _ZERO3`` is finite exactly where the row x is
_ZERO3 = np.zeros(3)
#: a single-contact test of no rows
_NO_TEST = (np.empty(0, bool), np.empty(0), np.empty(0, np.int8))


def _assemble(N, strong, all_strong, c, n, force, tau, ok, facet, cov, test) -> ContactEstimate:
    bad = np.flatnonzero(~ok)
    any_bad = len(bad) > 0

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
        force=full(force),
        torsion=full(np.asarray(tau, dtype=float)),
        valid=full(ok, False, bool),
    )
    if facet is not None:
        est.facet = full(facet, -1, np.intp)
    if cov is not None:
        est.point_cov = full(cov.point_cov)
        est.force_cov = full(cov.force_cov)
        est.torsion_var = full(cov.torsion_var)
    if test is None:
        return est
    single, p, reason = test if isinstance(test, tuple) else (test.single, test.p, test.reason)
    if all_strong:
        est.single_contact, est.single_contact_p, est.single_contact_reason = single, p, reason
    else:  # rows without force: nothing to judge
        est.single_contact = np.zeros(N, bool)
        est.single_contact[strong] = single
        est.single_contact_p = _Deferred((N,), lambda: _scatter(N, strong, p.value())) if isinstance(p, _Deferred) \
            else _scatter(N, strong, p)
        est.single_contact_reason = np.full(N, SingleContactReason.NO_FORCE, np.int8)
        est.single_contact_reason[strong] = reason
    return est


def _scatter(N, strong, p):
    """``p`` of the rows ``strong`` in ``N`` rows, NaN elsewhere (no force: nothing to judge)."""
    out = np.full(N, np.nan)
    out[strong] = p
    return out


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

"""Shared helpers of the contact tests: exact soft-finger wrenches and random contacts."""

import numpy as np

from pito_core.contact import Sphere, PatchBoundary, patch_solid
from pito_core.contact._surfaces import tangent_basis


def wrench_from_contact(c, f, tau, n):
    """Exact soft-finger wrench ``[f, c × f + τ n]`` ``(N, 6)``."""
    c, f, n = (np.atleast_2d(np.asarray(x, float)) for x in (c, f, n))
    tau = np.atleast_1d(np.asarray(tau, float))
    return np.c_[f, np.cross(c, f) + tau[:, None] * n]


def pushing_forces(rng, n, max_deg=85.0, magnitude=(0.5, 5.0), exact_deg=None):
    """Forces ``(N, 3)`` pushing into the surface, at most ``max_deg`` from ``−n``."""
    N = len(n)
    T = tangent_basis(n)
    if exact_deg is None:
        th = np.radians(rng.uniform(0.0, max_deg, N))
    else:
        th = np.full(N, np.radians(exact_deg))
    ph = rng.uniform(0.0, 2 * np.pi, N)
    d = -np.cos(th)[:, None] * n + np.sin(th)[:, None] * (
        np.cos(ph)[:, None] * T[:, :, 0] + np.sin(ph)[:, None] * T[:, :, 1]
    )
    return d * rng.uniform(*magnitude, size=(N, 1))


def random_on_ellipsoid(rng, surface, N, upper_only=False):
    """Random points on an Ellipsoid/Sphere surface ``(N, 3)`` and their normals."""
    q = rng.normal(size=(N, 3))
    if upper_only:
        q[:, 2] = np.abs(q[:, 2])
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    c = surface.center + (q * surface.semi_axes) @ surface.rotation.T
    n = ((q / surface.semi_axes) @ surface.rotation.T)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    return c, n


def dome_mesh(rings=18, segments=72):
    """A closed faceted dome (about 5,000 facets at the defaults), face frame, m."""
    zc, R, zmin = -0.032, 0.04, 0.002
    rim = np.sqrt(R**2 - (zmin - zc) ** 2)
    return patch_solid(Sphere([0, 0, zc], R), PatchBoundary("ellipse", radii=[rim, rim], z_min=zmin),
                       rings=rings, segments=segments)

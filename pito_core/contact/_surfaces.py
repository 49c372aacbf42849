"""Patch surfaces in a face frame: plane, sphere, ellipsoid and triangle mesh.

Each class validates its parameters once (``ValueError`` naming the field) and caches
the derived arrays the vectorised solvers need. The private methods take and return
plain float arrays and skip every check (hot path).
"""

from __future__ import annotations

import numpy as np

from ..frames import ROTATION_TOL, cross_rows
from ._mesh import MeshIndex
from ._quadric import _norm
from ._tol import BARYCENTRIC_TOL

__all__ = ["Plane", "Sphere", "Ellipsoid", "MeshSurface", "Surface", "BARYCENTRIC_TOL", "check_positive"]


def _check_point(x, name: str) -> np.ndarray:
    a = np.asarray(x, dtype=float)
    if a.shape != (3,):
        raise ValueError(f"{name}: expected shape (3,), got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name}: expected finite values, got {a.tolist()}")
    return a


def check_positive(x, name: str, what: str = "a positive length in m") -> float:
    """``x`` as a finite float > 0, or ``ValueError("<name>: expected <what>, got …")``."""
    try:
        v = float(x)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected {what}, got {x!r}") from None
    if not np.isfinite(v) or v <= 0:
        raise ValueError(f"{name}: expected {what}, got {x!r}")
    return v


def tangent_basis(n: np.ndarray) -> np.ndarray:
    """Two unit tangents ``(N, 3, 2)`` orthogonal to the unit normals ``n (N, 3)``."""
    a = np.zeros_like(n)
    use_x = np.abs(n[:, 0]) < 0.9
    a[use_x, 0] = 1.0
    a[~use_x, 1] = 1.0
    T = np.empty(n.shape + (2,))
    t1 = cross_rows(n, a)  # np.cross's arithmetic, without its call overhead
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    T[:, :, 0] = t1
    T[:, :, 1] = cross_rows(n, t1)
    return T


#: the 3 × 3 identity
_EYE3 = np.eye(3)


class Surface:
    """Base class of the patch surfaces (all given in a face frame, lengths in m)."""

    kind = "surface"

    def normal_at(self, points) -> np.ndarray:
        """Outward unit normal ``(N, 3)`` at surface points ``(N, 3)`` in m."""
        p = np.asarray(points, dtype=float).reshape(-1, 3)
        return self._normal(p)

    # -- private, unchecked, vectorised -------------------------------------------------
    def _normal(self, c: np.ndarray) -> np.ndarray:  # pragma: no cover - abstract
        raise NotImplementedError

    def _shape_operator(self, c: np.ndarray, n: np.ndarray) -> np.ndarray:
        """``(N, 3, 3)`` matrix ``S`` with ``dn = S dc`` for tangent displacements ``dc``."""
        return np.zeros((len(c), 3, 3))

    def _retract(self, c: np.ndarray) -> np.ndarray:
        """Map points near the surface back onto it (first-order identity on tangents)."""
        return c


class Plane(Surface):
    """The plane through ``point`` with outward unit ``normal`` (face frame).

    Parameters
    ----------
    point : array-like, shape (3,)
        A point of the plane, m.
    normal : array-like, shape (3,)
        Outward normal (normalised here; must be non-zero).
    """

    kind = "plane"

    def __init__(self, point, normal):
        self.point = _check_point(point, "point")
        n = _check_point(normal, "normal")
        norm = np.linalg.norm(n)
        if norm < 1e-12:
            raise ValueError(f"normal: expected a non-zero vector, got {n.tolist()}")
        self.normal = n / norm
        self.offset = float(self.point @ self.normal)  # n · x = offset on the plane

    def _normal(self, c):
        return np.broadcast_to(self.normal, c.shape).copy()

    def _retract(self, c):
        return c - np.outer(np.einsum("ij,j->i", c, self.normal) - self.offset, self.normal)

    def __repr__(self):
        return f"Plane(point={self.point.tolist()}, normal={self.normal.tolist()})"


class Ellipsoid(Surface):
    """The ellipsoid ``{c0 + R diag(a) q : |q| = 1}`` (face frame).

    Parameters
    ----------
    center : array-like, shape (3,)
        Centre ``c0``, m.
    semi_axes : array-like, shape (3,)
        Semi-axes ``a`` (> 0), m, along the columns of ``rotation``.
    rotation : array-like, shape (3, 3), optional
        Proper rotation whose columns are the principal axes in the face frame
        (identity if omitted).
    """

    kind = "ellipsoid"

    def __init__(self, center, semi_axes, rotation=None):
        self.center = _check_point(center, "center")
        a = _check_point(semi_axes, "semi_axes")
        if np.any(a <= 0):
            raise ValueError(f"semi_axes: expected three positive lengths in m, got {a.tolist()}")
        self.semi_axes = a
        if rotation is None:
            R = np.eye(3)
        else:
            R = np.asarray(rotation, dtype=float)
            if R.shape != (3, 3) or not np.all(np.isfinite(R)):
                raise ValueError(f"rotation: expected a finite (3, 3) matrix, got shape {R.shape}")
            if not np.allclose(R.T @ R, np.eye(3), atol=ROTATION_TOL) or np.linalg.det(R) < 0:
                raise ValueError("rotation: expected a proper rotation (RᵀR = I, det R = +1)")
        self.rotation = R
        # A = R diag(1/a²) Rᵀ: the quadric (c − c0)ᵀ A (c − c0) = 1.
        self._A = (R / a**2) @ R.T

    def _normal(self, c):
        g = np.einsum("ij,jk->ik", c - self.center, self._A)  # A symmetric
        return g / _norm(g)

    def _shape_operator(self, c, n):
        g = _norm(np.einsum("ij,jk->ik", c - self.center, self._A))[:, 0]
        P = _EYE3 - n[:, :, None] * n[:, None, :]
        return P @ self._A / g[:, None, None]

    def _retract(self, c):
        q = np.einsum("ij,jk->ik", c - self.center, self.rotation) / self.semi_axes
        q /= _norm(q)
        return self.center + np.einsum("ij,kj->ik", q * self.semi_axes, self.rotation)

    def __repr__(self):
        return (
            f"Ellipsoid(center={self.center.tolist()}, semi_axes={self.semi_axes.tolist()}, "
            f"rotation={self.rotation.tolist()})"
        )


class Sphere(Ellipsoid):
    """The sphere of centre ``center`` (m) and radius ``radius`` (m), face frame."""

    kind = "sphere"

    def __init__(self, center, radius):
        r = check_positive(radius, "radius")
        super().__init__(center, (r, r, r))
        self.radius = r

    def _normal(self, c):
        d = c - self.center
        return d / _norm(d)

    def _shape_operator(self, c, n):
        P = _EYE3 - n[:, :, None] * n[:, None, :]
        return P / self.radius

    def _retract(self, c):
        d = c - self.center
        return self.center + d * (self.radius / _norm(d))

    def __repr__(self):
        return f"Sphere(center={self.center.tolist()}, radius={self.radius!r})"


class MeshSurface(Surface):
    """A triangle mesh (face frame, m); the contact lies exactly on one facet.

    Parameters
    ----------
    mesh : trimesh.Trimesh
        The patch's outer surface (open or closed). Facet normals must point out
        of the object (``trimesh`` winding convention); degenerate facets are ignored.
    group_size : int
        Facets per group of the exact pruning hierarchy (see ``_mesh.py``); a tuning
        knob, the result does not depend on it.
    """

    kind = "mesh"

    def __init__(self, mesh, group_size: int = 8):
        import trimesh  # deferred: ~1 s to import; analytic surfaces never need it
        if not isinstance(mesh, trimesh.Trimesh):
            raise ValueError(f"mesh: expected a trimesh.Trimesh, got {type(mesh).__name__}")
        if len(mesh.faces) == 0:
            raise ValueError("mesh: expected at least one facet, got an empty mesh")
        if not np.all(np.isfinite(mesh.vertices)):
            raise ValueError("mesh: expected finite vertices, got NaN or inf")
        self.mesh = mesh
        self._index = MeshIndex(np.asarray(mesh.triangles, dtype=float), int(group_size))

    @property
    def facet_normals(self) -> np.ndarray:
        """Outward unit normal of every facet ``(F, 3)`` (zeros for degenerate facets)."""
        return self._index.normals_orig

    def _normal(self, c):
        # Normal of the nearest facet (the solver reports the facet it used directly).
        _, _, tri = self.mesh.nearest.on_surface(c)
        return self.facet_normals[tri]

    def __repr__(self):
        return f"MeshSurface(<{len(self.mesh.faces)} facets>)"

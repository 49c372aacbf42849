"""Patch boundaries: which surface points belong to a patch (face frame, m).

A boundary is a 2-D shape in the face plane ``z = 0`` (rectangle, ellipse or polygon)
and a projection that maps a surface point onto that plane: ``parallel`` (drop z) or
``central`` from an ``apex`` (e.g. the core centre ``(0, 0, −edge/2)`` for caps of one
sphere centred on the core). An optional ``z_min`` removes the part of the surface
below a height (a dome's hidden half). Points on the boundary (within ``BOUNDARY_TOL``)
belong to the patch.
"""

from __future__ import annotations

import numpy as np

from ._tol import BOUNDARY_TOL

__all__ = ["PatchBoundary", "BOUNDARY_TOL"]


_SHAPES = ("rectangle", "ellipse", "polygon", None)


def _pair(x, name):
    a = np.asarray(x, dtype=float)
    if a.shape != (2,) or not np.all(np.isfinite(a)) or np.any(a <= 0):
        raise ValueError(f"{name}: expected two positive lengths in m, got {x!r}")
    return a


class PatchBoundary:
    """Region of the surface that belongs to a patch.

    Parameters
    ----------
    shape : {"rectangle", "ellipse", "polygon"} or None
        Shape in the face plane (None: no lateral limit).
    size : array-like, shape (2,)
        Rectangle width (x) and height (y), m.
    radii : array-like, shape (2,)
        Ellipse semi-axes along x and y, m.
    vertices : array-like, shape (K, 2)
        Polygon vertices in the face plane, m, counter-clockwise, star-shaped about
        their mean.
    center : array-like, shape (2,)
        Centre of the rectangle or ellipse in the face plane, m.
    projection : {"parallel", "central"}
        How surface points are mapped onto the face plane.
    apex : array-like, shape (3,)
        Projection centre for ``central`` (must lie below the plane, z < 0).
    z_min : float, optional
        Points lower than this (face z, m) are outside.
    """

    def __init__(self, shape=None, *, size=None, radii=None, vertices=None, center=(0.0, 0.0),
                 projection="parallel", apex=None, z_min=None):
        if shape not in _SHAPES:
            raise ValueError(f"shape: expected one of rectangle, ellipse, polygon or None, got {shape!r}")
        self.shape = shape
        self.center = np.asarray(center, dtype=float)
        if self.center.shape != (2,) or not np.all(np.isfinite(self.center)):
            raise ValueError(f"center: expected shape (2,) finite, got {center!r}")
        self.size = self.radii = self.vertices = None
        if shape == "rectangle":
            self.size = _pair(size, "size")
        elif shape == "ellipse":
            self.radii = _pair(radii, "radii")
        elif shape == "polygon":
            v = np.asarray(vertices, dtype=float)
            if v.ndim != 2 or v.shape[1] != 2 or len(v) < 3 or not np.all(np.isfinite(v)):
                raise ValueError(f"vertices: expected shape (K >= 3, 2) finite, got {np.shape(vertices)}")
            area = 0.5 * np.sum(v[:, 0] * np.roll(v[:, 1], -1) - np.roll(v[:, 0], -1) * v[:, 1])
            if area <= 0:
                raise ValueError("vertices: expected a counter-clockwise polygon with positive area")
            self.vertices = v
        if projection not in ("parallel", "central"):
            raise ValueError(f"projection: expected 'parallel' or 'central', got {projection!r}")
        self.projection = projection
        self.apex = None
        if projection == "central":
            a = np.asarray(apex, dtype=float) if apex is not None else np.zeros(0)
            if a.shape != (3,) or not np.all(np.isfinite(a)) or a[2] >= 0:
                raise ValueError(f"apex: expected a point (3,) below the face plane (z < 0), got {apex!r}")
            self.apex = a
        self.z_min = None if z_min is None else float(z_min)
        if self.z_min is not None and not np.isfinite(self.z_min):
            raise ValueError(f"z_min: expected a finite height in m, got {z_min!r}")

    # ------------------------------------------------------------------ geometry
    def project(self, points) -> np.ndarray:
        """Face-plane coordinates ``(N, 2)`` of surface points ``(N, 3)`` (NaN if behind apex)."""
        p = np.asarray(points, dtype=float).reshape(-1, 3)
        xy = self._project(p)
        return xy.copy() if self.projection == "parallel" else xy

    def contains(self, points) -> np.ndarray:
        """Whether surface points ``(N, 3)`` (m, face frame) belong to the patch, ``(N,)``."""
        return self._contains(np.asarray(points, dtype=float).reshape(-1, 3))

    def _contains(self, p: np.ndarray) -> np.ndarray:
        tol = BOUNDARY_TOL
        inside = np.isfinite(p).all(axis=1)
        if self.z_min is not None:
            inside &= p[:, 2] >= self.z_min - tol
        if self.shape is None:
            return inside
        xy = self._project(p)
        if self.projection == "central":  # NaN behind the apex
            inside &= np.isfinite(xy).all(axis=1)
        # rows already outside (non-finite) stay outside whatever their xy gives below
        if self.shape == "rectangle":
            d = np.abs(xy - self.center) - 0.5 * self.size
            return inside & (d <= tol).all(axis=1)
        if self.shape == "ellipse":
            u = (xy - self.center) / (self.radii + tol)
            return inside & ((u * u).sum(1) <= 1.0)
        xy = np.nan_to_num(xy)
        return inside & (_in_polygon(xy, self.vertices) | (_polygon_distance(xy, self.vertices) <= tol))

    def _project(self, p: np.ndarray) -> np.ndarray:
        """``project`` of checked points ``(N, 3)``; ``parallel`` gives a view of ``p``."""
        if self.projection == "parallel":
            return p[:, :2]
        a = self.apex
        dz = p[:, 2] - a[2]
        with np.errstate(divide="ignore", invalid="ignore"):
            t = np.where(dz > 0, -a[2] / dz, np.nan)
        return a[:2] + t[:, None] * (p[:, :2] - a[:2])

    def margin(self, points) -> np.ndarray:
        """Signed distance ``(N,)`` (m) of surface points ``(N, 3)`` to the patch edge, > 0 inside.

        Measured in the face plane after projection (and in height for ``z_min``); the
        ellipse's is the distance along the ray from its centre. NaN for NaN points; +inf
        without any limit. Used by the single-contact test (``docs/contact.md``).
        """
        p = np.asarray(points, dtype=float).reshape(-1, 3)
        if self.shape is None:
            out = np.full(len(p), np.inf) if self.z_min is None else p[:, 2] - self.z_min
            return np.where(np.isfinite(p).all(axis=1), out, np.nan)
        xy = self._project(p)
        # column by column (x² + y² is what a row's sum of two squares gives, bit for bit): the single-contact
        # test calls this on every solved row five times, and a reduction over two columns costs 5x these
        if self.shape == "rectangle":
            dx = np.abs(xy[:, 0] - self.center[0]) - 0.5 * self.size[0]
            dy = np.abs(xy[:, 1] - self.center[1]) - 0.5 * self.size[1]
            ox, oy = np.maximum(dx, 0.0), np.maximum(dy, 0.0)
            outside = np.sqrt(ox * ox + oy * oy)  # |max(d, 0)|
            lateral = np.where(outside > 0, -outside, -np.maximum(dx, dy))
        elif self.shape == "ellipse":
            x, y = xy[:, 0] - self.center[0], xy[:, 1] - self.center[1]
            r = np.sqrt(x * x + y * y)
            x /= self.radii[0]
            y /= self.radii[1]
            rho = np.sqrt(x * x + y * y)
            with np.errstate(invalid="ignore", divide="ignore"):
                lateral = np.where(rho > 0, r * (1.0 / rho - 1.0), self.radii.min())
        else:
            dist = _polygon_distance(np.nan_to_num(xy), self.vertices)
            lateral = np.where(_in_polygon(np.nan_to_num(xy), self.vertices), dist, -dist)
            lateral = np.where(np.isfinite(xy).all(axis=1), lateral, np.nan)
        if self.z_min is None:
            return lateral
        return np.minimum(p[:, 2] - self.z_min, lateral)

    def outline(self, segments: int = 96) -> np.ndarray:
        """Counter-clockwise points ``(M, 2)`` on the boundary (corners included), m."""
        if self.shape is None:
            raise ValueError("outline: a boundary without shape has no outline")
        if self.shape == "ellipse":
            t = np.linspace(0.0, 2 * np.pi, segments, endpoint=False)
            return self.center + self.radii * np.c_[np.cos(t), np.sin(t)]
        if self.shape == "rectangle":
            hx, hy = 0.5 * self.size
            verts = self.center + np.array([[hx, -hy], [hx, hy], [-hx, hy], [-hx, -hy]])
        else:
            verts = self.vertices
        per = max(1, segments // len(verts))
        s = np.arange(per) / per
        nxt = np.roll(verts, -1, axis=0)
        pts = verts[:, None, :] + s[None, :, None] * (nxt - verts)[:, None, :]
        return pts.reshape(-1, 2)

    def to_dict(self) -> dict:
        """JSON-ready description (see ``docs/contact.md``)."""
        d = {"shape": self.shape, "projection": self.projection}
        if self.size is not None:
            d["size"] = self.size.tolist()
        if self.radii is not None:
            d["radii"] = self.radii.tolist()
        if self.vertices is not None:
            d["vertices"] = self.vertices.tolist()
        if np.any(self.center):
            d["center"] = self.center.tolist()
        if self.apex is not None:
            d["apex"] = self.apex.tolist()
        if self.z_min is not None:
            d["z_min"] = self.z_min
        return d

    @classmethod
    def from_dict(cls, d: dict) -> PatchBoundary:
        if not isinstance(d, dict):
            raise ValueError(f"boundary: expected an object, got {type(d).__name__}")
        known = {"shape", "size", "radii", "vertices", "center", "projection", "apex", "z_min"}
        extra = set(d) - known
        if extra:
            raise ValueError(f"boundary: unknown keys {sorted(extra)}")
        kw = {k: v for k, v in d.items() if k != "shape"}
        return cls(d.get("shape"), **kw)

    def __repr__(self):
        return f"PatchBoundary({self.to_dict()})"


def _in_polygon(xy: np.ndarray, verts: np.ndarray) -> np.ndarray:
    """Even-odd rule, vectorised over points and edges."""
    x, y = xy[:, 0:1], xy[:, 1:2]
    x0, y0 = verts[:, 0], verts[:, 1]
    x1, y1 = np.roll(x0, -1), np.roll(y0, -1)
    crosses = (y0 > y) != (y1 > y)
    with np.errstate(divide="ignore", invalid="ignore"):
        xc = x0 + (y - y0) * (x1 - x0) / (y1 - y0)
    return (np.sum(crosses & (x < xc), axis=1) % 2) == 1


def _polygon_distance(xy: np.ndarray, verts: np.ndarray) -> np.ndarray:
    a = verts[None, :, :]
    b = np.roll(verts, -1, axis=0)[None, :, :]
    ab = b - a
    t = np.clip(((xy[:, None, :] - a) * ab).sum(-1) / (ab * ab).sum(-1), 0.0, 1.0)
    d = xy[:, None, :] - (a + t[..., None] * ab)
    return np.sqrt((d * d).sum(-1)).min(axis=1)

"""Tolerances of the contact package, in one place (like trimesh's ``tol``).

Every comparison with slack in ``pito_core.contact`` reads its tolerance from here.
"""

from __future__ import annotations

__all__ = ["BARYCENTRIC_TOL", "BOUNDARY_TOL"]

#: Slack (dimensionless) on barycentric coordinates when deciding that a point lies on a
#: facet (points on a shared edge belong to both facets).
BARYCENTRIC_TOL = 1e-9

#: Distance (m) within which a point on a patch's boundary line counts as inside.
BOUNDARY_TOL = 1e-9

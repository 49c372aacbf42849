"""Intrinsic contact sensing: contact point, normal, force and torsion from a face wrench.

Surfaces are given in a face frame (m): ``Plane``, ``Sphere``, ``Ellipsoid``,
``MeshSurface``. ``solve(surface, wrench)`` applies the soft-finger model
``m = c × f + τ n(c)`` (finger pushing in, ``f · n < 0``) in closed form for the
quadrics and exactly, facet by facet, for meshes; ``point_contact=True`` uses the
``τ = 0`` redundancy (weighted least squares) and ``wrench_cov`` adds the Cramér–Rao
covariances. Patches and object assemblies live in ``assets/patches/``
(``load_patch``, ``load_assembly``); ``solve_object`` gives the six contacts of an
object in the core frame. Both return the one record, ``ContactEstimate`` (its ``frame``
says which). Every estimate carries ``single_contact`` (can one fingertip
on the patch produce this wrench within its noise?), its p-value ``single_contact_p`` and
``single_contact_reason``. See ``docs/contact.md``.
"""

from typing import TYPE_CHECKING

from .._lazy import attach

if TYPE_CHECKING:  # re-exported, each loaded on first use (pito_core/_lazy.py)
    from ._accuracy import ACCURACY_SQUARE, AccuracyResult, accuracy_points, flat_patch_accuracy
    from ._boundary import BOUNDARY_TOL, PatchBoundary
    from ._crb import ContactCovariance
    from ._display import patch_solid
    from ._estimate import CONTACT_FRAMES, ContactEstimate
    from ._object import solve_object
    from ._patches import (
        Assembly,
        Patch,
        list_assemblies,
        list_patches,
        load_assembly,
        load_patch,
        patches_dir,
        surface_from_dict,
        surface_to_dict,
    )
    from ._plausibility import (
        DEFAULT_FRICTION,
        DEFAULT_TORSION_RADIUS,
        SINGLE_CONTACT_ALPHA,
        SingleContactReason,
        reason_names,
    )
    from ._pointcontact import DEFAULT_WRENCH_COV
    from ._solve import DEFAULT_FORCE_THRESHOLD, contact_crb, solve
    from ._surfaces import BARYCENTRIC_TOL, Ellipsoid, MeshSurface, Plane, Sphere, Surface

__getattr__, __dir__ = attach(__name__, __file__)

__all__ = [
    "ACCURACY_SQUARE",
    "AccuracyResult",
    "Assembly",
    "BARYCENTRIC_TOL",
    "BOUNDARY_TOL",
    "CONTACT_FRAMES",
    "ContactCovariance",
    "ContactEstimate",
    "DEFAULT_FORCE_THRESHOLD",
    "DEFAULT_FRICTION",
    "DEFAULT_TORSION_RADIUS",
    "DEFAULT_WRENCH_COV",
    "Ellipsoid",
    "MeshSurface",
    "Patch",
    "PatchBoundary",
    "Plane",
    "SINGLE_CONTACT_ALPHA",
    "SingleContactReason",
    "Sphere",
    "Surface",
    "accuracy_points",
    "contact_crb",
    "flat_patch_accuracy",
    "list_assemblies",
    "list_patches",
    "load_assembly",
    "load_patch",
    "patch_solid",
    "patches_dir",
    "reason_names",
    "solve",
    "solve_object",
    "surface_from_dict",
    "surface_to_dict",
]

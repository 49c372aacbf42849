"""The papers' contact-accuracy test on the 46 × 46 mm flat patch.

Nine test points: the centre and eight points on the edges of a 26 × 26 mm square
centred on the patch (its four corners and four edge midpoints). At each, a load is
pressed on the patch; the contact is estimated from the face wrench and compared with
the true point. ``flat_patch_accuracy`` runs the test either on wrenches supplied by a
``measure`` callable (the simulator, a recording, the live device) or on the exact
soft-finger model with optional Gaussian noise.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._patches import load_patch
from ._quadric import _cross
from ._solve import DEFAULT_FORCE_THRESHOLD, solve

__all__ = ["AccuracyResult", "accuracy_points", "flat_patch_accuracy", "ACCURACY_SQUARE"]

#: Side of the square whose edges hold the test points, m.
ACCURACY_SQUARE = 0.026


def accuracy_points(square: float = ACCURACY_SQUARE) -> np.ndarray:
    """Face-plane coordinates ``(9, 2)`` (m): centre, 4 corners, 4 edge midpoints."""
    h = 0.5 * square
    return np.array([
        [0, 0], [-h, -h], [0, -h], [h, -h], [h, 0], [h, h], [0, h], [-h, h], [-h, 0],
    ], dtype=float)


@dataclass
class AccuracyResult:
    """Outcome of the flat-patch accuracy test (face frame).

    Attributes
    ----------
    true_points : ndarray, shape (9, 3)
        Where the loads were applied, m.
    estimated : ndarray, shape (9, K, 3)
        Estimated contacts for each of K repetitions per point, m.
    errors : ndarray, shape (9, K)
        Euclidean error of every estimate, m (NaN where no valid contact).
    point_errors : ndarray, shape (9,)
        RMS error per test point over the repetitions, m.
    """

    true_points: np.ndarray
    estimated: np.ndarray
    errors: np.ndarray
    point_errors: np.ndarray

    @property
    def mean_error(self) -> float:
        """Mean error over all estimates, m."""
        return float(np.nanmean(self.errors))

    @property
    def max_error(self) -> float:
        """Largest error over all estimates, m."""
        return float(np.nanmax(self.errors))


def flat_patch_accuracy(measure=None, *, patch="flat_46mm", force=(0.0, 0.0, -5.0), torsion=0.0,
                        repeats: int = 1, wrench_cov=None, rng=None, point_contact=False,
                        force_threshold=DEFAULT_FORCE_THRESHOLD, square=ACCURACY_SQUARE) -> AccuracyResult:
    """Run the nine-point accuracy test on a flat patch.

    Parameters
    ----------
    measure : callable, optional
        ``measure(points (9, 3) m, forces (9, 3) N, torsions (9,) N·m) -> wrenches``
        of shape ``(9, 6)`` or ``(9, K, 6)`` in the patch's face frame. Default: the
        exact soft-finger model plus Gaussian noise of ``wrench_cov`` (if given),
        ``repeats`` times.
    patch : str or Patch
        The flat patch (library name or object); test points lie on its plane.
    force : array-like, shape (3,)
        Applied force in the face frame, N (pushing in).
    torsion : float
        Applied torsion, N·m.
    repeats : int
        Repetitions per point for the default ``measure``.
    wrench_cov : array-like, shape (6, 6), optional
        Noise covariance for the default ``measure``.
    rng : numpy.random.Generator, optional
        Noise source (default ``default_rng(0)``).
    point_contact : bool
        Use the point-contact estimate.

    Returns
    -------
    AccuracyResult
    """
    if isinstance(patch, str):
        patch = load_patch(patch)
    plane = patch.surface
    if not hasattr(plane, "offset"):
        raise ValueError(f"patch: expected a flat patch, got {plane!r}")
    xy = accuracy_points(square)
    n = plane.normal
    pts = np.c_[xy, np.zeros(9)]
    pts = pts + (plane.offset - pts @ n)[:, None] * n / (n @ n)  # onto the plane (along n)
    forces = np.tile(np.asarray(force, dtype=float), (9, 1))
    torsions = np.full(9, float(torsion))
    if measure is None:
        rng = np.random.default_rng(0) if rng is None else rng
        w = np.c_[forces, _cross(pts, forces) + torsions[:, None] * n]
        w = np.repeat(w[:, None, :], int(repeats), axis=1)
        if wrench_cov is not None:
            w = w + rng.multivariate_normal(np.zeros(6), np.asarray(wrench_cov, float), size=w.shape[:2])
    else:
        w = np.asarray(measure(pts, forces, torsions), dtype=float)
        if w.shape == (9, 6):
            w = w[:, None, :]
        if w.ndim != 3 or w.shape[0] != 9 or w.shape[2] != 6:
            raise ValueError(f"measure: expected wrenches of shape (9, 6) or (9, K, 6), got {w.shape}")
    est = solve(patch, w, force_threshold, point_contact=point_contact,
                wrench_cov=wrench_cov if point_contact and wrench_cov is not None else None)
    err = np.linalg.norm(est.point - pts[:, None, :], axis=-1)
    rms = np.sqrt(np.nanmean(err**2, axis=1))
    return AccuracyResult(pts, est.point, err, rms)

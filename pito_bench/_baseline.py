"""The papers' plain affine least-squares fit, written independently of ``pito_core.calibration``.

The yardstick: ``calibrate(...)`` with its defaults must never be
worse than this. It shares nothing with pito's fitting code (not ``block_targets``, not
the streamed QR): the target wrenches come straight from the load paths of
docs/conventions.md with ``pito_core.frames``, and the fit is one LAPACK least-squares
solve (``scipy.linalg.lstsq``, single-threaded). Only the method table
(``get_method``: inputs and output frame) is pito's. Used by the ``random_cubes``
section of ``pito bench`` and by ``tests/calibration/test_plain_least_squares.py``.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg
from threadpoolctl import threadpool_limits

from pito_core.calibration import get_method
from pito_core.frames import invert_pose, wrench_adjoint

__all__ = ["plain_affine_lstsq", "plain_contact"]


def _targets(session, output_frame):
    """Wrench on each face from the reference by the load paths (docs/conventions.md).

    Returns
    -------
    targets : ndarray, shape (N, 6, 6)
        ``targets[n, i-1]``: wrench on face i, [fx, fy, fz, tx, ty, tz] in N and N·m, in
        face i's frame (``output_frame="face"``) or in S_A (``"reference"``).
    carries : ndarray of bool, shape (N, 6)
        Face i's target is nonzero.
    usable : ndarray of bool, shape (N,)
        At most one face loaded.
    """
    ref = np.asarray(session.reference, float)
    loaded = np.asarray(session.loaded, bool)
    usable = loaded.sum(axis=1) <= 1
    c = session.connected_face - 1
    T_ati_core = invert_pose(session.T_core_ati)
    T = np.zeros((len(ref), 6, 6))
    for i in range(6):
        X = wrench_adjoint(T_ati_core @ session.core.face_pose(i + 1)) if output_frame == "face" else np.eye(6)
        w = ref @ X.T
        sign = loaded[:, i].astype(float)
        if session.flange == "face" and i == c:
            sign = np.where(loaded[:, c], 1.0, np.where(loaded.any(axis=1), -1.0, 0.0))  # eq. 6
        T[:, i] = w * sign[:, None]
    carries = np.abs(T).sum(axis=2) > 0
    return T, carries, usable


def _lstsq(A, B):
    with threadpool_limits(limits=1):
        return scipy.linalg.lstsq(A, B, lapack_driver="gelsy", check_finite=False)[0]


def plain_affine_lstsq(session, method, output_faces):
    """Fit the plain affine least squares ``[1 | counts − mean] X = W`` on ``session``.

    Centring the columns is an exact re-parametrisation of the affine model; tare samples
    (no face loaded) enter as zero-wrench rows; samples loading two faces or more are
    left out.

    Parameters
    ----------
    session : CalibrationSession
        Training data, in memory.
    method : str or MethodSpec
        Decides the gauges each face is fitted from (``inputs``) and the frame of the fit.
    output_faces : sequence of int
        Faces 1..6 to fit (those ``calibrate`` chose).

    Returns
    -------
    predict : callable
        ``predict(counts)``, counts of shape (N, 36), returns the face wrenches, shape
        (N, 6, 6): ``[:, i-1]`` = [fx, fy, fz, tx, ty, tz] on face i in face i's frame, N
        and N·m; NaN for faces not in ``output_faces``.
    """
    spec = get_method(method)
    counts = np.asarray(session.counts, float)
    T, carries, usable = _targets(session, spec.output_frame)
    unloaded = ~np.asarray(session.loaded).any(axis=1)
    mean = counts.mean(axis=0)
    Sc = counts - mean
    models = []
    if spec.inputs == "own":
        for f in output_faces:
            rows = usable & (carries[:, f - 1] | unloaded)
            cols = slice(6 * (f - 1), 6 * f)
            A = np.c_[np.ones(rows.sum()), Sc[rows, cols]]
            X = _lstsq(A, T[rows, f - 1])
            models.append(((f,), cols, X))
    else:
        idx = [f - 1 for f in output_faces]
        A = np.c_[np.ones(usable.sum()), Sc[usable]]
        X = _lstsq(A, T[usable][:, idx].reshape(-1, 6 * len(idx)))
        models.append((tuple(output_faces), slice(0, 36), X))
    T_ati_core = invert_pose(session.T_core_ati)

    def predict(new_counts):
        x = np.asarray(new_counts, float) - mean
        W = np.full((len(x), 6, 6), np.nan)
        for faces, cols, X in models:
            Y = X[0] + x[:, cols] @ X[1:]
            for k, f in enumerate(faces):
                y = Y[:, 6 * k : 6 * k + 6]
                if spec.output_frame == "reference":
                    y = y @ wrench_adjoint(T_ati_core @ session.core.face_pose(f)).T
                W[:, f - 1] = y
        return W

    return predict


# ---------------------------------------------------------------- contact: the plain closed form
def plain_contact(kind, f, m, *, point=None, normal=None, center=None, semi_axes=None, rotation=None):
    """The soft-finger model's closed form in plain numpy, written apart from ``pito_core.contact``.

    ``m = c × f + τ n(c)``, finger pushing (``f · n < 0``). Plane ``n · x = n · point``:
    ``c = (n × m + d f) / (n · f)``. Ellipsoid ``c = center + R diag(a) q``, ``|q| = 1``
    (a sphere: ``a = (r, r, r)``, ``R = I``): in principal axes ``μ = q × g + κ q`` with
    ``g = Rᵀf / a``, ``μ = a ⊙ Rᵀ(m − center × f) / (a1 a2 a3)``; ``q ∝ v (g × μ) − √v (α μ + v g)``
    with ``α = g · μ`` and ``v`` the non-negative root of ``v² − (|g|² − |μ|²) v − α² = 0``.

    Parameters
    ----------
    kind : {"plane", "sphere", "ellipsoid"}
    f, m : ndarray, shape (N, 3)
        Force (N) and moment about the frame origin (N·m).

    Returns
    -------
    c : ndarray, shape (N, 3)
        Contact point, m.
    n : ndarray, shape (N, 3)
        Outward unit normal.
    tau : ndarray, shape (N,)
        Torsion about ``n``, N·m.
    ok : ndarray of bool, shape (N,)
        A pushing contact exists.
    """
    with np.errstate(divide="ignore", invalid="ignore"):
        if kind == "plane":
            nrm = np.asarray(normal, float)
            fn = f @ nrm
            c = (np.cross(nrm, m) + (np.asarray(point, float) @ nrm) * f) / fn[:, None]
            return c, np.broadcast_to(nrm, f.shape), np.sum(f * m, axis=1) / fn, fn < 0
        a = np.asarray(semi_axes, float)
        R = np.eye(3) if rotation is None else np.asarray(rotation, float)
        c0 = np.asarray(center, float)
        g = (f @ R) / a
        mu = ((m - np.cross(c0, f)) @ R) * a / np.prod(a)
        gg, alpha = np.sum(g * g, axis=1), np.sum(g * mu, axis=1)
        B = gg - np.sum(mu * mu, axis=1)
        v = 0.5 * (B + np.sqrt(B * B + 4 * alpha * alpha))
        q = v[:, None] * np.cross(g, mu) - np.sqrt(v)[:, None] * (alpha[:, None] * mu + v[:, None] * g)
        q /= np.linalg.norm(q, axis=1, keepdims=True)
        ok = np.sum(g * q, axis=1) < 0
        n = (q / a) @ R.T
        n /= np.linalg.norm(n, axis=1, keepdims=True)
        c = c0 + (q * a) @ R.T
        return c, n, np.sum(n * (m - np.cross(c, f)), axis=1), ok

"""Issue 25, item 5: the fast least-squares core (Cholesky of the Gram matrix) against LAPACK, on hard data.

``GramQR`` squares the condition number, so it solves only designs whose column-scaled
condition number κ is at most ``GRAM_KAPPA_MAX`` (10⁴) and says ``trouble()`` otherwise;
the fit then takes the streamed Householder QR. Checked on designs of κ = 1 … 10⁸ against
``numpy.linalg.lstsq`` with stated bounds, and through ``calibrate`` on a cube whose gauges
are nearly dependent.
"""

import numpy as np
import pytest
from gen import make_session, true_sensitivity

from pito_core.calibration import GRAM_KAPPA_MAX, GramQR, StreamedQR, calibrate

EPS = np.finfo(float).eps


def _design(kappa, n=4000, p=24, q=6, seed=0, noise=1e-3):
    """``A (n, p)`` with unit-norm columns and condition number ≈ κ, ``B = A X + noise``."""
    rng = np.random.default_rng(seed)
    U, _ = np.linalg.qr(rng.normal(size=(n, p)))
    V, _ = np.linalg.qr(rng.normal(size=(p, p)))
    A = (U * np.logspace(0, -np.log10(kappa), p)) @ V.T
    A = A * rng.uniform(1e-3, 1e3, p)  # columns of very different scale: the core scales them
    X = rng.normal(size=(p, q))
    B = A @ X + noise * np.linalg.norm(A @ X) / np.sqrt(n * q) * rng.normal(size=(n, q))
    return A, B


def _scaled_kappa(A):
    s = np.linalg.svd(A / np.linalg.norm(A, axis=0), compute_uv=False)
    return s[0] / s[-1]


def _gram(A, B, blocks=4):
    G = np.zeros((A.shape[1] + B.shape[1],) * 2)
    for Z in np.array_split(np.hstack([A, B]), blocks):  # summed over blocks, as the fit does
        G += Z.T @ Z
    p = A.shape[1]
    return GramQR(G[:p, :p], G[:p, p:], G[p:, p:], A.shape[0])


@pytest.mark.parametrize("kappa", [1.0, 1e4, 1e8])
def test_gram_core_is_used_only_where_it_is_accurate(kappa):
    A, B = _design(kappa)
    k = _scaled_kappa(A)
    X_ref = np.linalg.lstsq(A, B, rcond=None)[0]
    fit_ref = A @ X_ref
    g = _gram(A, B)
    if g.trouble() is None:
        assert k <= 1.5 * GRAM_KAPPA_MAX
        res = g.solve()
        # forward error of the normal equations: ε κ² (with a margin of 10 for the constants)
        assert np.linalg.norm(res.X - X_ref) / np.linalg.norm(X_ref) <= 10 * EPS * k**2 + 1e-13
        # its residual sum of squares, from BᵀB − R12ᵀR12, matches the true one
        rss = np.sum((B - A @ res.X) ** 2, axis=0)
        np.testing.assert_allclose(np.diag(res.residual_cp), rss, rtol=1e-6)
    else:
        assert k > GRAM_KAPPA_MAX / 1.5, g.trouble()
        acc = StreamedQR(A.shape[1], B.shape[1])
        for a, b in zip(np.array_split(A, 4), np.array_split(B, 4)):
            acc.add(a, b)
        res = acc.solve()
        # Householder QR is backward stable: its fitted values match LAPACK's to ~ε κ
        assert np.linalg.norm(A @ res.X - fit_ref) / np.linalg.norm(fit_ref) <= 100 * EPS * k
    assert kappa < 1e5 or g.trouble() is not None  # κ = 10⁶, 10⁸: always refused


def test_gram_core_refuses_empty_and_dependent_columns():
    A, B = _design(10.0)
    A[:, 3] = 0.0
    assert "empty" in _gram(A, B).trouble()
    A, B = _design(10.0)
    A[:, 5] = 2 * A[:, 4]
    assert _gram(A, B).trouble() is not None


@pytest.mark.parametrize("dependence", [1e-3, 1e-6])
def test_calibrate_falls_back_to_qr_on_nearly_dependent_gauges(dependence):
    """Gauge 7 nearly a copy of gauge 1 (κ of the scaled design ~1/dependence): the fit matches LAPACK."""
    K = true_sensitivity(31)
    s = make_session(K, flange="frame_hole", connected_face=6, k=400, noise=2.0, counts_dtype=float)
    rng = np.random.default_rng(3)
    counts = s.counts.copy()
    counts[:, 6] = counts[:, 0] + dependence * rng.normal(size=len(counts)) * np.std(counts[:, 0])  # gauge 1 again, plus a trace
    s.counts = counts
    cal = calibrate(s, "loaded_frame", model="linear")
    # the same affine least squares by LAPACK: [1 | counts − tare mean] X = targets (in S_A)
    free = ~s.loaded.any(axis=1)
    x = counts - counts[free].mean(axis=0)
    A = np.hstack([np.ones((len(x), 1)), x])
    T = np.where(s.loaded[:, :, None], s.reference[:, None, :], 0.0).reshape(len(x), 36)
    X = np.linalg.lstsq(A, T, rcond=None)[0]
    ours = A[:, 1:] @ cal.matrix.T
    theirs = A[:, 1:] @ X[1:]
    scale = np.linalg.norm(theirs)
    assert np.linalg.norm((ours - ours.mean(0)) - (theirs - theirs.mean(0))) / scale <= 1e-7

"""Single-contact test on random touches made here (not by pito_core.sim or the benchmark).

Patches of our own (tilted plane with an elliptic edge, off-centre sphere cap cut by a
square, rotated ellipsoid cut by a hexagon, icosphere mesh), touches drawn by rejection
sampling on the patch, a fingertip force of log-normal magnitude with its shear and twist
drawn inside the limit surface, and a simulated calibration: gauge noise plus a fixed
calibration matrix error per calibration (20 calibrations), whose covariance is handed to
the test as a calibration's ``return_cov`` would. Claims:

* single touches: flagged ≤ 5 % (soft finger and point contact);
* two-finger touches whose best single-contact explanation breaks a limit by more than
  3 σ of its margin (σ by Monte Carlo over noisy repeats): ≥ 90 % flagged;
* both again through a calibration fitted (``quasi_total``) to the linear gauge model of
  ``tests/calibration/gen.py``, with the covariance of its ``wrenches(return_cov=True)``.
"""

import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

from pito_core.calibration import calibrate
from pito_core.contact import Ellipsoid, MeshSurface, Patch, PatchBoundary, Plane, Sphere, load_patch, solve

sys.path.insert(0, str(Path(__file__).parents[1] / "calibration"))  # its gen.py: a known linear gauge model
from gen import make_session, true_sensitivity  # noqa: E402

MU, E = 0.8, 0.004  # this test's fingertip: friction coefficient, torsional radius (m)
SIG = np.array([0.03] * 3 + [3e-4] * 3)  # gauge noise: N, N·m
EPS = 0.01  # relative calibration error
SCALE = np.array([1.0, 1.0, 1.0, 0.025, 0.025, 0.025])


def _patches():
    hexagon = 0.018 * np.c_[np.cos(np.arange(6) * np.pi / 3), np.sin(np.arange(6) * np.pi / 3)]
    ico = trimesh.creation.icosphere(subdivisions=3, radius=0.03)
    ico.apply_translation([0.0, 0.0, -0.012])
    kw = dict(mu=MU, torsion_radius=E)
    return {
        "plane": Patch(Plane([0.001, 0.0, 0.003], [0.1, -0.05, 1.0]),
                       PatchBoundary("ellipse", radii=[0.02, 0.015]), **kw),
        "sphere": Patch(Sphere([0.002, -0.001, -0.03], 0.035),
                        PatchBoundary("rectangle", size=[0.03, 0.03], z_min=0.0), **kw),
        "ellipsoid": Patch(Ellipsoid([0.0, 0.0, -0.004], [0.022, 0.03, 0.012],
                                     Rotation.from_rotvec([0.1, 0.2, 0.7]).as_matrix()),
                           PatchBoundary("polygon", vertices=hexagon, z_min=0.0), **kw),
        "mesh": Patch(MeshSurface(ico), PatchBoundary(None, z_min=0.004), **kw),
    }


def _points(patch, n, rng):
    """Uniform-ish random points on the patch (rejection sampling) and their outward normals."""
    s = patch.surface
    pts, nrm = np.empty((0, 3)), np.empty((0, 3))
    while len(pts) < n:
        if isinstance(s, Plane):
            xy = rng.uniform(-0.025, 0.025, (4 * n, 2))
            p = np.c_[xy, (s.offset - xy @ s.normal[:2]) / s.normal[2]]
            q = np.broadcast_to(s.normal, p.shape)
        elif isinstance(s, MeshSurface):
            p, fi = trimesh.sample.sample_surface(s.mesh, 4 * n, seed=int(rng.integers(2**31)))
            q = s.mesh.face_normals[fi]
        else:
            d = rng.normal(size=(4 * n, 3))
            d[:, 2] = np.abs(d[:, 2])
            d /= np.linalg.norm(d, axis=1, keepdims=True)
            p = s.center + (d * s.semi_axes) @ s.rotation.T
            q = s.normal_at(p)
        keep = patch.boundary.margin(p) > 0.001
        pts, nrm = np.r_[pts, p[keep]], np.r_[nrm, q[keep]]
    return pts[:n], nrm[:n]


def _fingertip(nrm, rng, twist=True):
    """Force and torsion of one fingertip strictly inside its limit surface."""
    n = len(nrm)
    fn = rng.lognormal(np.log(3.0), 0.6, n)
    a = rng.uniform(0, 2 * np.pi, n)
    r = 0.97 * np.sqrt(rng.uniform(0, 1, n))  # share of the limit surface used
    t1 = np.cross(nrm, rng.normal(size=(n, 3)))
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    shear = MU * fn * r * (np.abs(np.cos(a)) if twist else 1.0)
    f = -fn[:, None] * nrm + shear[:, None] * t1
    tau = MU * E * fn * r * np.sin(a) if twist else np.zeros(n)
    return f, tau


def _wrench(c, nrm, f, tau):
    return np.c_[f, np.cross(c, f) + tau[:, None] * nrm]


def _measure(w, rng, n_cal=20):
    """Measured wrenches through one of ``n_cal`` miscalibrated sensors, and their covariance."""
    errs = rng.normal(size=(n_cal, 6, 6)) * EPS * SCALE[None, :, None] / SCALE[None, None, :]
    which = rng.integers(0, n_cal, len(w))
    meas = w + np.einsum("nij,nj->ni", errs[which], w) + rng.normal(size=w.shape) * SIG
    load = np.sum((w / SCALE) ** 2, axis=1)
    cov = np.zeros((len(w), 6, 6))
    cov[:, np.arange(6), np.arange(6)] = SIG**2 + (EPS * SCALE) ** 2 * load[:, None]
    return meas, cov


def _margins(patch, est):
    """This test's own margins: pushing (N), friction limit surface (N), distance to the edge (m)."""
    fn = -np.einsum("ij,ij->i", est.force, est.normal)
    ft = np.linalg.norm(est.force + fn[:, None] * est.normal, axis=1)
    fric = MU * fn - np.sqrt(ft**2 + (est.torsion / E) ** 2)
    return np.c_[fn, fric, patch.boundary.margin(est.point)]


def _separation(patch, w0, cov, rng, repeats=60):
    """How many σ the single-contact explanation of the noise-free ``w0`` breaks its worst limit by."""
    est0 = solve(patch.surface, w0, force_threshold=0.0)
    g0 = _margins(patch, est0)
    L = np.linalg.cholesky(cov)
    noisy = np.repeat(w0, repeats, 0) + np.einsum("nij,nj->ni", np.repeat(L, repeats, 0),
                                                  rng.normal(size=(len(w0) * repeats, 6)))
    g = _margins(patch, solve(patch.surface, noisy, force_threshold=0.0)).reshape(len(w0), repeats, 3)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # rows without a solution in any repeat
        q = np.nanpercentile(np.where(np.isfinite(g), g, np.nan), [15.87, 84.13], axis=1)
    sig = 0.5 * (q[1] - q[0])
    with np.errstate(invalid="ignore", divide="ignore"):
        z = np.where(sig > 0, -g0 / sig, np.where(g0 < 0, np.inf, -np.inf))
    D = np.max(np.where(np.isnan(z), -np.inf, z), axis=1)
    return np.where(np.isfinite(est0.point).all(axis=1), D, np.inf)


PATCHES = _patches()


@pytest.mark.parametrize("kind", list(PATCHES))
def test_single_touches_raise_at_most_5_percent_false_alarms(kind):
    patch = PATCHES[kind]
    rng = np.random.default_rng(sum(map(ord, kind)))
    c, nrm = _points(patch, 1000, rng)
    f, tau = _fingertip(nrm, rng)
    w, cov = _measure(_wrench(c, nrm, f, tau), rng)
    est = solve(patch, w, wrench_cov=cov)
    assert np.mean(~est.single_contact) <= 0.05
    assert np.all((est.single_contact_p >= 0) & (est.single_contact_p <= 1))
    f, _ = _fingertip(nrm, rng, twist=False)
    w, cov = _measure(_wrench(c, nrm, f, np.zeros(len(c))), rng)
    est = solve(patch, w, wrench_cov=cov, point_contact=True)
    assert np.mean(~est.single_contact) <= 0.05


@pytest.mark.parametrize("kind", list(PATCHES))
def test_two_finger_touches_beyond_the_noise_are_flagged(kind):
    patch = PATCHES[kind]
    rng = np.random.default_rng(7 + sum(map(ord, kind)))
    n = 1500
    c1, n1 = _points(patch, n, rng)
    c2, n2 = _points(patch, n, rng)
    f1, t1 = _fingertip(n1, rng)
    f2, t2 = _fingertip(n2, rng)
    ratio = rng.uniform(0.2, 1.0, n)
    far = np.linalg.norm(c1 - c2, axis=1) > 0.004
    w0 = (_wrench(c1, n1, f1, t1) + ratio[:, None] * _wrench(c2, n2, f2, t2))[far]
    w, cov = _measure(w0, rng)
    D = _separation(patch, w0, cov, rng)
    flagged = ~solve(patch, w, wrench_cov=cov).single_contact
    beyond = D > 3.0
    assert beyond.sum() >= 30  # enough cases for the claim to mean something
    assert flagged[beyond].mean() >= 0.90
    # and those exactly explained by one fingertip well inside its limits are rarely flagged
    inside = D < -3.0
    assert flagged[inside].mean() <= 0.05


def test_a_fitted_calibration_and_its_own_covariance():
    """Touches on face 6 of a cube measured through a calibration fitted to a known linear gauge
    model (tests/calibration/gen.py: not pito_core.sim); the test gets the calibration's
    ``return_cov`` covariance (fit error + gauge noise), as the pipeline does."""
    K = true_sensitivity(23)
    s = make_session(K, flange="frame", connected_face=1, k=400, noise=20.0, seed=23)
    cal = calibrate(s, "quasi_total")
    flat = load_patch("flat_46mm")
    patch = Patch(flat.surface, flat.boundary, mu=MU, torsion_radius=E)
    rng = np.random.default_rng(23)

    def measure(w):
        F = np.zeros((len(w), 6, 6))
        F[:, 5] = w
        counts = s.true_offset + F.reshape(-1, 36) @ K.T + rng.normal(scale=20.0, size=(len(w), 36))
        W, cov = cal.wrenches(counts, return_cov=True)
        return W[:, 5], cov[:, 5]

    c, nrm = _points(patch, 1500, rng)
    f, tau = _fingertip(nrm, rng)
    w, cov = measure(_wrench(c, nrm, f, tau))
    est = solve(patch, w, wrench_cov=cov)
    assert est.valid.mean() > 0.99 and np.mean(~est.single_contact) <= 0.05
    c1, n1 = _points(patch, 600, rng)
    c2, n2 = _points(patch, 600, rng)
    (f1, t1), (f2, t2) = _fingertip(n1, rng), _fingertip(n2, rng)
    w0 = _wrench(c1, n1, f1, t1) + rng.uniform(0.2, 1.0, 600)[:, None] * _wrench(c2, n2, f2, t2)
    w, cov = measure(w0)
    D = _separation(patch, w0, cov, rng)
    flagged = ~solve(patch, w, wrench_cov=cov).single_contact
    assert (D > 3).sum() >= 30 and flagged[D > 3].mean() >= 0.90

"""What a calibration measures (``Calibration.coverage``) on a random linear cube built here, not ``pito_core.sim``'s.

A face-flange calibration that never loads the connected face nor the net load says so (and the
live pipeline shows NaN, never a silent 0); with the completing ``frame_hole`` session it measures
everything, and a resting and a grasped object read without phantom forces and with ‖ΣF‖ = m·g,
within the calibration's own error. Seeded, deterministic.
"""

import numpy as np
import pytest

from pito_core.calibration import (
    CalibrationSession, Coverage, calibrate, completing_mount, load_calibration,
)
from pito_core.frames import CubeCore, invert_pose, wrench_adjoint
from pito_core.pipeline import Pipeline

CORE = CubeCore()
FS = np.array([15.0, 15.0, 15.0, 0.1, 0.1, 0.1])
K99 = 3.37  # √χ²₃(0.99): 99 % radius of a 3-D error in σ of its largest axis


class LinearCube:
    """Counts = K · (face wrenches / full scale) + offset + noise: 36×36, dense coupling, own seed."""

    def __init__(self, seed=5):
        rng = np.random.default_rng(seed)
        K = rng.standard_normal((36, 36)) * 0.08
        for f in range(6):
            K[6 * f:6 * f + 6, 6 * f:6 * f + 6] += rng.standard_normal((6, 6)) + 3 * np.eye(6)
        self.K = K * 2e4
        self.offset = rng.uniform(-1e5, 1e5, 36)
        self.noise = rng.uniform(1.0, 4.0, 36)
        self.rng = rng

    def counts(self, W):
        W = np.asarray(W).reshape(-1, 36) / np.tile(FS, 6)
        return W @ self.K.T + self.offset + self.rng.standard_normal((W.shape[0], 36)) * self.noise


def X(a, b):
    """Wrench in face a's frame → face b's frame (a, b in 1..6; 0 is the core frame)."""
    T = lambda f: np.eye(4) if f == 0 else CORE.face_pose(f)  # noqa: E731
    return wrench_adjoint(invert_pose(T(a)) @ T(b))


def session(cube, flange, c, faces, k=800, seed=0):
    """Single-face loads uniform in full scale, by the load paths of docs/conventions.md (written here)."""
    rng = np.random.default_rng([seed, c, len(flange)])
    T_core_ati = CORE.face_pose(c).copy()
    T_core_ati[:3, 3] += CORE.face_pose(c)[:3, 2] * 0.02  # the reference 2 cm out of the connected face
    X_ati = lambda j: wrench_adjoint(invert_pose(CORE.face_pose(j)) @ T_core_ati)  # noqa: E731
    n_tare = 200
    W = np.zeros((n_tare + k * len(faces), 6, 6))
    ref = np.zeros((W.shape[0], 6))
    loaded = np.zeros((W.shape[0], 6), bool)
    for n, j in enumerate(faces):
        rows = slice(n_tare + n * k, n_tare + (n + 1) * k)
        w = rng.uniform(-1, 1, (k, 6)) * FS
        W[rows, j - 1] = w
        if flange == "face" and j != c:
            W[rows, c - 1] = -w @ X(j, c).T
        ref[rows] = w @ X_ati(j).T
        loaded[rows, j - 1] = True
    return CalibrationSession(cube.counts(W).round(), ref, loaded, T_core_ati, flange, c, core=CORE,
                              meta={"simulated": True})


def opposite(f):
    n = CORE.face_pose(f)[:3, 2]
    return next(g for g in range(1, 7) if np.allclose(CORE.face_pose(g)[:3, 2], -n))


def object_loads(weight=2.94, squeeze=8.0, table=6, grip=None):
    """Face wrenches (6, 6) of an object under gravity: on the table (face ``table``), or held by two opposite faces."""
    W = np.zeros((6, 6))
    up = -CORE.face_pose(table)[:3, 2] * weight  # the support pushes against gravity
    if grip is None:
        W[table - 1] = np.r_[up, 0, 0, 0] @ X(0, table).T
        return W
    for f in (grip, opposite(grip)):
        F = -CORE.face_pose(f)[:3, 2] * squeeze + up / 2  # pushing in, carrying half the weight
        W[f - 1] = np.r_[F, 0, 0, 0] @ X(0, f).T  # (at the face centre: no moment about it)
    return W


def live(cal, cube, W, n=20):
    pipe = Pipeline(cal, has_reference=False, smooth=n)
    b = pipe.process({"time": np.arange(n) / 1000.0, "counts": cube.counts(np.repeat(W[None], n, axis=0))})
    _, cov = cal.wrenches(cube.counts(W[None]), return_cov=True)
    return b, cov[0]


def test_a_face_flange_alone_measures_neither_the_net_load_nor_any_face_and_says_so():
    cube = LinearCube()
    cal = calibrate(session(cube, "face", 6, (1, 2, 3, 4, 5)), "unloaded_frame")
    cov = cal.coverage
    assert not cov.net_load and not cov.faces.any() and not cov.complete
    assert "net load" in cov.describe() and "not measured by this calibration" in cov.describe()
    # the defect it guards: the plain fit reads ΣF ≈ 0 under the object's weight, silently
    W = cal.wrenches(cube.counts(object_loads()[None]))[0]
    assert np.linalg.norm(sum(CORE.face_pose(f)[:3, :3] @ W[f - 1, :3] for f in range(1, 7))) < 0.5
    b, _ = live(cal, cube, object_loads())
    assert np.isnan(b.sum_force).all() and np.isnan(b.wrenches).all() and not b.contacts.valid.any()


@pytest.mark.parametrize("method", ["unloaded_frame", "quasi_total", "face_to_face"])
def test_the_completing_mount_measures_the_rest(method):
    cube = LinearCube(seed=11)
    flange = "face" if method == "unloaded_frame" else "frame"
    main = session(cube, flange, 6, (1, 2, 3, 4, 5), seed=1)
    extra = completing_mount(method, flange, 6)
    assert extra is not None and extra.flange == "frame_hole" and extra.faces == (6,) and extra.why
    cal = calibrate([main, session(cube, extra.flange, 6, extra.faces, seed=2)], method)
    cov = cal.coverage
    if method == "quasi_total":  # 30 × 36 by definition: face 6 and the net load stay unmeasured, said so
        assert cov.faces[:5].all() and not cov.faces[5].any() and not cov.net_load
    else:
        assert cov.complete
    for W in (object_loads(), object_loads(grip=1), object_loads(grip=2)):
        b, c = live(cal, cube, W)
        untouched = np.linalg.norm(W[:, :3], axis=1) == 0
        for f in np.flatnonzero(untouched & cov.face_measured):
            sigma = np.sqrt(np.linalg.eigvalsh(c[f, :3, :3]).max())
            assert np.linalg.norm(b.wrenches[f, :3]) <= K99 * sigma, f"phantom on face {f + 1}"
        if cov.net_load:
            s = np.sqrt(sum(np.linalg.eigvalsh(c[f, :3, :3]).max() for f in range(6)))
            assert abs(np.linalg.norm(b.sum_force) - 2.94) <= K99 * s
        else:
            assert np.isnan(b.sum_force).all() and np.isnan(b.wrenches[5]).all()


def test_complete_methods_need_no_extra_mount():
    assert completing_mount("total", "face", 6) is None
    assert completing_mount("loaded_frame", "frame_hole", 3) is None
    assert completing_mount("face_to_face", "frame_hole", 3) is None


def test_coverage_is_saved_and_old_files_load(tmp_path):
    cube = LinearCube(seed=3)
    cal = calibrate(session(cube, "face", 2, (1, 3, 4, 5, 6), seed=4), "unloaded_frame")
    cal.save(tmp_path / "c.pitocal")
    back = load_calibration(tmp_path / "c.pitocal")
    assert (back.coverage.faces == cal.coverage.faces).all() and back.coverage.net_load == cal.coverage.net_load
    assert back.coverage.known
    # a file from before the record: derived from its net-load note
    old = dict(cal.meta)
    old.pop("coverage")
    derived = Coverage.from_meta(old, cal.has_output)
    assert not derived.known and not derived.net_load and not derived.faces.any()
    old["net_load"], old["flanges"] = "measured", ["frame_hole"]
    assert Coverage.from_meta(old, cal.has_output).complete
    with pytest.raises(ValueError, match="faces"):
        Coverage(np.ones((5, 6), bool), True)

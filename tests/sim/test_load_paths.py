"""Load paths per mount (docs/conventions.md) and the sessions the protocols write."""

import numpy as np
import pytest

from pito_core.frames import CubeCore, invert_pose, transform_wrench
from pito_core.sim import (
    SQUEEZE_PAIRS,
    TOUCH_POINTS,
    VirtualCube,
    face_wrenches_from_applied,
    reference_pose,
    simulate_calibration,
    simulate_squeeze,
    simulate_touches,
)

CORE = CubeCore()


def _to_core(F):
    """Face-frame wrenches (N, 6, 6) -> core frame, each about the core centre."""
    out = np.zeros_like(F)
    for i in range(6):
        out[:, i] = transform_wrench(F[:, i], invert_pose(CORE.face_pose(i + 1)))
    return out


def _applied(seed=0, faces=(1, 2, 3, 4, 5, 6)):
    rng = np.random.default_rng(seed)
    W = np.zeros((20, 6, 6))
    for j in faces:
        W[:, j - 1] = rng.uniform(-1, 1, (20, 6)) * [10, 10, 10, 0.3, 0.3, 0.3]
    return W


@pytest.mark.parametrize("c", [1, 4, 6])
def test_frame_flange_connected_face_carries_nothing(c):
    W = _applied(faces=[j for j in range(1, 7) if j != c])
    F, W_tot, W_frame = face_wrenches_from_applied(W, "frame", c, CORE)
    Fc = _to_core(F)
    assert np.allclose(F[:, c - 1], 0)
    for j in range(1, 7):
        if j != c:
            assert np.allclose(Fc[:, j - 1], W[:, j - 1])
    assert np.allclose(W_tot, W.sum(axis=1))
    assert W_frame is not None and np.allclose(W_frame, W_tot)  # the load passes through the frame


def test_frame_flange_refuses_load_on_connected_face():
    W = _applied()
    with pytest.raises(ValueError, match="cannot be loaded"):
        face_wrenches_from_applied(W, "frame", 2, CORE)


@pytest.mark.parametrize("c", [2, 6])
def test_frame_hole_connected_face_loaded_through_hole(c):
    W = _applied()
    F, W_tot, W_frame = face_wrenches_from_applied(W, "frame_hole", c, CORE)
    assert np.allclose(_to_core(F), W)
    assert np.allclose(W_tot, W.sum(axis=1))
    assert W_frame is not None and np.allclose(W_frame, W_tot)  # every load, the connected face's too, through the frame


@pytest.mark.parametrize("c", [3, 5, 6])
def test_face_flange_connected_face_carries_the_reaction(c):
    W = _applied(faces=[j for j in range(1, 7) if j != c])
    F, W_tot, W_frame = face_wrenches_from_applied(W, "face", c, CORE)
    Fc = _to_core(F)
    assert np.allclose(Fc[:, c - 1], -W_tot)  # reaction −W
    assert np.allclose(Fc.sum(axis=1), 0, atol=1e-12)  # the faces balance: nothing through the frame
    assert W_frame is None


def test_face_flange_direct_load_on_connected_face_is_carried_by_it():
    """Eq. 6 of the multi-touch paper: under face 6's own load, face 6 carries W_6."""
    W = np.zeros((5, 6, 6))
    W[:, 5] = [1, 2, -8, 0.05, 0, 0.02]
    F, W_tot, W_frame = face_wrenches_from_applied(W, "face", 6, CORE)
    Fc = _to_core(F)
    assert np.allclose(Fc[:, 5], W[:, 5]) and np.allclose(Fc[:, :5], 0)
    assert np.allclose(W_tot, W[:, 5])  # the reference reads it too


def test_free_grasp_faces_carry_everything():
    W = _applied()
    F, W_tot, W_frame = face_wrenches_from_applied(W, None, None, CORE)
    assert np.allclose(_to_core(F), W) and W_frame is None


def test_mount_validation():
    with pytest.raises(ValueError, match="flange"):
        face_wrenches_from_applied(_applied(), "bolted", 1, CORE)
    with pytest.raises(ValueError, match="connected_face"):
        face_wrenches_from_applied(_applied(), "face", 7, CORE)
    with pytest.raises(ValueError, match="applied_core"):
        face_wrenches_from_applied(np.zeros((3, 6)), "face", 1, CORE)


# ------------------------------------------------------------------ protocols
@pytest.fixture(scope="module")
def cube():
    return VirtualCube()


@pytest.mark.parametrize("flange, c", [("frame", 6), ("frame_hole", 2), ("face", 6)])
def test_calibration_session(cube, flange, c):
    s, truth = simulate_calibration(flange, c, k=400, seed=1, model=cube, return_truth=True)
    n = len(s)
    loaded = np.asarray(s.loaded)
    assert s.counts.shape == (n, 36) and s.counts.dtype == np.int32
    assert s.flange == flange and s.connected_face == c and s.meta["simulated"] is True
    assert loaded.sum(axis=1).max() == 1  # one face at a time
    unloaded = ~loaded.any(axis=1)
    n_tare = np.argmax(~unloaded)
    assert n_tare >= 0.04 * n  # tare first (~5 %)
    faces_loaded = set(np.flatnonzero(loaded.any(axis=0)) + 1)
    expected = {1, 2, 3, 4, 5, 6} - ({c} if flange == "frame" else set())
    assert faces_loaded == expected
    assert np.allclose(s.T_core_ati, reference_pose(flange, c, cube.core))
    # applied loads within the papers' ranges (face frame of the loaded face)
    F_face = truth.face_wrenches
    for j in expected - {c}:
        rows = loaded[:, j - 1]
        assert np.abs(F_face[rows, j - 1, :3]).max() <= 15 + 1e-9
        assert np.abs(F_face[rows, j - 1, 3:]).max() <= 0.1 + 1e-9
        assert np.abs(F_face[rows, j - 1, :3]).max() > 5
    # the reference reads the total applied load in its frame, within its noise
    ideal = transform_wrench(truth.total, s.T_core_ati)
    err = np.asarray(s.reference) - ideal
    assert np.abs(err[:, :3]).max() < 0.2 and np.abs(err[:, 3:]).max() < 0.005
    assert truth.through_frame == (flange != "face")
    # unloaded samples: no load anywhere
    assert np.allclose(truth.face_wrenches[unloaded], 0)


def test_calibration_reproducible_by_seed(cube):
    a = simulate_calibration("face", 6, k=200, seed=4, model=cube)
    b = simulate_calibration("face", 6, k=200, seed=4, model=cube)
    c = simulate_calibration("face", 6, k=200, seed=5, model=cube)
    assert np.array_equal(a.counts, b.counts) and np.array_equal(a.reference, b.reference)
    assert not np.array_equal(a.counts, c.counts)


def test_calibration_session_round_trips(cube, tmp_path):
    from pito_core.calibration import CalibrationSession

    s = simulate_calibration("frame_hole", 3, k=100, model=cube)
    s.save(tmp_path / "s.h5")
    r = CalibrationSession.load(tmp_path / "s.h5")
    assert np.array_equal(r.counts, s.counts) and r.counts_range == cube.counts_range
    assert r.meta["simulated"] is True


def test_calibration_validation(cube):
    with pytest.raises(ValueError, match="faces"):
        simulate_calibration("frame", 6, k=100, faces=(1, 6), model=cube)
    with pytest.raises(ValueError, match="flange"):
        simulate_calibration(None, 6, k=100, model=cube)
    with pytest.raises(ValueError, match="k"):
        simulate_calibration("face", 6, k=3, model=cube)
    with pytest.raises(ValueError, match="model"):
        simulate_calibration("face", 6, k=100, model="cube")


def test_squeeze_pairs(cube):
    s, truth = simulate_squeeze("face", 6, k=200, model=cube, return_truth=True)
    loaded = np.asarray(s.loaded)
    pairs = {tuple(np.flatnonzero(r) + 1) for r in loaded if r.any()}
    assert pairs == {tuple(sorted(p)) for p in SQUEEZE_PAIRS}
    # fingers press into the faces (face-frame fz <= 0)
    for a, b in SQUEEZE_PAIRS:
        rows = loaded[:, a - 1] & loaded[:, b - 1]
        assert truth.face_wrenches[rows, a - 1, 2].max() <= 1e-9
    # the connected face carries the reaction of both
    Fc = _to_core(truth.face_wrenches)
    assert np.allclose(Fc[:, 5], -truth.total)
    # under a frame flange, pairs with the connected face are skipped
    s2 = simulate_squeeze("frame", 5, k=100, model=cube)
    assert not np.asarray(s2.loaded)[:, 4].any()
    assert len(s2.meta["pairs"]) == sum(5 not in p for p in SQUEEZE_PAIRS)


def test_touches_truth(cube):
    s, tr = simulate_touches(5, "face", 6, k=300, model=cube)
    assert tr.points.shape == (9, 3)
    assert np.allclose(tr.points[:, :2], TOUCH_POINTS)
    assert np.allclose(np.abs(tr.points[:8, :2]).max(axis=1), 0.013)  # on the 26 mm square's edges
    touching = tr.point_index >= 0
    # the face wrench is the soft-finger contact wrench [f, c × f + τ n]
    F5 = tr.sim.face_wrenches[touching, 4]
    m = np.cross(tr.point[touching], tr.force[touching]) + tr.torsion[touching, None] * [0, 0, 1]
    assert np.allclose(F5[:, 3:], m, atol=1e-9)
    assert np.all(tr.force[touching, 2] <= 1e-12)  # pressing into the patch
    with pytest.raises(ValueError, match="face"):
        simulate_touches(6, "face", 6, k=100, model=cube)

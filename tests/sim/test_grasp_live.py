"""Free grasp physics (Newton–Euler at every sample) and the live sources."""

import numpy as np
import pytest

from pito_core.frames import CubeCore
from pito_core.sim import (
    GRAVITY,
    CalibrationLiveSource,
    GraspLiveSource,
    GraspScenario,
    VirtualCube,
    default_live_source,
    reference_pose,
    simulate_free_grasp,
)


@pytest.fixture(scope="module")
def run():
    return simulate_free_grasp(k=12_000, seed=2)


def test_free_grasp_force_equilibrium(run):
    st = run.state
    total = st.applied.sum(axis=1)
    # Σ F_i + m g = m a at every sample
    assert np.allclose(total[:, :3] + run.mass * st.gravity, run.mass * st.accel, atol=1e-9)
    assert np.allclose(np.linalg.norm(st.gravity, axis=1), np.linalg.norm(GRAVITY))
    # there is some dynamics, and quasi-static holds where the faces carry the weight
    acc = np.linalg.norm(st.accel, axis=1)
    assert acc.max() > 0.3
    still = acc < 1e-6
    assert still.any()
    assert np.allclose(np.linalg.norm(total[still, :3], axis=1), run.weight, rtol=1e-6)


def test_free_grasp_moment_equilibrium(run):
    st = run.state
    sc = run.scenario
    total = st.applied.sum(axis=1)
    F_req = run.mass * (st.accel - st.gravity)
    # moments about the core centre: Σ M_i − c × m(a − g) = I α + ω × I ω, small for this object
    M_cog = total[:, 3:] - np.cross(sc.cog, F_req)
    assert np.abs(M_cog).max() < 5e-3
    still = np.linalg.norm(st.accel, axis=1) < 1e-6
    assert np.allclose(M_cog[still], 0, atol=1e-9)


def test_free_grasp_faces_carry_everything_and_fingers_push(run):
    st = run.state
    sc = run.scenario
    core = sc.core
    # face wrenches are the applied loads expressed in the face frames
    from pito_core.frames import transform_wrench

    for i in range(6):
        assert np.allclose(transform_wrench(st.applied[:, i], core.face_pose(i + 1)), st.face_wrenches[:, i])
    fn = np.einsum("nkc,kc->nk", st.finger_force, sc.normals)
    assert np.all(fn[st.finger_active] <= 1e-9)  # fingers push into the patches
    assert st.on_table.any() and (~st.on_table).any()


def test_free_only_has_no_table():
    r = simulate_free_grasp(k=2000, free_only=True, n_fingers=5)
    assert not r.state.on_table.any()
    assert np.allclose(r.state.table_wrench, 0)
    assert np.all(r.state.finger_active)


def test_grasp_reproducible_by_seed():
    a = simulate_free_grasp(k=1000, seed=1)
    b = simulate_free_grasp(k=1000, seed=1)
    c = simulate_free_grasp(k=1000, seed=2)
    assert np.array_equal(a.counts, b.counts)
    assert not np.array_equal(a.counts, c.counts)


def test_grasp_validation():
    with pytest.raises(ValueError, match="mass"):
        GraspScenario(mass=0)
    with pytest.raises(ValueError, match="n_fingers"):
        GraspScenario(n_fingers=7)
    with pytest.raises(ValueError, match="cog"):
        GraspScenario(cog=(0, 0))


# ------------------------------------------------------------------ live sources
def test_grasp_live_source_is_a_function_of_time():
    src = default_live_source(seed=3)
    assert isinstance(src, GraspLiveSource)
    t = np.arange(0, 13.0, 0.001)
    c = src.counts_at(t)
    r = src.reference_at(t)
    assert c.shape == (t.size, 36) and c.dtype == np.int32 and r.shape == (t.size, 6)
    # polled at another rate, or in another order: the same values
    assert np.array_equal(src.counts_at(t[::7]), c[::7])
    assert np.array_equal(src.counts_at(t[::-3]), c[::-3])
    assert np.array_equal(GraspLiveSource(seed=3).reference_at(t[::5]), r[::5])
    # the table sensor reads the weight while resting, nothing while lifted
    st = src.truth_at(t)
    fz = np.abs(r[:, 2])
    assert np.median(fz[st.on_table & (np.mod(t, 12) < 0.9)]) == pytest.approx(0.3 * 9.81, rel=0.05)
    assert np.median(fz[~st.on_table]) < 0.1
    # it loops
    assert np.allclose(src.face_wrenches_at([1.5]), src.face_wrenches_at([13.5]))


def test_grasp_live_contacts():
    src = GraspLiveSource(n_fingers=4)
    ct = src.contacts_at(np.array([0.5, 5.0]))
    assert len(ct["names"]) == 4
    assert ct["force"].shape == (2, 4, 3)
    assert not ct["active"][0].any() and ct["active"][1].all()
    # forces in the face frames push into the patch (along −z of a flat patch)
    assert np.all(ct["force"][1, :, 2] < 0)


def test_calibration_live_source():
    src = CalibrationLiveSource("face", 6, seed=1)
    t = np.arange(0, 6.0, 0.002)
    assert src.face is None
    c0 = src.counts_at(t)
    assert np.allclose(src.reference_at(t), 0, atol=0.25)  # noise: σ = 1/32 N on fz
    src.face = 2
    ref = src.reference_at(t)
    assert np.abs(ref[:, :3]).max() > 3
    F = src.face_wrenches_at(t)
    assert np.abs(F[:, 1, :3]).max() <= 15 + 1e-9 and np.abs(F[:, 1, 3:]).max() <= 0.1 + 1e-9
    assert np.allclose(F[:, [0, 2, 3, 4]], 0)
    assert np.abs(F[:, 5]).max() > 1  # the reaction on the connected face
    still = src.is_still(t)
    assert 0.3 < still.mean() < 0.7
    # still samples within one hold are equal loads
    hold = still & (np.floor(t / src.period) == 2)
    assert np.ptp(src.applied_at(t[hold]), axis=0).max() < 1e-12
    assert not np.array_equal(src.counts_at(t), c0)
    assert src.loaded_at(t[:3])[:, 1].all()
    with pytest.raises(ValueError, match="face"):
        src.face = 9


def test_calibration_live_slip_matches_play_operator():
    src = CalibrationLiveSource("frame_hole", 6, seed=2, period=0.5)
    src.face = 3
    t = np.arange(0, 30.0, 0.001)
    _, _, _, W_frame, slip = src._loads(t)
    exact = src.model.frame_slip(W_frame)
    assert np.allclose(slip, exact, atol=1e-9)


def test_calibration_live_frame_flange_refuses_connected_face():
    src = CalibrationLiveSource("frame", 4)
    with pytest.raises(ValueError, match="cannot be loaded"):
        src.face = 4
    assert np.allclose(src.T_core_ati, reference_pose("frame", 4, CubeCore()))


def test_live_matches_model():
    src = CalibrationLiveSource("face", 6, seed=0, model=VirtualCube(seed=4))
    src.face = 1
    t = np.array([0.0, 1.0, 2.0])
    c = src.counts_at(t)
    assert np.abs(c - src.model.offsets_at(t)).max() > 100


def test_live_sources_say_they_are_simulated():
    assert "simulated" in default_live_source().label
    assert "simulated" in CalibrationLiveSource("frame", 1).label


def test_calibration_live_fades_in_after_a_switch():
    src = CalibrationLiveSource("face", 6, seed=5)
    src.set_face(3, t=10.0)
    w = src.applied_at(np.array([10.0, 10.2, 20.0]))
    assert np.allclose(w[0], 0)  # the operator starts from zero
    assert np.abs(w[1]).max() < np.abs(src._keypoints(np.array([6]), 3)).max() + 1e-12
    src2 = CalibrationLiveSource("face", 6, seed=5)
    src2.face = 3
    assert np.allclose(w[2], src2.applied_at(np.array([20.0]))[0])  # after the fade: the same loads
    with pytest.raises(ValueError, match="t:"):
        src.set_face(2, t=float("nan"))

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from pito_core.frames import (
    FACE_NORMALS,
    OPPOSITE_FACE,
    CubeCore,
    check_pose,
    invert_pose,
    pose_from_rotation_translation,
    rotation_from_x,
    transform_points,
    transform_twist,
    transform_wrench,
    wrench_adjoint,
)

rng = np.random.default_rng(20261121)


def random_pose(rng):
    R = Rotation.random(random_state=rng.integers(1 << 31)).as_matrix()
    return pose_from_rotation_translation(R, rng.normal(scale=0.1, size=3))


@pytest.mark.parametrize("trial", range(20))
def test_round_trip(trial):
    T = random_pose(rng)
    w = rng.normal(size=(5, 6))
    back = transform_wrench(transform_wrench(w, T), invert_pose(T))
    np.testing.assert_allclose(back, w, atol=1e-12)


@pytest.mark.parametrize("trial", range(20))
def test_composition(trial):
    T_ab, T_bc = random_pose(rng), random_pose(rng)
    w = rng.normal(size=6)
    np.testing.assert_allclose(
        transform_wrench(transform_wrench(w, T_ab), T_bc), transform_wrench(w, T_ab @ T_bc), atol=1e-12
    )


@pytest.mark.parametrize("trial", range(20))
def test_power_is_frame_independent(trial):
    T = random_pose(rng)
    w, t = rng.normal(size=(4, 6)), rng.normal(size=(4, 6))
    p_a = np.sum(w * t, axis=-1)
    p_b = np.sum(transform_wrench(w, T) * transform_twist(t, T), axis=-1)
    np.testing.assert_allclose(p_b, p_a, atol=1e-12)


def test_point_force_moment_matches_cross_product():
    # a force f at point p_b (frame b) gives moment p × f about each frame's origin
    T = random_pose(rng)
    p_b, f_b = rng.normal(size=3), rng.normal(size=3)
    w_b = np.r_[f_b, np.cross(p_b, f_b)]
    p_a = transform_points(p_b, T)
    f_a = T[:3, :3] @ f_b
    w_a = transform_wrench(w_b, invert_pose(T))
    np.testing.assert_allclose(w_a, np.r_[f_a, np.cross(p_a, f_a)], atol=1e-12)


def test_adjoint_matches_function_and_inverse():
    T = random_pose(rng)
    X = wrench_adjoint(T)
    w = rng.normal(size=6)
    np.testing.assert_allclose(X @ w, transform_wrench(w, T), atol=1e-14)
    np.testing.assert_allclose(wrench_adjoint(invert_pose(T)) @ X, np.eye(6), atol=1e-12)


def test_pure_translation_known_values():
    T = np.eye(4)
    T[:3, 3] = [0.0, 0.0, 0.1]  # frame b 10 cm above a
    w = np.array([1.0, 0, 0, 0, 0, 0])  # 1 N along x through a's origin
    np.testing.assert_allclose(transform_wrench(w, T), [1, 0, 0, 0, -0.1, 0], atol=1e-15)


@pytest.mark.parametrize("edge", [0.01, 0.05, 0.2])
def test_face_poses(edge):
    core = CubeCore(edge)
    for i in range(1, 7):
        T = core.face_pose(i)
        check_pose(T, "T")
        np.testing.assert_allclose(T[:3, 2], FACE_NORMALS[i])
        np.testing.assert_allclose(T[:3, 3], np.array(FACE_NORMALS[i]) * edge / 2)
        np.testing.assert_allclose(T[:3, 2], -core.face_pose(OPPOSITE_FACE[i])[:3, 2])
    np.testing.assert_allclose(core.face_poses()[4], core.face_pose(5))


def test_face_pose_returns_copy():
    core = CubeCore()
    core.face_pose(1)[0, 3] = 99.0
    assert core.face_pose(1)[0, 3] == core.edge / 2


def test_validators():
    with pytest.raises(ValueError, match=r"edge: expected a positive length"):
        CubeCore(-1)
    with pytest.raises(ValueError, match=r"i: expected a face number 1..6, got 7"):
        CubeCore().face_pose(7)
    with pytest.raises(ValueError, match=r"wrench: expected shape \(..., 6\)"):
        transform_wrench(np.zeros(5), np.eye(4))
    with pytest.raises(ValueError, match=r"T_a_b: expected a 4x4 pose"):
        transform_wrench(np.zeros(6), np.eye(3))
    bad = np.eye(4)
    bad[0, 0] = 2.0
    with pytest.raises(ValueError, match=r"T_a_b: expected a proper rotation"):
        transform_wrench(np.zeros(6), bad)
    mirror = np.diag([1.0, 1.0, -1.0, 1.0])
    with pytest.raises(ValueError, match=r"proper rotation"):
        check_pose(mirror, "T")


def test_check_pose_accepts_what_the_rotation_tolerance_accepts():
    """check_pose's written-out tests take the same poses as np.allclose(·, atol=ROTATION_TOL) and det R > 0,
    on proper and improper rotations perturbed around the tolerance."""
    from pito_core.frames._checks import ROTATION_TOL

    rng = np.random.default_rng(3)
    verdicts = []
    for i in range(3000):
        T = np.eye(4)
        T[:3, :3] = np.linalg.qr(rng.normal(size=(3, 3)))[0]
        T[:3, 3] = rng.normal(size=3)
        T += rng.normal(size=(4, 4)) * 10 ** rng.uniform(-8, -5)
        R = T[:3, :3]
        expected = (np.allclose(T[3], [0, 0, 0, 1], atol=ROTATION_TOL)
                    and np.allclose(R.T @ R, np.eye(3), atol=ROTATION_TOL) and np.linalg.det(R) >= 0)
        try:
            check_pose(T, "T")
            got = True
        except ValueError:
            got = False
        assert got == expected, (i, T)
        verdicts.append(got)
    assert 0.2 < np.mean(verdicts) < 0.8  # both verdicts, many times each


def test_rotation_from_x_is_proper_for_any_direction():
    """The glyphs' per-frame rotation (scalar arithmetic) is orthonormal, right-handed, and takes +x onto the direction."""
    rng = np.random.default_rng(7)
    dirs = [rng.normal(size=3) * s for s in rng.uniform(1e-3, 50, 300)]
    dirs += [np.array(d, float) for d in ((0, 0, 1), (0, 0, -2), (1, 0, 0), (0, 1e-9, 5), (0.1, 0, 0.95))]
    for d in dirs:
        R = rotation_from_x(d)
        assert np.allclose(R.T @ R, np.eye(3), atol=1e-12) and np.isclose(np.linalg.det(R), 1.0)
        assert np.allclose(R[:, 0], d / np.linalg.norm(d))

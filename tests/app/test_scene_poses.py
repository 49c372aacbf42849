"""The scene's pose maths (app.scene._poses, numpy only): glyph poses and camera placement."""

import numpy as np

from app.scene import disc_matrix, ellipsoid_matrix
from app.scene._poses import VIEW_ANGLE, default_camera, framing_distance, mount_camera
from pito_core.frames import FACE_NORMALS, FACES

rng = np.random.default_rng(22)


def test_disc_faces_its_normal_and_has_its_radius():
    for _ in range(50):
        n = rng.normal(size=3)
        c = rng.normal(size=3)
        r = rng.uniform(0.001, 0.1)
        M = disc_matrix(c, n, r)
        assert np.allclose(M[:3, 2] / r, n / np.linalg.norm(n))  # the disc's +z is the normal
        assert np.allclose(np.linalg.norm(M[:3, :3], axis=0), r)  # a round disc of radius r
        assert np.allclose(M[:3, 3], c)


def test_ellipsoid_axes_are_n_sigma_of_the_covariance():
    for _ in range(50):
        A = rng.normal(size=(3, 3)) * 1e-3
        cov = A @ A.T
        M = ellipsoid_matrix(np.zeros(3), cov, n_sigma=2.0)
        # the unit sphere mapped by M is {x : x^T (4 cov)^-1 x = 1}: M M^T = (2σ)² cov
        assert np.allclose(M[:3, :3] @ M[:3, :3].T, 4.0 * cov, atol=1e-12)


def test_mount_camera_puts_the_flange_face_down_and_the_active_face_in_view():
    edge = 0.05
    for connected in FACES:
        for active in FACES:
            position, focal, up = (np.array(v, float) for v in mount_camera(edge, connected, active))
            assert np.allclose(up, -np.array(FACE_NORMALS[connected]))  # the flange's face is at the bottom
            view = position - focal
            assert np.dot(view, up) > 0  # seen from above
            if active != connected:
                assert np.dot(view, FACE_NORMALS[active]) > 0  # the face to load is turned towards the viewer


def test_default_camera_distance_and_framing():
    edge = 0.04
    position, focal, _ = (np.array(v, float) for v in default_camera(edge, 5.0))
    assert np.isclose(np.linalg.norm(position - focal), 5.0 * edge * 1.35)
    # a sphere of radius r at the framing distance fills the narrower half-angle exactly
    r = 0.07
    d = framing_distance(r, 800, 800)
    assert np.isclose(np.degrees(np.arcsin(r / d)), VIEW_ANGLE / 2)
    assert framing_distance(r, 400, 800) > d  # a narrow view: farther away
    assert framing_distance(r, 1600, 800) == d  # wider than tall: the vertical angle counts

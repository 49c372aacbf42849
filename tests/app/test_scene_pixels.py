"""Screenshot checks of the 3D view, read from its pixels: a contact on a face turned away is
hidden by the object (not drawn through it), a visible one shows; uncertainty ellipsoids stay
inside the view and are drawn only where they say something (issue 21, defects 4 and 5)."""

import numpy as np
import pytest

from pito_core.contact import ContactEstimate
from pito_core.frames import FACE_NORMALS, CubeCore

pytestmark = pytest.mark.needs_display


def contact_on(face: int, force_n: float = 0.5, cov=None, core=CubeCore()):
    """One contact at the centre of ``face``, pushing inwards with ``force_n`` N (others invalid)."""
    pts = np.full((6, 3), np.nan)
    nrm = np.zeros((6, 3))
    frc = np.zeros((6, 3))
    valid = np.zeros(6, bool)
    n = np.array(FACE_NORMALS[face])
    pts[face - 1] = n * core.edge / 2
    nrm[face - 1] = n
    frc[face - 1] = -force_n * n
    valid[face - 1] = True
    covs = None if cov is None else np.tile(np.asarray(cov, float), (6, 1, 1))
    return ContactEstimate(pts, nrm, frc, np.zeros(6), valid, point_cov=covs, frame="core")


def pixels(scene) -> np.ndarray:
    from app.scene import grab_scene

    img = grab_scene(scene).convertToFormat(grab_scene(scene).format().Format_RGB888)
    w, h = img.width(), img.height()
    return np.frombuffer(img.constBits(), np.uint8)[: h * img.bytesPerLine()].reshape(h, img.bytesPerLine())[:, : 3 * w].reshape(h, w, 3).astype(int)


def changed(a, b) -> np.ndarray:
    return np.abs(a - b).sum(axis=2) > 30


@pytest.fixture
def scene(scene):
    for lab in scene.face_labels.values():  # the labels are not what is checked here
        lab.SetVisibility(False)
    return scene


def test_default_camera_sees_faces_1_4_5(scene):
    cam = np.array(scene.plotter.camera.position) - np.array(scene.plotter.camera.focal_point)
    facing = {f for f, n in FACE_NORMALS.items() if np.dot(n, cam) > 0}
    assert facing == {1, 4, 5}


@pytest.mark.parametrize("face", [2, 3, 6])
def test_a_contact_on_a_hidden_face_is_occluded(scene, face):
    g = scene.glyphs
    g.hide()
    empty = pixels(scene)
    g.update(contact_on(face))
    assert g.spheres[face].GetVisibility()  # drawn — and hidden by the object
    diff = changed(pixels(scene), empty)
    assert diff.sum() == 0, f"face {face}'s contact shows through the object on {diff.sum()} px"


@pytest.mark.parametrize("face", [1, 4, 5])
def test_a_contact_on_a_visible_face_shows(scene, face):
    g = scene.glyphs
    g.hide()
    empty = pixels(scene)
    g.update(contact_on(face))
    diff = changed(pixels(scene), empty)
    assert diff.sum() > 40, f"face {face}'s contact sphere is not seen ({diff.sum()} px)"
    white = (pixels(scene) > 200).all(axis=2) & diff
    assert white.sum() > 10  # the sphere itself (white), not only its arrow


def test_contact_colour_hook(scene):
    from app.palette import hex_rgb

    g = scene.glyphs
    g.set_contact_color(1, "#ff0000")
    g.update(contact_on(1))
    assert np.allclose(g.spheres[1].prop.color.float_rgb, hex_rgb("#ff0000"), atol=1e-3)
    g.set_contact_color(1, None)
    g.update(contact_on(1))
    assert np.allclose(g.spheres[1].prop.color.float_rgb, (1.0, 1.0, 1.0), atol=1e-3)


@pytest.mark.parametrize("sigma_mm, state", [(1.0, "inside sphere"), (4.0, "drawn"), (30.0, "too wide"), (300.0, "too wide")])
def test_ellipsoids_are_drawn_only_where_meaningful_and_stay_in_view(scene, sigma_mm, state):
    g = scene.glyphs
    g.show_uncertainty = False
    g.update(contact_on(1, 2.0))
    without = pixels(scene)
    g.show_uncertainty = True
    cov = np.diag([1.0, 1.0, 0.3]) * (sigma_mm * 1e-3) ** 2
    g.update(contact_on(1, 2.0, cov))
    assert g.ellipsoid_state[1] == state
    assert g.ellipsoids[1].GetVisibility() == (state == "drawn")
    diff = changed(pixels(scene), without)
    if state != "drawn":
        assert diff.sum() == 0
        return
    ys, xs = np.nonzero(diff)
    h, w = diff.shape
    assert ys.size > 20  # seen
    assert xs.min() > 0.1 * w and xs.max() < 0.9 * w and ys.min() > 0.1 * h and ys.max() < 0.9 * h  # well inside the view
    assert ys.size < 0.1 * h * w


def test_ellipsoid_axes_are_two_sigma():
    from app.scene import ContactGlyphs

    rng = np.random.default_rng(2)
    A = rng.normal(size=(3, 3))
    cov = A @ A.T * 1e-6
    axes = ContactGlyphs.ellipsoid_axes(None, cov)
    np.testing.assert_allclose(axes, 2 * np.sqrt(np.linalg.eigvalsh(cov)))


def test_face_numbers_stand_clear_of_the_patches(scene):
    """A face's number is placed past its patch (not inside a dome, under its contact sphere), and off the
    face's normal (issue 45, point 10: an arrow pushing along the normal covered it)."""
    from app.scene._scene import LABEL_SIDE

    from app.objects import display_meshes, load_assembly

    scene.set_patches(display_meshes(load_assembly("pito_mixed")))
    for i, lab in scene.face_labels.items():
        c = np.array(scene.core.face_pose(i)[:3, 3])
        n = c / np.linalg.norm(c)
        pts = np.asarray(scene._patches[i].mapper.dataset.points) if i in scene._patches else np.zeros((1, 3))
        outer = max(0.5 * scene.core.edge, float((pts @ n).max()))
        pos = np.array(lab.GetPosition())
        assert pos @ n >= outer + scene.glyphs.radius * 2
        off = np.linalg.norm(pos - (pos @ n) * n)
        assert off == pytest.approx(LABEL_SIDE * scene.core.edge)
        assert off > 4 * scene.glyphs.radius  # clear of an arrow (and its sphere) along the normal


def test_culled_back_faces_change_no_pixel(scene):
    """The library's patches are closed and face out: their back faces are culled, and the view is the same."""
    from app.objects import display_meshes, load_assembly

    scene.set_patches(display_meshes(load_assembly("pito_mixed")))
    assert all(a.GetProperty().GetBackfaceCulling() for a in scene._patches.values())
    culled = pixels(scene)
    for a in scene._patches.values():
        a.GetProperty().SetBackfaceCulling(False)
    assert changed(culled, pixels(scene)).sum() == 0


def test_open_inward_or_translucent_patches_keep_their_back_faces(scene):
    import pyvista as pv

    e = scene.core.edge
    ball = pv.Sphere(radius=0.2 * e, center=(0.55 * e, 0, 0))
    scene.set_patches({1: ball, 2: ball.flip_faces(), 3: pv.Disc(center=(-0.55 * e, 0, 0), outer=0.2 * e, normal=(-1, 0, 0))})
    assert [scene._patches[i].GetProperty().GetBackfaceCulling() for i in (1, 2, 3)] == [1, 0, 0]
    scene.set_patches({1: ball}, opacity=0.5)
    assert not scene._patches[1].GetProperty().GetBackfaceCulling()


# --- the kept object frame (app/scene/_backdrop.py): a frame that restores it looks as a full draw


def frame(scene) -> np.ndarray:
    """Render a frame as the live view does and read it (no grab filter: it renders with copies of the cameras)."""
    from vtkmodules.util.numpy_support import vtk_to_numpy
    from vtkmodules.vtkCommonCore import vtkUnsignedCharArray

    rw = scene.plotter.ren_win
    rw.Render()
    w, h = rw.GetSize()
    arr = vtkUnsignedCharArray()
    rw.GetPixelData(0, 0, w - 1, h - 1, 0, arr, 0)
    return vtk_to_numpy(arr).reshape(h, w, 3)[::-1].astype(int)


def full_frame(scene) -> np.ndarray:
    """A frame that draws the object (nothing kept, nothing restored)."""
    scene.backdrop.enabled = False
    try:
        return frame(scene)
    finally:
        scene.backdrop.enabled = True


def test_moving_glyphs_restore_the_object_and_look_as_a_full_draw(scene):
    g, bd = scene.glyphs, scene.backdrop
    g.update(contact_on(1))
    frame(scene)  # draws the object and keeps it
    for k, face in enumerate((4, 5, 1, 2)):  # (face 2's contact: hidden by the object)
        g.update(contact_on(face, 1.0 + k))
        restored = bd.restored
        img = frame(scene)
        assert bd.restored == restored + 1  # the object restored, not drawn
        assert np.array_equal(img, full_frame(scene))  # pixel for pixel
        frame(scene)  # (the full draw kept nothing: keep again)


@pytest.mark.parametrize("change", ["rotate", "zoom", "face colour", "mount", "resize"])
def test_a_new_view_or_object_draws_the_object_again(scene, qtbot, change):
    g, bd = scene.glyphs, scene.backdrop
    g.update(contact_on(1, 2.0))
    frame(scene)
    before = frame(scene)
    assert bd.restored > 0
    drawn = bd.drawn
    iren = scene.plotter.iren.interactor
    if change == "rotate":  # a left-button drag through the interactor, as the mouse does it
        iren.SetEventInformation(320, 240, 0, 0)
        iren.InvokeEvent("LeftButtonPressEvent")
        for x in range(330, 400, 10):
            iren.SetEventInformation(x, 240 - (x - 320) // 3, 0, 0)
            iren.InvokeEvent("MouseMoveEvent")
        iren.InvokeEvent("LeftButtonReleaseEvent")
    elif change == "zoom":
        iren.SetEventInformation(320, 240, 0, 0)
        iren.InvokeEvent("MouseWheelForwardEvent")
    elif change == "face colour":
        scene.set_face_colors({1: "#ff0000", 5: "#00ff00"})
    elif change == "mount":
        scene.set_mount("face", 6)
    else:
        scene.resize(560, 420)
        qtbot.wait(50)
    g.update(contact_on(1, 2.5))
    img = frame(scene)
    assert bd.drawn > drawn  # drawn again (by this frame, or by the interactor's own frames)
    assert img.shape != before.shape or changed(img, before).sum() > 100  # (the change shows)
    assert np.array_equal(img, full_frame(scene))
    frame(scene)
    g.update(contact_on(1, 3.0))
    restored = bd.restored
    img = frame(scene)
    assert bd.restored == restored + 1  # kept again
    assert np.array_equal(img, full_frame(scene))


def test_a_translucent_object_draws_the_glyphs_with_it(scene):
    """The mount page's see-through flange: glyphs behind it blend under it, as in one renderer."""
    g, bd = scene.glyphs, scene.backdrop
    scene.set_mount("face", 6, flange_opacity=0.45)
    g.update(contact_on(1))
    frame(scene)
    assert bd.renderer.GetViewProps().IsItemPresent(g.spheres[1])  # back in the object's renderer
    restored = bd.restored
    frame(scene)
    assert bd.restored == restored
    scene.set_mount("face", 6)
    frame(scene)
    assert bd.glyph_renderer.GetViewProps().IsItemPresent(g.spheres[1])


def test_a_firm_touch_ellipsoid_shows_magnified_and_the_note_says_why(scene):
    """Issue 45, point 5: a firm touch's 2σ (0.3 mm) hides inside the 3.5 mm contact sphere at ×1
    — the note says so; at ×10 (the live view's) it is drawn, and seen on screen."""
    g = scene.glyphs
    g.show_uncertainty = False
    g.update(contact_on(1, 8.0))
    without = pixels(scene)
    assert g.ellipsoid_note() == ""
    g.show_uncertainty = True
    cov = np.diag([1.0, 1.0, 0.3]) * 0.3e-3 ** 2 / 4  # σ 0.15 mm: 2σ 0.3 mm
    g.ellipsoid_scale = 1.0
    g.update(contact_on(1, 8.0, cov))
    assert g.ellipsoid_state[1] == "inside sphere" and (changed(pixels(scene), without).sum() == 0)
    assert "0.30–0.30 mm: 1 inside the 3.5 mm spheres at ×1" in g.ellipsoid_note(), g.ellipsoid_note()
    g.ellipsoid_scale = 20.0
    g.update(contact_on(1, 8.0, cov))
    assert g.ellipsoid_state[1] == "drawn" and "1 drawn ×20" in g.ellipsoid_note()
    assert changed(pixels(scene), without).sum() > 20
    g.update(contact_on(1, 8.0))  # no covariance at all: said so
    assert "no covariance" in g.ellipsoid_note()

"""Issue 45, point 10: the wizard's loading step keeps the probe's full-scale arrow on face 5 (the top) in view."""

import numpy as np
import pytest

pytestmark = pytest.mark.needs_display


def test_a_full_scale_push_on_face_5_stays_inside_the_view(qtbot, styled):
    from app.palette import FACE_COLORS, hex_rgb
    from app.scene import grab_scene
    from app.wizard.load_page import LoadPage
    from app.wizard.model import WizardModel
    from pito_core.contact import ContactEstimate

    model = WizardModel()
    model.set_mount(method="loaded_frame", flange="frame_hole", connected_face=6)
    page = LoadPage(model)
    qtbot.addWidget(page)
    page.resize(1100, 700)
    page.show()
    qtbot.waitExposed(page)
    try:
        g = page.scene.glyphs
        pts, nrm, frc = np.full((6, 3), np.nan), np.zeros((6, 3)), np.zeros((6, 3))
        pts[4], nrm[4], frc[4] = [0, 0, 0.025], [0, 0, 1], [0, 0, -g.full_scale]  # straight down on the top
        valid = np.zeros(6, bool)
        valid[4] = True
        page.scene.show_contacts(ContactEstimate(pts, nrm, frc, np.zeros(6), valid, frame="core"))
        page.scene.redraw()
        qtbot.wait(300)
        img = grab_scene(page.scene).convertToFormat(grab_scene(page.scene).format().Format_RGB888)
        w, h = img.width(), img.height()
        px = np.frombuffer(img.constBits(), np.uint8)[: h * img.bytesPerLine()].reshape(h, img.bytesPerLine())
        px = px[:, : 3 * w].reshape(h, w, 3).astype(int)
        arrow = np.abs(px - np.array(hex_rgb(FACE_COLORS[5])) * 255).sum(axis=2) < 120
        ys, _ = np.nonzero(arrow)
        assert ys.size > 50  # the arrow (and face 5's patch colour) is seen
        assert ys.min() > 2, "the arrow leaves the view at its top"
    finally:
        page.scene.close_scene()

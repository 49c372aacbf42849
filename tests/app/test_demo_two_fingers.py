"""Issue 45, point 4: the demo's two fingers on one patch — the contact is flagged red-pink on screen
and the live view says why (demo devices, SIMULATED)."""

import numpy as np
import pytest

pytestmark = [pytest.mark.needs_display, pytest.mark.slow]


def test_two_fingers_on_one_patch_are_flagged_and_explained(qtbot, styled):
    from app.palette import FLAGGED_CONTACT_COLOR, hex_rgb
    from app.scene import grab_scene
    from app.screenshot import process_for, wait_until
    from app.window import MainWindow

    window = MainWindow(demo=True, demo_k=600)
    qtbot.addWidget(window)
    window.resize(1280, 800)
    window.show()
    qtbot.waitExposed(window)
    live = window.live
    try:
        assert wait_until(lambda: window.calibration is not None and live.bundles_shown > 5, timeout=60)
        live.scenario.setCurrentIndex(live.scenario.findData("two_fingers"))
        assert window.rig.sim.state()["scenario"] == "two_fingers"
        assert wait_until(lambda: live.scene.glyphs.flagged[0], timeout=20)
        g = live.scene.glyphs
        assert not g.flagged[2] and not g.flagged[5]  # the thumb and the table: one contact each
        assert wait_until(lambda: "face 1: the twist exceeds" in live.flag_note.text(), timeout=10), live.flag_note.text()
        assert "two fingers on one patch" in live.flag_note.text()
        process_for(0.5)
        img = grab_scene(live.scene).convertToFormat(grab_scene(live.scene).format().Format_RGB888)
        w, h = img.width(), img.height()
        px = np.frombuffer(img.constBits(), np.uint8)[: h * img.bytesPerLine()].reshape(h, img.bytesPerLine())
        px = px[:, : 3 * w].reshape(h, w, 3).astype(int)
        pink = np.array(hex_rgb(FLAGGED_CONTACT_COLOR)) * 255
        near = np.abs(px - pink).sum(axis=2) < 90  # the lit sphere's shades of red-pink
        assert near.sum() > 15, near.sum()  # the flagged sphere, seen
        live.scenario.setCurrentIndex(live.scenario.findData("grasp"))
        assert wait_until(lambda: live.flag_note.text() == "" or not g.flagged[0], timeout=20)
        assert window.errors == []
    finally:
        window.shutdown()
        window.release_views()

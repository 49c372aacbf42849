"""Issue 21, point 3: the live view's Tare only when it is right (the wizard's checks), with its
reason when refused, undoable, shown, and kept through a replay and Back to live (demo devices,
SIMULATED). Issue 45, point 1: at rest on the table with the object's mass, the load named when refused."""

import re

import numpy as np
import pytest

pytestmark = [pytest.mark.needs_display, pytest.mark.slow]


def test_live_tare_refuses_under_load_undoes_and_survives_a_replay(qtbot, styled, tmp_path):
    from app.screenshot import process_for, wait_until
    from app.window import MainWindow

    window = MainWindow(demo=True, demo_k=600)
    qtbot.addWidget(window)
    window.resize(1280, 800)
    window.show()
    qtbot.waitExposed(window)
    live, feed = window.live, window.feed
    path = tmp_path / "short.pitorec"
    try:
        assert wait_until(lambda: window.calibration is not None and live.bundles_shown > 5, timeout=60)
        process_for(0.5)
        # the demo's object at rest on the table, hands off; its mass unknown: refused, the load named
        live.scenario.setCurrentIndex(live.scenario.findData("rest"))
        live.mass.setValue(0.0)
        process_for(1.0)
        live.tare.click()
        assert wait_until(lambda: live.tare_label.text().startswith("✘ Tare refused"), timeout=10)
        text = live.tare_label.text()
        assert "face 6 carries 2.9" in text and "mass" in text, text
        assert feed.source.tare_in_force is None and not live.undo_tare.isEnabled()
        # with the object's mass: taken at rest, face 6 then reads the weight (‖ΣF‖ = m·g)
        live.mass.setValue(0.3)
        live.tare.click()
        assert wait_until(lambda: live.tare_label.text().startswith("Tare: taken"), timeout=10), live.tare_label.text()
        assert "at rest on face 6" in live.tare_label.text() and live.undo_tare.isEnabled()
        assert feed.source.tare_in_force["known_load"][5][2] == pytest.approx(-0.3 * 9.81)
        process_for(1.0)
        assert abs(live._sums[0] - 0.3 * 9.81) < 0.03, live._sums
        live.undo_tare.click()
        assert wait_until(lambda: live.tare_label.text() == "Tare: the calibration's own zero", timeout=10)
        # held by fingers (the two-finger demo: loads that never rest): refused, the finger's load named
        live.scenario.setCurrentIndex(live.scenario.findData("two_fingers"))
        process_for(1.0)
        live.tare.click()
        assert wait_until(lambda: live.tare_label.text().startswith("✘ Tare refused"), timeout=10)
        assert re.search(r"face \d carries \d+\.\d+ N", live.tare_label.text()), live.tare_label.text()
        # nothing touches the cube (it hangs on its flange, the operator's hands off): accepted
        window.rig.set_scenario("calibration")
        window.rig.set_operator_face(None)
        process_for(1.5)
        live.tare.click()
        assert wait_until(lambda: live.tare_label.text().startswith("Tare: taken"), timeout=10), live.tare_label.text()
        assert live.undo_tare.isEnabled()
        first = np.asarray(feed.source.tare_in_force["counts_offset"])
        # undo: back to the calibration's own zero
        live.undo_tare.click()
        assert wait_until(lambda: live.tare_label.text() == "Tare: the calibration's own zero", timeout=10)
        assert feed.source.tare_in_force is None and not live.undo_tare.isEnabled()
        live.tare.click()
        assert wait_until(lambda: live.tare_label.text().startswith("Tare: taken"), timeout=10)
        kept = np.asarray(feed.source.tare_in_force["counts_offset"])
        assert np.abs(kept - first).max() < 1e4  # the same unloaded state (counts)
        # record a little, replay it, and come back: the live tare is in force again, and shown
        window.toggle_recording(True, path)
        process_for(1.0)
        with qtbot.waitSignal(window.recording_saved, timeout=15_000):
            window.toggle_recording(False)
        from pito_core.io import Recording

        assert Recording(path).meta["mass_kg"] == pytest.approx(0.3)  # the analysis's force residual needs it
        window.open_replay(str(path))
        assert wait_until(lambda: live.timeline.isEnabled(), timeout=20)
        assert wait_until(lambda: "replay" in live.tare_label.text(), timeout=10)
        live.tare.click()  # no tare of a replay
        assert wait_until(lambda: "not during a replay" in live.tare_label.text(), timeout=10)
        window.back_to_live()
        assert wait_until(lambda: live.tare_label.text().startswith("Tare: taken"), timeout=20), live.tare_label.text()
        process_for(0.5)
        assert np.allclose(feed.source.tare_in_force["counts_offset"], kept)
        assert window.errors == []
    finally:
        window.shutdown()
        window.release_views()

"""Issue 21, point 3: the live view's Tare only when it is right (the wizard's checks), with its
reason when refused, undoable, shown, and kept through a replay and Back to live (demo devices,
SIMULATED)."""

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
        # the object rests on the table or is held: a load on a face — refused, with the reason
        live.tare.click()
        assert wait_until(lambda: live.tare_label.text().startswith("✘ Tare refused"), timeout=10)
        assert " N" in live.tare_label.text()  # the reason, with its figure: a load on a face, or motion
        assert feed.source.tare_in_force is None and not live.undo_tare.isEnabled()
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

"""Record both devices from the live view, then replay the file with the timeline (demo devices)."""

import numpy as np
import pytest

pytestmark = [pytest.mark.needs_display, pytest.mark.slow]


def test_record_then_replay(qtbot, styled, tmp_path):
    from app.screenshot import process_for, wait_until
    from app.window import MainWindow
    from pito_core.io import read_recording

    window = MainWindow(demo=True, demo_k=600)
    qtbot.addWidget(window)
    window.resize(1280, 800)
    window.show()
    qtbot.waitExposed(window)
    path = tmp_path / "grasp.pitorec"
    try:
        live = window.live
        assert wait_until(lambda: live.bundles_shown > 5, timeout=30)
        window.toggle_recording(True, path)
        live.record.blockSignals(True)
        live.record.setChecked(True)
        live.record.blockSignals(False)
        process_for(2.0)
        # stopping is asynchronous (the worker closes the file): the window says when it is complete
        with qtbot.waitSignal(window.recording_saved, timeout=15_000) as saved:
            window.toggle_recording(False)
            live.record.setChecked(False)
        assert saved.args[0] == str(path) and saved.args[1] > 1000
        assert path.exists() and path.stat().st_size > 10000
        rec = read_recording(path)
        assert rec.complete and rec.simulated
        assert rec.pito.size > 1000 and rec.netft.size > 500  # ~2 s at 1 kHz, both devices
        assert np.all(np.diff(rec.pito["seq"].astype(np.int64)) == 1)  # no sample lost
        # replay: bundles come from the file, the timeline follows and can seek
        window.open_replay(str(path))  # the file is read in the background
        assert wait_until(lambda: live.timeline.isEnabled(), timeout=20) and live.back_live.isVisible()
        shown = live.bundles_shown
        assert wait_until(lambda: live.bundles_shown > shown + 10 and live.time_label.text().startswith("replay"),
                          timeout=20)
        window.seek(1.0)
        process_for(0.3)
        window.back_to_live()
        assert not live.timeline.isEnabled()
        assert window.errors == []
    finally:
        window.shutdown()
        window.release_views()

"""App: File → Export (background task with a progress bar) and the live view's LSL toggle wiring.

No LSL traffic here: the toggle is driven with a recording sink in place of the publisher
(the real outlets are tested in test_lsl.py inside a private network namespace).
"""


import numpy as np
import pytest

pytest.importorskip("PySide6")
pytest.importorskip("pynwb", reason="the interop extra is not installed")

pytestmark = pytest.mark.gui


def test_export_dialog_writes_every_format_in_the_background(qtbot, interop_files, tmp_path):
    import pynwb

    from app.export_dialog import ExportDialog

    _, _, rec, _ = interop_files
    dlg = ExportDialog(recording=str(rec))
    qtbot.addWidget(dlg)
    for c in dlg.checks.values():
        c.setChecked(True)
    dlg.prefix.setText(str(tmp_path / "out"))
    dlg.subject.setText("S07")
    seen = []
    task = dlg.start()
    assert task is not None
    task.progressed.connect(lambda f, t: seen.append(f))
    qtbot.waitUntil(lambda: bool(dlg.written) or "failed" in dlg.status.text(), timeout=120000)
    assert "failed" not in dlg.status.text(), dlg.status.text()
    names = sorted(p.split("/")[-1] for p in dlg.written)
    assert names == ["out.mat", "out.mcap", "out.nwb", "out_ati.csv", "out_pito.csv"]
    with pynwb.NWBHDF5IO(str(tmp_path / "out.nwb"), "r") as io:
        f = io.read()
        assert f.subject.subject_id == "S07" and "behavior" in f.processing
    # the CSV files as `pito export` writes them: every sample, on the device clock's time base
    from pito_core.io import read_recording, read_recording_csv
    from pito_core.pipeline import recording_times

    recording = read_recording(rec)
    for name, stream, t in zip(("out_pito.csv", "out_ati.csv"), ("pito", "netft"), recording_times(recording)):
        cols = read_recording_csv(tmp_path / name, stream)
        assert "time" in cols and np.allclose(cols["time"], t, rtol=0, atol=1e-9), name
    assert dlg.export_button.isEnabled()
    assert seen and all(0 <= f <= 1 for f in seen) and seen == sorted(seen)  # the bar only moves forward


def test_export_dialog_names_the_bad_field(qtbot, tmp_path):
    from app.export_dialog import ExportDialog

    dlg = ExportDialog(recording=str(tmp_path / "missing.pitorec"))
    qtbot.addWidget(dlg)
    assert dlg.start() is None and dlg.status.text().startswith("Recording:")


def test_lsl_toggle_publishes_every_bundle_while_on(qtbot):
    from PySide6.QtWidgets import QHBoxLayout, QPushButton, QWidget

    from app.live.lsl_toggle import LslToggle, install_lsl_toggle
    from app.live import LiveFeed

    feed = LiveFeed()
    got = []

    class Sink:
        names = ("pito-wrenches", "pito-contacts")

        def __init__(self, source):
            assert source is feed  # the feed's calibration and object describe the streams

        def __call__(self, bundle):
            got.append(bundle)

        def close(self):
            got.append("closed")

    view = QWidget()
    bar = QHBoxLayout(view)
    view.replay = QPushButton("Replay…")
    bar.addWidget(view.replay)
    qtbot.addWidget(view)
    toggle = install_lsl_toggle(view, feed)
    assert bar.indexOf(toggle) == 1 and view.lsl is toggle
    toggle.factory = Sink
    feed.bundle.emit("before")
    toggle.button.setChecked(True)
    assert "pito-wrenches" in toggle.label.text() and "pito-contacts" in toggle.label.text()
    feed.bundle.emit("b1")
    feed.bundle.emit("b2")
    toggle.button.setChecked(False)
    feed.bundle.emit("after")
    assert got == ["b1", "b2", "closed"] and toggle.label.text() == ""

    def refuse(source):
        raise ValueError("calibration: the LSL streams carry wrenches")

    t2 = LslToggle(feed, publisher_factory=refuse)
    qtbot.addWidget(t2)
    t2.button.setChecked(True)
    assert not t2.button.isChecked() and "calibration" in t2.label.text()
    feed.stop()

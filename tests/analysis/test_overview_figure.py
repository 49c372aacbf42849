"""Issue 44 point 2: one overview figure per recording by default; per-trial figures on request."""

import numpy as np
import pytest

from pito_core.analysis import analyze_recording, overview_figure, write_analysis
from pito_core.analysis._figures import _envelope


def test_the_overview_is_the_default_figure_and_trials_are_on_request(lift_recording, tmp_path):
    path, task, _ = lift_recording
    a = analyze_recording(path)
    (tmp_path / "o").mkdir()
    names = {p.name for p in write_analysis(a, tmp_path / "o", figures="overview") if p.suffix == ".png"}
    assert names == {"overview.png"}
    (tmp_path / "t").mkdir()
    names = {p.name for p in write_analysis(a, tmp_path / "t", figures="trials") if p.suffix == ".png"}
    assert names == {"overview.png"} | {f"trial_{k:02d}.png" for k in range(1, task.n_trials + 1)}
    with pytest.raises(ValueError, match="figures: expected one of none, overview, trials"):
        write_analysis(a, tmp_path, figures="all")
    fig = overview_figure(a)
    assert f"SIMULATED — {task.n_trials} trials" in fig._suptitle.get_text()
    overlaid = fig.axes[1].collections[0]
    assert len(overlaid.get_paths()) == 2 * task.n_trials  # grip and load of every trial


def test_the_envelope_keeps_every_peak_of_a_pixel_column():
    t = np.arange(100_000) * 1e-3
    y = np.zeros(t.size)
    y[[777, 54_321]] = (5.0, -3.0)
    tt, yy = _envelope(t, y, 700)
    assert tt.size == yy.size == 1400 and np.all(np.diff(tt) >= 0)
    assert yy.max() == 5.0 and yy.min() == -3.0
    assert _envelope(t[:1000], y[:1000], 700)[0].size == 1000

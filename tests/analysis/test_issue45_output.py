"""Issue 45, point 8: the analysis's face colours are the app's, a trial caught mid-release is
labelled "release", and `pito analyze --recover` exists (the error it answers names it)."""

import numpy as np

from pito_core.analysis import AnalysisSettings, analyze_recording, trial_figure, trials_from_contacts
from pito_core.frames import FACE_COLORS


def test_trial_figures_draw_each_face_in_the_apps_colour(lift_recording):
    from matplotlib.colors import to_hex

    path, _, _ = lift_recording
    analysis = analyze_recording(path)
    fig = trial_figure(analysis, analysis.trials[0])
    lines = [ln for ax in fig.axes[1:3] for ln in ax.get_lines() if ln.get_label().startswith("face ")]
    assert lines
    for ln in lines:
        face = int(ln.get_label().split()[1])
        assert to_hex(ln.get_color()).lower() == FACE_COLORS[face].lower(), ln.get_label()


def test_a_trial_caught_mid_release_is_release_not_load():
    t = np.arange(0, 2.0, 0.001)
    on = np.zeros((t.size, 6), bool)
    on[:, 5] = True  # the object rests on its base the whole time
    on[: 800, 0] = on[: 800, 2] = True  # two fingers on at the first sample, letting go at 0.8 s
    on[1200:1900, 0] = on[1200:1900, 2] = True  # a whole trial later: load
    trials = trials_from_contacts(t, on, AnalysisSettings(min_duration=0.2))
    assert [list(tr.phases) for tr in trials] == [["release"], ["load"]]


def test_analyze_has_the_recover_option_its_error_names(capsys):
    from pito_core.cli import main

    try:
        main(["analyze", "--help"])
    except SystemExit:
        pass
    assert "--recover" in capsys.readouterr().out

"""Plot history (issue 21, defect 6): a replay that loops does not draw a line back to its start,
Back to live does not join the old timeline with a jump, Resume after Pause shows what was
measured meanwhile."""

import numpy as np
import pytest

from app.widgets.plots import GAP, TimeRing, break_gaps

pytestmark = pytest.mark.needs_display


def test_time_ring_starts_a_new_timeline_when_time_goes_back():
    r = TimeRing(100, 2)
    r.append(np.column_stack([np.arange(10.0, 15.0), np.ones(5)]))
    r.append([[3.0, 2.0], [4.0, 2.0]])  # a replay looped: earlier times
    np.testing.assert_array_equal(r.view()[:, 0], [3.0, 4.0])
    r.append([[5.0, 1.0], [2.0, 1.0], [2.5, 1.0]])  # back in time inside one append: the last run
    np.testing.assert_array_equal(r.view()[:, 0], [2.0, 2.5])
    assert np.all(np.diff(r.view()[:, 0]) > 0)


def test_time_ring_written_changes_with_every_append_and_clear():
    # a new timeline as long as the old one, less one row: still a change a refresh must draw
    r = TimeRing(8, 2)
    r.append(np.column_stack([np.arange(5.0), np.zeros(5)]))
    seen = {r.written}
    r.append(np.column_stack([np.arange(4.0), np.ones(4)]))  # back in time: clear, then 4 rows
    assert r.written not in seen and len(r) == 4
    seen.add(r.written)
    r.append([[20.0 + k, 2.0] for k in range(12)])  # more than the capacity: the last 8 rows
    assert r.written not in seen and len(r) == 8
    np.testing.assert_array_equal(r.view()[:, 0], np.arange(24.0, 32.0))
    assert r.view().base is not None  # a view, not a copy


def test_refresh_draws_a_restarted_timeline_of_the_same_length(plots):
    f, _ = plots
    f.append(np.arange(0.0, 0.05, 0.01), np.ones((5, 6)))
    assert f.refresh()
    f.append(np.arange(0.0, 0.04, 0.01), np.full((4, 6), 3.0))  # looped: 1 clear + 4 rows
    assert f.refresh()
    _, y = drawn(f.curves[0])
    assert np.allclose(y, 3.0)


def test_gaps_are_breaks_not_lines():
    rng = np.random.default_rng(4)
    t = np.r_[np.sort(rng.uniform(0, 1, 30)), 1.0 + GAP + np.sort(rng.uniform(0.1, 1, 30))]
    y = rng.normal(size=(60, 2))
    t2, y2 = break_gaps(t, y)
    assert t2.size == 61 and np.isnan(y2[30]).all() and np.all(np.diff(t2) >= 0)
    np.testing.assert_array_equal(y2[np.isfinite(y2[:, 0])], y)


@pytest.fixture
def plots(qtbot):
    from app.widgets.plots import EquilibriumPlot, FaceForcePlot

    f, e = FaceForcePlot(), EquilibriumPlot(weight=2.9)
    for w in (f, e):
        qtbot.addWidget(w)
        w.resize(500, 300)
        w.show()
    return f, e


def drawn(curve):
    x, y = curve.getData()
    return np.asarray(x), np.asarray(y)


def test_replay_loop_draws_no_line_to_its_start(plots):
    f, e = plots
    t = np.arange(0, 6, 0.01)
    f.append(t, np.tile(np.sin(t)[:, None] + 2, (1, 6)))
    f.refresh()
    f.append(np.arange(0, 1, 0.01), np.ones((100, 6)))  # the replay starts again at 0 s
    f.refresh()
    x, y = drawn(f.curves[0])
    assert np.all(np.diff(x) >= 0) and x.min() >= -1.0 and np.allclose(y[np.isfinite(y)], 1.0)


def test_back_to_live_is_a_break_not_a_jump(plots):
    f, e = plots
    for k, t in enumerate(np.arange(100.0, 103.0, 0.05)):
        e.append(t, 2.9, 0.004)
    for t in np.arange(105.0, 107.0, 0.05):  # live again 2 s later
        e.append(t, 5.0, 0.008)
    e.refresh()
    x, y = drawn(e.force_curve)
    gap = np.flatnonzero(np.isnan(y))
    assert gap.size == 1 and x[gap[0] - 1] < -4.0 + 1e-9 and x[gap[0] + 1] > -2.0 - 1e-9


def test_resume_after_pause_shows_the_samples_measured_meanwhile(qtbot, styled):
    from app.live import LiveView
    from pito_core.pipeline import LiveBundle as Bundle
    from pito_core.frames import CubeCore

    view = LiveView(CubeCore(), ["cube"])
    qtbot.addWidget(view)
    view.resize(1280, 800)
    view.show()
    qtbot.waitExposed(view)
    try:
        def bundle(t):
            return Bundle(np.array([t]), np.zeros((1, 36)), np.zeros((1, 6)), wrenches=np.ones((6, 6)),
                          contacts=None, sum_force=np.array([0, 0, 2.9]), sum_torque=np.zeros(3))

        for t in np.arange(0.0, 2.0, 0.1):
            view.on_bundle(bundle(t))
        view.pause.setChecked(True)
        for t in np.arange(2.0, 30.0, 0.1):  # 28 s paused: acquisition goes on
            view.on_bundle(bundle(t))
        view.pause.setChecked(False)
        view.display()
        x, y = drawn(view.equilibrium.force_curve)
        # the last 10 s, continuous (not an empty plot with the newest sample only)
        assert np.isfinite(y).sum() >= 95 and x.min() <= -9.8 and not np.isnan(y).any()
    finally:
        view.scene.close_scene()


def test_sample_sums_are_the_pipelines_face_sums_of_each_sample():
    """Issue 45, point 10: ‖ΣF‖, ‖ΣT‖ of every sample, as the pipeline's ``face_sums`` of one."""
    from app.live.view import sample_sums
    from pito_core.frames import CubeCore
    from pito_core.pipeline._bundle import face_sums

    rng = np.random.default_rng(5)
    W = rng.normal(size=(7, 6, 6))
    W[3, 2] = np.nan  # a face without output on one sample: left out
    cog = (0.002, -0.001, -0.003)
    F, T = sample_sums(W, CubeCore(), cog)
    for k in range(7):
        f, m = face_sums(W[k], CubeCore(), cog)
        assert F[k] == pytest.approx(np.linalg.norm(f)) and T[k] == pytest.approx(np.linalg.norm(m))


def test_a_display_stall_breaks_neither_the_face_nor_the_sum_plots(qtbot):
    """Bundles 0.8 s apart (a stall) with every sample in them: both plots continuous, no break."""
    from types import SimpleNamespace

    from app.live import LiveView
    from app.widgets.plots import GAP

    view = LiveView()
    qtbot.addWidget(view)
    try:
        for k in range(3):
            arrived = 0.8 * k + np.arange(800) / 1000.0
            fw = np.zeros((800, 6, 6))
            fw[:, 5, 2] = -2.94  # the object at rest on face 6
            b = SimpleNamespace(replay_position=None, replay_duration=None, arrived_time=arrived, time=arrived,
                                contacts_time=arrived[-1], latest_time=arrived[-1], wrenches=fw[-1],
                                arrived_face_wrenches=fw, sum_force=np.r_[0, 0, 2.94], sum_torque=np.zeros(3),
                                measured=np.ones((6, 6), bool), contacts=None, recorded=0)
            view.on_bundle(b)
        for ring in (view.force_plot.buffer, view.equilibrium.buffer):
            t = ring.ring.last(copy=True)["rows"][:, 0]
            assert t.size == 2400 and np.diff(t).max() < GAP
        assert view.equilibrium.buffer.ring.last(copy=True)["rows"][:, 1] == pytest.approx(2.94)
    finally:
        view.scene.close_scene()

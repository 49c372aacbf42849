"""The live view's update path: actors moved in place, hidden under the threshold; the worker."""

import numpy as np
import pytest

from app.workers import Bundle, DeviceWorker, face_sums, merge_bundles
from pito_core.contact import ContactEstimate
from pito_core.frames import CubeCore
from pito_core.pipeline import NewSamples

pytestmark = pytest.mark.needs_display


def contacts(force_face1=(-8.0, 1.0, 2.0), valid=(True, True, False, False, False, False)):
    pts = np.full((6, 3), np.nan)
    nrm = np.zeros((6, 3))
    frc = np.zeros((6, 3))
    pts[0], nrm[0], frc[0] = (0.027, 0.004, 0.002), (1, 0, 0), force_face1
    pts[1], nrm[1], frc[1] = (0.0, 0.027, 0.0), (0, 1, 0), (0.0, -0.1, 0.0)  # 0.1 N: under threshold
    return ContactEstimate(pts, nrm, frc, np.array([0.02, 0, 0, 0, 0, 0.0]), np.array(valid),
                           point_cov=np.tile(np.eye(3) * 9e-6, (6, 1, 1)), frame="core")


def bundle(t, c):
    W = np.zeros((6, 6))
    W[0, :3] = np.linalg.norm(c.force[0])
    return Bundle(np.array([t]), np.zeros((1, 36)), np.zeros((1, 6)), wrenches=W, contacts=c,
                  sum_force=np.array([0, 0, 2.9]), sum_torque=np.zeros(3))


@pytest.fixture
def live(qtbot, styled):
    from app.live import LiveView

    view = LiveView(CubeCore(), ["cube"])
    qtbot.addWidget(view)
    view.resize(1280, 800)
    view.show()
    qtbot.waitExposed(view)
    yield view
    view.scene.close_scene()


def test_glyphs_move_in_place_and_hide_under_threshold(live):
    g = live.scene.glyphs
    renderer = live.scene.plotter.renderer
    actors_before = dict(renderer.actors)
    ids = {i: id(g.arrows[i]) for i in g.arrows}
    shown = []
    for k in range(20):
        f = (-8.0 + 0.2 * k, 1.0, 2.0)
        live.on_bundle(bundle(0.02 * k, contacts(f)))
        live.display()  # the glyphs move when a frame is drawn (at most display_rate a second), not per bundle
        live.scene.sync()  # ... in the scene's drawing thread, before its next frame
        shown.append(g.shown.copy())
        if k == 0:
            m0 = np.array(g.arrows[1].user_matrix)
    m1 = np.array(g.arrows[1].user_matrix)
    assert dict(renderer.actors).keys() == actors_before.keys()  # nothing added or removed
    assert {i: id(g.arrows[i]) for i in g.arrows} == ids  # the same actor objects
    assert not np.allclose(m0, m1)  # ... moved
    assert all(s.tolist() == [True, False, False, False, False, False] for s in shown)
    assert g.arrows[1].GetVisibility() and g.spheres[1].GetVisibility()
    assert not g.arrows[2].GetVisibility()  # 0.1 N: under the 0.3 N threshold
    assert not g.arrows[3].GetVisibility()  # not valid
    assert np.allclose(g.spheres[1].position, (0.027, 0.004, 0.002))
    # raising the threshold hides face 1 as well, still without adding actors
    live.threshold.setValue(20.0)
    live.scene.sync()
    assert g.threshold == 20.0 and g.shown_count() == 0 and not g.arrows[1].GetVisibility()
    assert dict(renderer.actors).keys() == actors_before.keys()


def test_arrow_ends_at_the_contact_point_and_scales_with_force(live):
    from app.scene import arrow_matrix

    tip = np.array([0.025, 0.0, 0.0])
    for f in ((-5.0, 0, 0), (-10.0, 3.0, 1.0)):
        M = arrow_matrix(tip, f, scale=0.004, width=0.002)
        end = M @ np.array([1.0, 0, 0, 1])  # the unit arrow's tip
        assert np.allclose(end[:3], tip)
        assert np.isclose(np.linalg.norm(M[:3, 0]), 0.004 * np.linalg.norm(f))
        assert np.allclose(M[:3, 0] / np.linalg.norm(M[:3, 0]), np.array(f) / np.linalg.norm(f))


def test_pause_freezes_the_view(live):
    live.on_bundle(bundle(0.0, contacts()))
    n = live.bundles_shown
    live.pause.setChecked(True)
    live.on_bundle(bundle(0.1, contacts((-2.0, 0, 0))))
    assert live.bundles_shown == n
    live.pause.setChecked(False)
    live.on_bundle(bundle(0.2, contacts((-2.0, 0, 0))))
    assert live.bundles_shown == n + 1
    # acquisition went on while paused: the rings kept the paused sample, Resume shows it
    assert len(live.force_plot.buffer) == 3 and len(live.equilibrium.buffer) == 3


def test_torsion_and_uncertainty_toggles(live):
    g = live.scene.glyphs
    live.show_uncertainty.setChecked(True)
    live.on_bundle(bundle(0.0, contacts()))
    live.display()
    live.scene.sync()
    assert g.ellipsoids[1].GetVisibility() and g.rings[1].GetVisibility()
    live.show_torsion.setChecked(False)
    live.scene.sync()
    assert not g.rings[1].GetVisibility()


class FakeSource:
    simulated = True
    has_reference = False

    def __init__(self):
        self.t = 0.0

    def read(self):
        t = self.t + np.arange(17) / 1000
        self.t = t[-1] + 1e-3
        counts = np.zeros((17, 36))
        counts[:, 2] = 1000.0
        return NewSamples({"time": t, "counts": counts, "tick": np.rint(t * 1e6).astype(np.int64)})

    def stats(self):
        return {"rate_cube": 1000.0}

    def close(self):
        pass


class FakeCalibration:
    offset = np.zeros(36)

    def wrenches(self, counts, offset=None):
        counts = np.asarray(counts)
        W = np.zeros((counts.shape[0], 6, 6))
        W[:, 0, 2] = -counts[:, 2] / 200.0  # 5 N pushing into face 1
        return W


def test_worker_bundles_and_backpressure(qtbot):
    worker = DeviceWorker(rate=60)
    worker.set_source(FakeSource())
    worker.set_calibration(FakeCalibration())
    got = []
    worker.bundle.connect(got.append)
    for _ in range(5):
        worker.tick()
    # the GUI has not acknowledged the first bundle: the later ticks were merged, not queued
    assert worker.emitted == 1 and len(got) == 1
    worker.ack()
    worker.tick()
    assert worker.emitted == 2
    b = got[-1]
    assert b.time.size == 5 * 17  # every sample of the merged ticks
    assert np.allclose(b.wrenches[0, 2], -5.0)
    assert np.allclose(b.sum_force, [-5.0, 0, 0])  # face 1's z is the core's +x


def test_face_sums_about_the_centre_of_gravity():
    core = CubeCore()
    W = np.zeros((6, 6))
    W[0, 2] = -4.0  # pushing on face 1 along -x
    W[2, 2] = -4.0  # and on face 3 along +x: a squeeze, no net force
    W[5, 2] = -2.9  # the table under face 6 (pushing up)
    F, T = face_sums(W, core, cog=(0.0, 0.0, 0.0))
    assert np.allclose(F, [0, 0, 2.9]) and np.allclose(T, 0)
    F2, T2 = face_sums(W, core, cog=(0.01, 0.0, 0.0))
    assert np.allclose(T2, -np.cross([0.01, 0, 0], F2))


def test_merge_keeps_every_sample():
    rng = np.random.default_rng(5)
    a = Bundle(np.arange(3.0), rng.normal(size=(3, 36)), rng.normal(size=(3, 6)), wrenches=rng.normal(size=(6, 6)))
    b = Bundle(np.arange(3.0, 5.0), rng.normal(size=(2, 36)), rng.normal(size=(2, 6)))
    m = merge_bundles(a, b)
    # every sample of both, the older first
    assert m.time.tolist() == [0, 1, 2, 3, 4]
    np.testing.assert_array_equal(m.counts, np.vstack([a.counts, b.counts]))
    np.testing.assert_array_equal(m.reference, np.vstack([a.reference, b.reference]))
    # the newer bundle has no derived values: the older one's are kept, not lost
    np.testing.assert_array_equal(m.wrenches, a.wrenches)
    # when both have them, the newest state wins
    c = Bundle(np.arange(5.0, 6.0), rng.normal(size=(1, 36)), rng.normal(size=(1, 6)), wrenches=rng.normal(size=(6, 6)))
    np.testing.assert_array_equal(merge_bundles(m, c).wrenches, c.wrenches)


def test_the_live_scene_draws_in_its_own_thread(live, qtbot):
    """Frames are rendered by the scene's drawing thread, the glyphs move there, and a grab still works."""
    import threading

    scene = live.scene
    qtbot.waitUntil(lambda: scene.render_thread is not None, timeout=5000)
    rt = scene.render_thread
    assert rt.running and rt._thread is not threading.current_thread()
    rendered_in = []
    obs = scene.plotter.ren_win.AddObserver("StartEvent", lambda *_: rendered_in.append(threading.current_thread().name))
    try:
        n0 = rt.frames
        live.on_bundle(bundle(0.5, contacts()))
        live.display()
        qtbot.waitUntil(lambda: rt.frames > n0 and scene.contacts_time == 0.5, timeout=5000)
        assert set(rendered_in) == {"pito-render"}  # no frame was drawn by the GUI thread
        assert live.scene_time == 0.5 and scene.glyphs.spheres[1].GetVisibility()
        # a rotation with the mouse moves the camera (under the drawing thread's lock) and asks for a frame
        from PySide6.QtCore import QPoint, Qt

        view = scene.plotter.interactor
        cam0 = np.array(scene.plotter.camera.position)
        c = view.rect().center()
        n1 = rt.frames
        qtbot.mousePress(view, Qt.MouseButton.LeftButton, pos=c)
        for dx in range(0, 120, 20):
            qtbot.mouseMove(view, QPoint(c.x() + dx, c.y()))
        qtbot.mouseRelease(view, Qt.MouseButton.LeftButton, pos=QPoint(c.x() + 120, c.y()))
        scene.sync()
        qtbot.waitUntil(lambda: rt.frames > n1, timeout=5000)
        assert not np.allclose(np.array(scene.plotter.camera.position), cam0)
        # a grab renders and reads back in the drawing thread: the contact's white sphere is in it
        from app.scene import grab_scene

        img = grab_scene(scene)
        assert (img.width(), img.height()) == (view.width(), view.height())
        # a hidden view draws nothing (its queued changes still apply); shown again, it draws
        live.hide()
        assert not rt.visible
        scene.sync()
        n2 = rt.frames
        live.on_bundle(bundle(0.7, contacts()))
        scene.sync()
        scene.sync()
        assert rt.frames == n2 and scene.contacts_time == 0.7
        live.show()
        qtbot.waitUntil(lambda: rt.frames > n2, timeout=5000)
        # software GL (Xvfb's llvmpipe here): fewer frames a second than with a GPU, however often asked
        import time

        from app.scene import MAX_FRAME_RATE

        assert scene.software_gl and rt.max_rate == MAX_FRAME_RATE["software"] < MAX_FRAME_RATE["hardware"]
        starts = []
        obs2 = scene.plotter.ren_win.AddObserver("StartEvent", lambda *_: starts.append(time.monotonic()))
        try:
            t_end = time.monotonic() + 0.4
            while time.monotonic() < t_end:
                scene.show_contacts(contacts(), time.monotonic())
                scene.redraw()
                qtbot.wait(2)
            scene.sync()
        finally:
            scene.plotter.ren_win.RemoveObserver(obs2)
        assert len(starts) >= 3
        assert np.diff(starts).min() >= 1.0 / rt.max_rate - 1e-3
        assert rt.errors == []
    finally:
        scene.plotter.ren_win.RemoveObserver(obs)
    scene.close_scene()  # stops the thread; the context is the GUI thread's again
    assert scene.render_thread is None and not rt.running


def test_contacts_go_from_the_worker_thread_to_the_drawing_thread(live, qtbot):
    """The worker hands each bundle's contacts to the 3D view itself (not through the GUI thread)."""
    import threading

    scene = live.scene
    qtbot.waitUntil(lambda: scene.render_thread is not None, timeout=5000)
    # the worker calls its sink with every bundle's contacts and newest sample time
    worker = DeviceWorker(rate=60)
    worker.set_source(FakeSource())
    worker.set_calibration(FakeCalibration())
    worker.set_assembly("cube")
    seen = []
    worker.contacts_sink = lambda c, t: seen.append((c, t))
    worker.tick()
    assert len(seen) == 1 and np.isclose(seen[0][1], 0.016) and seen[0][0].valid[0]
    # from another thread, the live view queues them for the next frame; paused, it does not
    live.direct_contacts = True

    def from_worker(t, c):
        th = threading.Thread(target=live.take_contacts, args=(c, t))
        th.start()
        th.join()

    from_worker(1.5, contacts())
    scene.sync()
    assert scene.contacts_time == 1.5 and scene.glyphs.spheres[1].GetVisibility()
    live.pause.setChecked(True)
    from_worker(2.5, contacts((-3.0, 0.0, 0.0)))
    scene.sync()
    assert scene.contacts_time == 1.5
    live.pause.setChecked(False)
    # the GUI's on_bundle then only counts them (no second move)
    live.on_bundle(bundle(1.5, contacts()))
    assert scene._queued_contacts is None and live._n_shown == 1
    live.direct_contacts = False  # (another tab current: the view's on_bundle moves them itself)
    from_worker(3.5, contacts())
    scene.sync()
    assert scene.contacts_time == 1.5

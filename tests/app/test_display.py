"""What the operator sees: one palette, white contacts, clamped arrows marked, lifted torsion
rings, plots decimated from rings, the loading page's gates, the wizard's default method."""

import warnings

import numpy as np
import pytest

from pito_core.contact import ContactEstimate

pytestmark = pytest.mark.needs_display


def one_contact(force, torsion=0.02):
    pts = np.full((6, 3), np.nan)
    nrm = np.zeros((6, 3))
    frc = np.zeros((6, 3))
    pts[0], nrm[0], frc[0] = (0.025, 0.003, 0.001), (1, 0, 0), force
    valid = np.array([True, False, False, False, False, False])
    return ContactEstimate(pts, nrm, frc, np.array([torsion, 0, 0, 0, 0, 0.0]), valid, frame="core")


def test_palette_has_six_distinct_colours_shared_by_scene_and_plots():
    from app.palette import FACE_COLORS, hex_rgb
    from app.scene import FACE_COLORS as scene_colors
    from app.widgets import plots

    assert scene_colors is FACE_COLORS and plots.FACE_COLORS is FACE_COLORS
    rgb = np.array([hex_rgb(FACE_COLORS[i]) for i in range(1, 7)])
    d = np.linalg.norm(rgb[:, None] - rgb[None], axis=2) + np.eye(6)
    assert d.min() > 0.2  # no two faces share a hue (faces 1 and 5 were two blues)


def test_contact_is_white_on_top_and_the_arrow_ends_on_it(scene):
    from app.palette import CONTACT_COLOR, FACE_COLORS, hex_rgb

    g = scene.glyphs
    g.update(one_contact((-6.0, 1.0, 0.5)))
    assert g.spheres[1].GetVisibility() and np.allclose(g.spheres[1].GetProperty().GetColor(), hex_rgb(CONTACT_COLOR))
    # depth-tested with the object (no overlay): in the glyph layer, which keeps the object's depth buffer
    glyph_layer = scene.backdrop.glyph_renderer
    assert glyph_layer.GetViewProps().IsItemPresent(g.spheres[1]) and glyph_layer.GetPreserveDepthBuffer()
    assert np.allclose(g.arrows[1].prop.color.float_rgb, hex_rgb(FACE_COLORS[1]), atol=1e-3)
    M = np.array(g.arrows[1].user_matrix)
    tip = (M @ np.array([1.0, 0, 0, 1]))[:3]
    assert np.isclose(np.linalg.norm(tip - np.array([0.025, 0.003, 0.001])), g.radius)  # on the sphere's surface
    assert not g.collars[1].GetVisibility()


def test_arrows_beyond_full_scale_are_clamped_and_marked(scene):
    g = scene.glyphs
    g.update(one_contact((-30.0, 0.0, 0.0)))
    M = np.array(g.arrows[1].user_matrix)
    assert np.isclose(np.linalg.norm(M[:3, 0]), g.full_scale * g.force_scale)
    assert g.clamped[0] and g.collars[1].GetVisibility()


def test_torsion_ring_floats_above_the_surface(scene):
    g = scene.glyphs
    g.update(one_contact((-6.0, 0.0, 0.0), torsion=0.05))
    centre = np.array(g.rings[1].user_matrix)[:3, 3]
    assert g.rings[1].GetVisibility() and centre[0] - 0.025 == pytest.approx(g.lift)  # along the normal (+x)


def test_camera_holds_full_scale_arrows(scene):
    scene.frame_contacts()
    cam = scene.plotter.camera
    d = np.linalg.norm(np.array(cam.position) - np.array(cam.focal_point))
    reach = scene.object_radius() + scene.glyphs.reach()
    assert d * np.tan(np.radians(cam.view_angle / 2)) >= reach * 0.999


def test_ring_buffer_view_and_minmax_decimation_keep_peaks():
    from app.widgets.plots import TimeRing, minmax_decimate

    rb = TimeRing(100, 2)
    for k in range(7):
        rb.append(np.column_stack([np.arange(30) + 30 * k, np.arange(30) + 30 * k]))
    v = rb.view()
    assert v.shape == (100, 2) and np.array_equal(v[:, 0], np.arange(110, 210)) and v.base is not None
    t = np.linspace(0, 10, 10_000)
    y = np.zeros((t.size, 2))
    y[5000, 0] = 9.0  # one-sample spike
    y[7000, 1] = -4.0
    td, yd = minmax_decimate(t, y, 0.0, 10.0, 100)
    assert td.size <= 200 and yd[:, 0].max() == 9.0 and yd[:, 1].min() == -4.0


@pytest.mark.parametrize("holes", ["none", "nan", "nan column", "inf"])
def test_minmax_decimation_is_each_columns_nan_ignoring_min_and_max(holes):
    from app.widgets.plots import minmax_decimate

    rng = np.random.default_rng(5)
    t = np.sort(rng.uniform(0.0, 10.0, 5000))
    y = rng.normal(size=(t.size, 3))
    if holes == "nan":
        y[rng.random(y.shape) < 0.2] = np.nan
    elif holes == "nan column":
        y[:, 1] = np.nan
    elif holes == "inf":
        y[17, 0], y[4000, 0] = np.inf, -np.inf
    td, yd = minmax_decimate(t, y, 0.0, 10.0, 300)
    col = np.clip(np.floor(t / 10.0 * 300), 0, 299).astype(int)
    expect_t, expect_y = [], []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN columns
        for c in np.unique(col):
            sel = col == c
            expect_t += [t[sel][0], t[sel][-1]]
            expect_y += [np.nanmin(y[sel], axis=0), np.nanmax(y[sel], axis=0)]
    assert np.array_equal(td, expect_t)
    assert np.array_equal(yd, np.array(expect_y), equal_nan=True)


def test_plot_curves_carry_the_bounds_pyqtgraph_would_find(qtbot):
    import pyqtgraph as pg

    from app.widgets.plots import EquilibriumPlot, FaceForcePlot

    fp, eq = FaceForcePlot(), EquilibriumPlot()
    for w in (fp, eq):
        qtbot.addWidget(w)
    t = 100 + np.arange(3000) * 1e-3
    norms = np.abs(np.sin(t[:, None] * np.arange(1, 7))) * np.arange(1, 7)
    norms[:, 2] = np.nan  # a face without output: no bounds
    norms[100:200, 4] = np.nan  # a gap
    fp.append(t, norms)
    for k in range(0, t.size, 10):
        eq.append(t[k], 2.0 + np.sin(t[k]), 0.003 * np.cos(t[k]) ** 2)
    assert fp.refresh() and eq.refresh()
    for c in fp.curves + [eq.force_curve, eq.torque_curve]:
        for ax in (0, 1):
            mine = c.dataBounds(ax)
            c._boundsCache = [None, None]
            theirs = pg.PlotCurveItem.dataBounds(c, ax)
            if theirs[0] is None or not np.isfinite(theirs[0]):
                assert mine == (None, None)
            else:
                assert mine == theirs, (ax, mine, theirs)


def test_load_page_progress_follows_the_gate_that_holds_the_face():
    from pito_core.devices import CaptureRules, FaceCaptures
    from app.wizard.load_page import face_gates

    fc = FaceCaptures(1, CaptureRules(k=100))
    gates = face_gates(fc)
    assert [g[0] for g in gates] == [0.0, 0.0, 0.0, 0.0]
    assert gates[0][1].startswith("κ ∞")


def test_wizard_defaults_to_the_recommended_method():
    from app.wizard.model import RECOMMENDED_METHOD, RECOMMENDED_WHY, WizardModel

    m = WizardModel()
    assert m.method == RECOMMENDED_METHOD == "unloaded_frame" and m.flange == "face"
    assert "PITO" in RECOMMENDED_WHY and "face_to_face" in RECOMMENDED_WHY


def test_plot_views_paint_every_pixel_of_their_viewport(qtbot):
    """The plots' viewports are opaque (Qt paints no styled background beneath them), so they must cover it
    themselves: on the screen, the same pixels as with the style sheet's background painted first."""
    from PySide6.QtCore import QPoint, Qt
    from PySide6.QtGui import QImage
    from PySide6.QtWidgets import QApplication

    from app.theme import STYLE
    from app.widgets.plots import EquilibriumPlot, FaceForcePlot

    app = QApplication.instance()
    app.setStyleSheet(STYLE)
    try:
        fp, eq = FaceForcePlot(), EquilibriumPlot(weight=2.0)
        t = 100 + np.arange(3000) * 1e-3
        fp.append(t, np.abs(np.sin(t[:, None] * np.arange(1, 7))) * 4)
        for k in range(0, t.size, 10):
            eq.append(t[k], 2.0 + np.sin(t[k]), 0.003)
        views = [fp, eq.force_plot, eq.torque_plot]
        assert all(v.viewport().testAttribute(Qt.WidgetAttribute.WA_OpaquePaintEvent) for v in views)

        def grab():
            out = []
            for v in views:
                vp = v.viewport()
                p = vp.mapToGlobal(QPoint(0, 0))
                img = app.primaryScreen().grabWindow(0, p.x(), p.y(), vp.width(), vp.height()).toImage()
                img = img.convertToFormat(QImage.Format.Format_RGB32)
                out.append(np.array(img.constBits()).reshape(img.height(), img.bytesPerLine()).copy())
            return out

        def screen_pixels():
            """The three viewports as the X server shows them after a fresh paint, once two grabs agree
            (a busy machine delivers the paint late; a paint that leaves garbage is still compared below)."""
            for w in (fp, eq):
                w.repaint()
            last = None
            for _ in range(20):
                qtbot.wait(100)
                now = grab()
                if last is not None and all(np.array_equal(a, b) for a, b in zip(last, now)):
                    break
                last = now
            return now

        for w, y in ((fp, 0), (eq, 300)):
            qtbot.addWidget(w)
            w.setWindowFlag(Qt.WindowType.FramelessWindowHint)
            w.setGeometry(0, y, 500, 280)
            w.show()
            qtbot.waitExposed(w)
        assert fp.refresh() and eq.refresh()
        opaque = screen_pixels()
        for v in views:
            v.viewport().setAttribute(Qt.WidgetAttribute.WA_OpaquePaintEvent, False)
        styled = screen_pixels()
        for a, b in zip(opaque, styled):
            assert a.shape == b.shape and np.array_equal(a, b)
    finally:
        app.setStyleSheet("")


def test_a_new_readout_text_lays_out_the_window_only_when_it_needs_more_room(qtbot):
    from PySide6.QtCore import QEvent, QObject, Qt

    from app.live.view import LiveView

    view = LiveView()
    qtbot.addWidget(view)
    view.resize(1200, 700)
    view.show()
    qtbot.waitExposed(view)
    qtbot.wait(300)  # the view settles (its first layouts)
    r = view.readout
    requests = []

    class Count(QObject):
        def eventFilter(self, obj, ev):  # noqa: N802
            if ev.type() == QEvent.Type.LayoutRequest:
                requests.append(obj)
            return False

    counter = Count()
    r.parentWidget().installEventFilter(counter)
    view._set_readout("2 contacts   ‖ΣF‖  2.85 N   ‖ΣT‖  11.4 mN·m")
    qtbot.wait(200)
    wide = r.width()
    assert wide >= r.sizeHint().width() and r.alignment() & Qt.AlignmentFlag.AlignRight
    requests.clear()
    view._set_readout("1 contact")  # shorter: the same room
    qtbot.wait(50)
    assert requests == [] and r.width() == wide and r.fontMetrics().horizontalAdvance(r.text()) < wide
    view._set_readout("0 contacts   ‖ΣF‖  0.05 N   ‖ΣT‖   0.4 mN·m   face 6: not measured by this calibration")
    qtbot.wait(50)
    assert r.width() >= r.sizeHint().width() > wide  # more room: laid out again

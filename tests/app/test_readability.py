"""Readability (issue 21, defects 8 and 9): the coverage bars' legend and full-scale column,
the loading page's sample count, one font with every glyph, figure text size and titles."""

import numpy as np
import pytest

pytestmark = pytest.mark.needs_display


def grab(widget) -> np.ndarray:
    from PySide6.QtGui import QImage

    img = widget.grab().toImage().convertToFormat(QImage.Format.Format_RGB888)
    w, h = img.width(), img.height()
    buf = np.frombuffer(img.constBits(), np.uint8, count=img.bytesPerLine() * h)
    return buf.reshape(h, img.bytesPerLine())[:, : 3 * w].reshape(h, w, 3).astype(int)


def near(img, hex_color, tol=40):
    c = np.array([int(hex_color[i:i + 2], 16) for i in (1, 3, 5)])
    return np.abs(img - c).sum(axis=2) < tol


@pytest.mark.parametrize("reached", [0.1, 1.0])
def test_full_bars_do_not_cover_the_full_scale_labels(qtbot, styled, reached):
    from app.widgets.coverage import LEGEND_TEXT, REACHED_COLOR, UNDER_COLOR, CoverageBars, CoverageModel

    model = CoverageModel(0.3)
    bars = CoverageBars(model)
    qtbot.addWidget(bars)
    bars.resize(520, 260)
    bars.show()
    qtbot.waitExposed(bars)
    model.set_state(np.full((6, 2), reached), np.zeros(6))
    img = grab(bars)
    color = REACHED_COLOR if reached >= 0.3 else UNDER_COLOR
    bar = bars.bar_rect()
    assert near(img[int(bar.top()):int(bar.bottom()), int(bar.left()):int(bar.right())], color).sum() > 500
    for k in range(6):
        r = bars.value_rect(k)
        cell = img[int(r.top()):int(r.bottom()), int(r.left()):int(r.right())]
        assert not near(cell, REACHED_COLOR).any() and not near(cell, UNDER_COLOR).any()
        assert (cell.sum(axis=2) > 350).sum() > 10  # the "±15 N" text is drawn there
    top = img[: int(bar.top()) - 20]
    assert near(top, UNDER_COLOR).sum() > 20 and near(top, REACHED_COLOR).sum() > 20  # the legend's swatches
    assert "Orange" in bars.toolTip() and bars.toolTip() == LEGEND_TEXT


def test_samples_row_says_at_least_k():
    from app.wizard.load_page import SAMPLES_TIP, samples_text

    assert samples_text(71303, 1000) == "71 303 (≥ 1 000 ✔)"
    assert samples_text(420, 1000) == "420 (≥ 1 000 needed)"
    assert "least" in SAMPLES_TIP and "fit uses all" in SAMPLES_TIP


def test_the_app_font_has_every_glyph_used(qapp, styled):
    import matplotlib
    from matplotlib import font_manager
    from matplotlib.ft2font import FT2Font
    from PySide6.QtGui import QFontMetrics

    from app.fonts import APP_FONT, GLYPHS

    assert qapp.font().family() == APP_FONT
    fm = QFontMetrics(qapp.font())
    missing = [ch for ch in GLYPHS if not fm.inFontUcs4(ord(ch))]
    assert not missing, f"Qt's font lacks {missing}"
    path = font_manager.findfont(matplotlib.rcParams["font.sans-serif"][0])
    ft = FT2Font(path)
    assert "DejaVuSans" in path and all(ft.get_char_index(ord(ch)) for ch in "‖·±σΣ")


@pytest.fixture(scope="module")
def evaluation():
    from pito_core.calibration import fit_and_evaluate
    from pito_core.sim import simulate_calibration

    return fit_and_evaluate(simulate_calibration("frame_hole", 6, k=150, seed=3), "loaded_frame").headline  # SIMULATED


@pytest.mark.parametrize("name", ["rmse", "ident", "comp"])
def test_results_figures_text_is_readable_and_inside(evaluation, name, qapp, styled):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from pito_core import report

    draw = {"rmse": report.rmse_figure, "ident": report.identification_figure, "comp": report.comparison_figure}[name]
    for dark, fig in ((True, Figure(figsize=(576 / 96, 270 / 96), dpi=report.SCREEN_DPI)), (False, None)):
        fig = draw(evaluation, fig, dark=dark)
        canvas = FigureCanvasAgg(fig)
        canvas.draw()
        renderer = canvas.get_renderer()
        box = fig.bbox
        for ax in fig.axes:
            for lab in ax.get_xticklabels() + ax.get_yticklabels():
                if lab.get_text():
                    assert lab.get_fontsize() >= 9
        tight = fig.get_tightbbox(renderer).transformed(fig.dpi_scale_trans)  # every drawn artist, px
        assert tight.x0 >= box.x0 - 1 and tight.x1 <= box.x1 + 1 and tight.y0 >= box.y0 - 1 and tight.y1 <= box.y1 + 1, \
            f"{name}: text cut at the figure's edge ({tight} outside {box})"

"""Issue 45, point 9: the demo's start-up calibration cached, keyed by what makes it (SIMULATED)."""

import numpy as np
import pytest
from PySide6.QtWidgets import QWidget


def test_the_demo_calibration_is_cached_by_its_parameters(demo_cache):
    from app.demo import cached_demo_calibration, demo_cache_path, demo_calibration

    assert cached_demo_calibration(200, 0) is None  # nothing yet
    cal = demo_calibration(200, 0)
    path = demo_cache_path(200, 0)
    assert path.is_file() and path.parent == demo_cache
    again = cached_demo_calibration(200, 0)
    assert again is not None and again.meta["simulated"] is True
    np.testing.assert_array_equal(again.matrix, cal.matrix)
    assert demo_cache_path(200, 1) != path and cached_demo_calibration(200, 1) is None  # another seed
    assert demo_cache_path(300, 0) != path
    path.write_bytes(b"not a calibration")  # a damaged cache is dropped, not used
    assert cached_demo_calibration(200, 0) is None and not path.exists()


@pytest.mark.needs_display
@pytest.mark.slow
def test_a_second_start_shows_forces_without_calibrating(qtbot, styled):
    from app.demo import demo_calibration
    from app.window import MainWindow

    demo_calibration(300, 0)  # what the first start leaves
    window = MainWindow(demo=True, demo_k=300)
    qtbot.addWidget(window)
    try:
        assert window.calibration is not None and window.calibration_task is None
        assert "virtual cube" in window.cal_label.text()
        assert "cached by an earlier start" in window.statusBar().currentMessage()
        # the message fits beside the bar's permanent widgets at the smallest window (no text cut)
        window.resize(1280, 800)
        window.show()
        qtbot.waitExposed(window)
        bar = window.statusBar()
        room = bar.width() - sum(w.sizeHint().width() for w in bar.findChildren(QWidget) if w.parent() is bar
                                 and w.isVisible()) - 24
        assert bar.fontMetrics().horizontalAdvance(bar.currentMessage()) <= room
    finally:
        window.shutdown()
        window.release_views()


def test_decimated_patch_meshes_are_cached(demo_cache):
    from app.objects import display_meshes, load_assembly
    from app.scene import PATCH_DISPLAY_CELLS

    a = load_assembly("pito_mixed")
    first = display_meshes(a)
    files = sorted(demo_cache.glob("patch-*.vtp"))
    assert files and all(m.n_cells <= PATCH_DISPLAY_CELLS for m in first.values())
    again = display_meshes(a)
    for i in first:
        np.testing.assert_allclose(np.asarray(again[i].points), np.asarray(first[i].points))
    files[0].write_bytes(b"damaged")  # dropped and made again
    display_meshes(a)
    assert files[0].stat().st_size > 100


def test_a_library_assemblys_display_meshes_are_read_back_without_building_a_patch(demo_cache, monkeypatch):
    from app.objects import display_meshes, load_assembly

    a = load_assembly("pito_mixed")
    first = display_meshes(a, "pito_mixed")
    assert len(sorted(demo_cache.glob("display-*.vtp"))) == 6

    def no_build(face):
        raise AssertionError("a patch mesh was built although the description's meshes are cached")

    b = load_assembly("pito_mixed")
    monkeypatch.setattr(b, "face_mesh", no_build)
    again = display_meshes(b, "pito_mixed")
    for i in first:
        np.testing.assert_allclose(np.asarray(again[i].points), np.asarray(first[i].points))
        np.testing.assert_array_equal(np.asarray(again[i].faces), np.asarray(first[i].faces))
    with pytest.raises(AssertionError, match="was built"):  # another assembly: another key, built
        display_meshes(b, "cube")
    sorted(demo_cache.glob("display-*.vtp"))[0].write_bytes(b"damaged")  # dropped, built again
    display_meshes(load_assembly("pito_mixed"), "pito_mixed")
    assert all(p.stat().st_size > 100 for p in demo_cache.glob("display-*.vtp"))

"""GUI tests of pito-app (pytest-qt). They need an X server: run the suite under
``xvfb-run -a -s "-screen 0 1600x1000x24" pytest`` (QT_QPA_PLATFORM unset: the offscreen
platform leaves the 3D view blank)."""

import os

import pytest

pytest.importorskip("PySide6")
pytest.importorskip("pyvistaqt")
pytest.importorskip("pytestqt")


def pytest_collection_modifyitems(config, items):
    here = os.path.dirname(__file__)
    no_display = not os.environ.get("DISPLAY") and not os.environ.get("WAYLAND_DISPLAY")
    skip = pytest.mark.skip(reason="GUI test: needs an X server (run under xvfb-run)")
    for item in items:
        if str(item.fspath).startswith(here):
            item.add_marker(pytest.mark.gui)
            if no_display and "needs_display" in item.keywords:
                item.add_marker(skip)


@pytest.fixture(autouse=True)
def demo_cache(tmp_path, monkeypatch):
    """Each test its own empty cache of the demo's calibration (app/demo.py): nothing shared between tests."""
    path = tmp_path / "pito-cache"
    monkeypatch.setenv("PITO_CACHE_DIR", str(path))
    return path


@pytest.fixture(autouse=True)
def gc_in_gui_thread(request):
    """Garbage cycles (closed windows, pages, menus) freed in the GUI thread only, as in
    pito-app (app/gc_guard.py): a collection started by a worker thread could run a Qt
    destructor there and deadlock against the GUI thread."""
    if "qapp" not in request.fixturenames and "qtbot" not in request.fixturenames:
        yield
        return
    import gc

    from app.gc_guard import GuiThreadCollector

    qapp = request.getfixturevalue("qapp")
    gc.collect()
    collector = GuiThreadCollector(qapp).install()
    yield
    collector.uninstall()
    gc.collect()  # what the test left, here in the GUI thread
    collector.deleteLater()


@pytest.fixture(scope="session")
def qapp_args():
    return ["pito-app-tests"]


@pytest.fixture
def styled(qapp):
    from app.fonts import install_app_font
    from app.theme import STYLE

    install_app_font(qapp)
    qapp.setStyleSheet(STYLE)
    return qapp


@pytest.fixture
def scene(qtbot):
    """A :class:`app.scene.CubeScene` of the bare cube, 640 × 480 px, shown (closed after the test)."""
    from app.scene import CubeScene
    from pito_core.frames import CubeCore

    s = CubeScene(CubeCore())
    qtbot.addWidget(s)
    s.resize(640, 480)
    s.show()
    qtbot.waitExposed(s)
    yield s
    s.close_scene()


@pytest.fixture(scope="module")
def fitted():
    """A SIMULATED ``loaded_frame`` calibration and its evaluation, fitted as the results page does (k = 150)."""
    from pito_core.calibration import fit_and_evaluate
    from pito_core.sim import simulate_calibration

    session = simulate_calibration("frame_hole", 6, k=150, seed=3)  # SIMULATED
    fit = fit_and_evaluate(session, "loaded_frame")
    return fit.calibration, fit.headline

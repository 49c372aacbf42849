"""Issue 45, point 9: the live view's first frame waits for nothing it does not show.

The wizard (two 3D views) is built when its tab is first shown or ``window.wizard`` is used, and
it then shows what the window learnt meanwhile (the devices line); the app's start-up imports
neither the wizard nor matplotlib.
"""

import os
import time
import subprocess
import sys

import pytest


@pytest.mark.needs_display
def test_the_wizard_is_built_when_its_tab_is_first_shown(qtbot, styled):
    from app.window import MainWindow

    window = MainWindow()
    qtbot.addWidget(window)
    try:
        assert window._wizard is None and window.tabs.count() == 2
        assert window.tabs.tabText(1) == "Calibration wizard"
        window._set_devices_status("✔ cube on /dev/ttyX, reference at 192.0.2.1", True)
        window.tabs.setCurrentIndex(1)  # the operator clicks the tab
        wiz = window._wizard
        assert wiz is not None and window.tabs.widget(1) is wiz and window.tabs.currentWidget() is wiz
        assert window.tabs.count() == 2 and window.tabs.tabText(1) == "Calibration wizard"
        assert "/dev/ttyX" in wiz.pages["devices"].status.text()
        assert window.wizard is wiz  # built once
        window.tabs.setCurrentIndex(0)
        window.tabs.setCurrentIndex(1)
        assert window.wizard is wiz and window.tabs.count() == 2
    finally:
        window.shutdown()
        window.release_views()


@pytest.mark.needs_display
def test_using_window_wizard_builds_it_in_its_tab(qtbot, styled):
    from app.window import MainWindow

    window = MainWindow()
    qtbot.addWidget(window)
    try:
        wiz = window.wizard
        assert window.tabs.indexOf(wiz) == 1 and window.tabs.currentIndex() == 0  # the live view stays in front
        window.tabs.setCurrentWidget(wiz)
        assert window.tabs.currentWidget() is wiz
    finally:
        window.shutdown()
        window.release_views()


def test_the_window_module_loads_neither_the_wizard_nor_matplotlib():
    code = ("import sys; import app.window, app.fonts; "
            "print(sorted(m for m in ('app.wizard.wizard', 'app.wizard.results_page', 'matplotlib') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60,
                         env={**os.environ, "QT_QPA_PLATFORM": "offscreen"})
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "[]"


def test_the_demo_boot_starts_both_children_at_once_and_connects_them():
    from app.main import _boot_demo_devices

    boot = _boot_demo_devices(0, 1.5)
    time.sleep(1.0)
    # the pipeline opens the devices only once the (built) window asks for them
    assert not boot.hold.is_set() and not boot.done()
    rig = boot.result(timeout=90)
    try:
        src = rig.open_source()
        assert rig.process.has_reference and rig.sim.alive()
        deadline = time.monotonic() + 30
        while (b := src.take()) is None or len(b) == 0:
            assert time.monotonic() < deadline, "no samples from the demo's pipeline process"
            time.sleep(0.05)
    finally:
        rig.close()
    assert rig.process._proc.poll() is not None and not rig.sim.alive()


def test_a_pipeline_launch_never_configured_ends_with_its_socket():
    from pito_core.pipeline import PipelineLaunch

    launch = PipelineLaunch()
    launch.close()
    assert launch.proc.returncode == 0


def test_the_demo_start_up_loads_no_fit_no_simulation_and_no_export_writers(demo_cache):
    """What the app's process imports for its window, a cached calibration and cached display meshes:
    not the fit (scipy.optimize, scipy.linalg), the contact test (scipy.special), the simulated world
    (it runs in its own process), trimesh or the MCAP/NWB writers (docs/app.md, "Start-up")."""
    from app.demo import demo_calibration
    from app.objects import display_meshes, load_assembly

    demo_calibration(50, 0)  # what a first start leaves in the cache
    display_meshes(load_assembly("pito_mixed"), "pito_mixed")
    code = ("import sys; import app.main, app.window; from app.demo import cached_demo_calibration; "
            "from app.objects import display_meshes, load_assembly; "
            "assert cached_demo_calibration(50, 0) is not None, 'the cached calibration was not read'; "
            "display_meshes(load_assembly('pito_mixed'), 'pito_mixed'); "
            "print(sorted(m for m in ('scipy.optimize', 'scipy.linalg', 'scipy.special', 'trimesh', "
            "'pito_core.sim._world', "
            "'pito_core.calibration._fit', 'pito_core.interop._mcap', 'pito_core.interop._nwb') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                         env={**os.environ, "QT_QPA_PLATFORM": "offscreen", "PITO_CACHE_DIR": str(demo_cache)})
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip().splitlines()[-1] == "[]"

"""Importing the app changes no global state of the libraries it uses (pyvista's theme)."""

import subprocess
import sys

CODE = r"""
import json, pyvista as pv
before = json.dumps(pv.global_theme.to_dict(), sort_keys=True, default=str)
import app, app.scene, app.live.view
after = json.dumps(pv.global_theme.to_dict(), sort_keys=True, default=str)
print('same' if before == after else 'changed')
"""


def test_importing_the_scene_leaves_pyvistas_global_theme_alone():
    r = subprocess.run([sys.executable, "-c", CODE], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip().splitlines()[-1] == "same"


def test_scene_plotter_draws_without_multisampling(qtbot):
    from app.scene import CubeScene

    scene = CubeScene()
    qtbot.addWidget(scene)
    assert scene.plotter.ren_win.GetMultiSamples() == 0

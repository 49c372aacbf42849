"""pito_core never imports the GUI: it imports with Qt and pyvista made unimportable."""

import subprocess
import sys

CODE = r"""
import sys, importlib, pkgutil
class Block:
    def find_spec(self, name, path=None, target=None):
        if name.split('.')[0] in ('PySide6', 'pyvista', 'pyvistaqt', 'pyqtgraph', 'PyQt5', 'PyQt6', 'vtk', 'app'):
            raise ImportError('GUI module blocked: ' + name)
        return None
sys.meta_path.insert(0, Block())
import pito_core
for m in pkgutil.walk_packages(pito_core.__path__, 'pito_core.'):
    importlib.import_module(m.name)
print('ok', len(sys.modules))
"""


def test_core_imports_without_gui():
    r = subprocess.run([sys.executable, "-c", CODE], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert r.stdout.startswith("ok")

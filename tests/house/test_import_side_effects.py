"""Importing pito changes no global state: every module of pito_core, app and pito_bench is
imported in a fresh interpreter and the libraries' global settings are compared before and after.

Checked: pyqtgraph's config options, matplotlib's rcParams (and its backend), pyvista's global
theme, the root logger, the warnings filters, the environment, ``sys.path``, the locale, signal handlers,
exception hooks and multiprocessing's start method.
The third-party libraries are imported first, so a change counted here is made by our modules.
"""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

pytest.importorskip("PySide6")
pytest.importorskip("pyvista")
pytest.importorskip("pyqtgraph")

CODE = r"""
import ast, importlib, importlib.util, json, locale, logging, multiprocessing, os, pathlib, pkgutil, signal, sys
import threading, warnings
import matplotlib, pyqtgraph, pyvista

def third_party(tops):
    # every other module our sources name in an import, so their own import-time settings
    # (threadpoolctl's KMP_DUPLICATE_LIB_OK, scipy's warnings filters...) fall before the baseline
    names = set()
    for top in tops:
        root = pathlib.Path(importlib.util.find_spec(top).submodule_search_locations[0])
        for path in root.rglob("*.py"):
            for node in ast.walk(ast.parse(path.read_text())):
                if isinstance(node, ast.Import):
                    names.update(a.name for a in node.names)
                elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                    names.add(node.module)
    ours = {"pito_core", "app", "pito_bench", *tops}
    for name in sorted(n for n in names if n.split(".")[0] not in ours):
        try:
            importlib.import_module(name)
        except ImportError:  # an optional dependency not installed: our modules defer it too
            pass

third_party(sys.argv[1:])

def state():
    return {
        "pyqtgraph": {k: repr(v) for k, v in pyqtgraph.CONFIG_OPTIONS.items()},
        # dict.items: RcParams' own __getitem__ would resolve the 'backend' sentinel (loads pyplot)
        "matplotlib.rcParams": {k: repr(v) for k, v in dict.items(matplotlib.rcParams)},
        "pyvista.global_theme": repr(pyvista.global_theme.to_dict()),
        "logging.root": repr((logging.root.level, logging.root.handlers)),
        "warnings.filters": [repr(f) for f in warnings.filters],
        "os.environ": dict(os.environ),
        "sys.path": list(sys.path),
        "locale": repr(locale.setlocale(locale.LC_ALL)),
        "signal handlers": {s.name: repr(signal.getsignal(s)) for s in (signal.SIGINT, signal.SIGTERM, signal.SIGCHLD)},
        "excepthooks": repr((sys.excepthook, threading.excepthook)),
        "multiprocessing start method": repr(multiprocessing.get_start_method(allow_none=True)),
    }

before = state()
imported = []
for top in sys.argv[1:]:
    pkg = importlib.import_module(top)
    imported.append(top)
    for m in pkgutil.walk_packages(pkg.__path__, top + "."):
        importlib.import_module(m.name)
        imported.append(m.name)
after = state()
changed = {}
for key in before:
    a, b = before[key], after[key]
    if isinstance(a, dict):
        diff = {k: (a.get(k), b.get(k)) for k in set(a) | set(b) if a.get(k) != b.get(k)}
    else:
        diff = (a, b) if a != b else None
    if diff:
        changed[key] = diff
print(json.dumps({"modules": len(imported), "changed": changed}, default=str))
"""


def imports_change(*packages: str, setup: str = "") -> dict:
    """Import every module of ``packages`` in a fresh interpreter (after ``setup``, Python code);
    return what changed: ``{setting: difference}`` (empty: nothing)."""
    r = subprocess.run([sys.executable, "-c", setup + "\n" + CODE, *packages], capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 0, r.stderr[-3000:]
    out = json.loads(r.stdout.strip().splitlines()[-1])
    assert out["modules"] > len(packages), out  # the walk found the modules
    return out["changed"]


def test_importing_every_module_changes_no_global_setting():
    changed = imports_change("pito_core", "app", "pito_bench")
    assert changed == {}, f"changed on import: {changed}"


def test_the_check_sees_a_change_made_on_import(tmp_path):
    # a module that sets a global option at import, as app/widgets/plots.py once did
    (tmp_path / "pito_probe").mkdir()
    (tmp_path / "pito_probe" / "__init__.py").write_text(
        "import pyqtgraph, matplotlib, pyvista\n"
        "pyqtgraph.setConfigOptions(background='#1e2329')\n"
        "matplotlib.rcParams['font.family'] = 'monospace'\n"
        "pyvista.global_theme.background = '#123456'\n")
    (tmp_path / "pito_probe" / "quiet.py").write_text("x = 1\n")
    changed = imports_change("pito_probe", setup=f"import sys; sys.path.insert(0, {str(tmp_path)!r})")
    assert set(changed) == {"pyqtgraph", "matplotlib.rcParams", "pyvista.global_theme"}, changed
    assert set(changed["pyqtgraph"]) == {"background"}
    assert set(changed["matplotlib.rcParams"]) == {"font.family"}

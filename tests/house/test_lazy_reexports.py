"""The packages' re-exports load on first use (pito_core/_lazy.py): the public names are the same,
and a device process imports only what it needs (the demo's start-up, docs/app.md "Start-up")."""

from __future__ import annotations

import importlib
import subprocess
import sys

import pytest

from pito_core._lazy import reexports

PACKAGES = ["pito_core", "pito_core.calibration", "pito_core.contact", "pito_core.devices", "pito_core.frames", "pito_core.interop",
            "pito_core.io", "pito_core.pipeline", "pito_core.sim"]


@pytest.mark.parametrize("name", PACKAGES)
def test_every_public_name_resolves_to_its_module_object(name):
    pkg = importlib.import_module(name)
    where = reexports(open(pkg.__file__, encoding="utf-8").read())
    assert set(pkg.__all__) - {"__version__"} <= set(where), "every name in __all__ is re-exported"
    for attr, module in where.items():
        obj = getattr(pkg, attr)
        assert obj is getattr(importlib.import_module(module, name), attr)
    assert set(pkg.__all__) <= set(dir(pkg))
    with pytest.raises(AttributeError, match="has no attribute 'not_a_name'"):
        pkg.not_a_name  # noqa: B018


def test_from_import_works_for_a_lazy_name():
    from pito_core import Calibration
    from pito_core.calibration import Calibration as same

    assert Calibration is same


def test_reexports_rejects_a_non_relative_line():
    with pytest.raises(ValueError, match="only relative"):
        reexports("if TYPE_CHECKING:\n    import numpy\n")


def _modules_after(statement: str) -> set[str]:
    code = f"import sys\n{statement}\nprint('\\n'.join(sys.modules))"
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return set(r.stdout.split())


def test_the_devices_and_the_sim_package_import_no_scipy_and_no_calibration():
    mods = _modules_after("import pito_core.devices, pito_core.sim, pito_core.pipeline")
    assert "scipy" not in mods
    assert not any(m.startswith("pito_core.calibration") for m in mods)


def test_the_device_child_processes_import_no_calibration_code():
    # the simulated devices' child and the pipeline child: no least-squares code, no scipy.optimize
    for child in ("pito_core.sim._child", "pito_core.pipeline._process_child"):
        mods = _modules_after(f"import {child}")
        assert "scipy.optimize" not in mods, child
        if child == "pito_core.sim._child":
            assert not any(m.startswith("pito_core.calibration") for m in mods)


def test_the_launchers_of_the_demo_processes_load_the_standard_library_only():
    # pito-app --demo starts both children on its first line, before importing numpy, Qt or the core
    mods = _modules_after("from pito_core.sim import DevicesLaunch\nfrom pito_core.pipeline import PipelineLaunch")
    assert "numpy" not in mods
    assert not any(m.startswith("pito_core.") and m.split(".")[-1] not in ("_lazy", "_version", "sim", "pipeline",
                                                                           "_launch") for m in mods)

"""Lazy re-exports for the packages' ``__init__`` (PEP 562): a name loads its module on first use.

A package writes its re-exports as usual, under ``if TYPE_CHECKING:`` (so type checkers, IDEs
and import-linter see them), keeps its ``__all__``, and ends the block with::

    __getattr__, __dir__ = attach(__name__, __file__)

:func:`attach` reads those ``from .x import a, b`` lines from the package's own source, once.
``from pito_core.sim import DemoWorld`` and ``pito_core.sim.DemoWorld`` work as with eager
imports; importing one submodule (``python -m pito_core.sim._child``) no longer loads every
sibling and their dependencies (scipy, h5py), which the demo's device processes paid at
start-up (docs/app.md, "Start-up"). No third-party code here.
"""

from __future__ import annotations

import ast
import sys
from importlib import import_module
from pathlib import Path

__all__ = ["attach", "reexports"]


def reexports(source: str) -> dict[str, str]:
    """Name → relative module (``"._world"``) of every ``from .x import name`` under a top-level
    ``if TYPE_CHECKING:`` in ``source`` (a package's ``__init__``)."""
    where = {}
    for node in ast.parse(source).body:
        if isinstance(node, ast.If) and isinstance(node.test, ast.Name) and node.test.id == "TYPE_CHECKING":
            for imp in node.body:
                if not (isinstance(imp, ast.ImportFrom) and imp.level >= 1):
                    raise ValueError(f"reexports: only relative 'from . import' lines, got line {imp.lineno}")
                for alias in imp.names:
                    where[alias.asname or alias.name] = "." * imp.level + (imp.module or "")
    return where


def attach(package: str, init_file: str):
    """``(__getattr__, __dir__)`` for ``package``, whose ``__init__`` is ``init_file``.

    The first access to a re-exported name imports its module and stores the name on the
    package, so later accesses are plain attribute lookups. Other names raise ``AttributeError``.
    """
    where = reexports(Path(init_file).read_text(encoding="utf-8"))

    def __getattr__(name: str):
        try:
            module = where[name]
        except KeyError:
            raise AttributeError(f"module {package!r} has no attribute {name!r}") from None
        value = getattr(import_module(module, package), name)
        setattr(sys.modules[package], name, value)
        return value

    def __dir__():
        return sorted(set(vars(sys.modules[package])) | set(where))

    return __getattr__, __dir__

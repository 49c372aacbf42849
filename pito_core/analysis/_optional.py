"""The analysis's optional dependencies (extra ``analysis``: pandas, dask[distributed]), imported where used."""

from __future__ import annotations

import importlib

__all__ = ["require"]


def require(module: str, needed_by: str, package: str | None = None):
    """Import ``module`` (an optional dependency), or raise an ImportError naming ``package`` (default
    ``module``) and the extra to install.

    Deferred on purpose: ``pito_core`` imports without pandas or Dask; only the analysis needs them.
    """
    try:
        return importlib.import_module(module)
    except ImportError as exc:  # pragma: no cover - exercised only without the extra
        raise ImportError(f"{needed_by} needs {package or module}: pip install 'pito[analysis]'") from exc

"""Entry point of the pipeline process: ``python -m pito_core.pipeline._process_child CONFIG_JSON FD``.

See :mod:`pito_core.pipeline._process` (protocol, no orphans). A module of its own so that
``-m`` does not run ``_process`` a second time beside the package's import of it.
"""

from __future__ import annotations

import sys

from ._process import main

if __name__ == "__main__":
    sys.exit(main())

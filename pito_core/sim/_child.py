"""Entry point of the simulated-devices child process: ``python -m pito_core.sim._child CONFIG_JSON``.

See :mod:`pito_core.sim._process` (announcement line, control channel, no orphans).
"""

from __future__ import annotations

import json
import sys

from ._process import run_devices


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    cfg = json.loads(argv[0]) if argv else {}
    run_devices(**cfg, watch_parent=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())

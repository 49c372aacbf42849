"""The ``pito`` command: one module per subcommand, each with ``register(subparsers)``.

A subcommand module defines ``register(subparsers)`` that adds its parser (with a help
line and ``--help`` text that explains units and defaults) and sets ``func=run`` where
``run(args) -> int`` is the exit status.
"""

from __future__ import annotations

import argparse
import importlib
import sys
import warnings
from importlib.metadata import entry_points

from .._version import __version__

#: Subcommand modules, in the order ``pito --help`` lists them.
COMMANDS = (
    "calibrate",
    "evaluate",
    "simulate",
    "reproduce",
    "devices",
    "sim-devices",
    "record",
    "replay",
    "export",
    "analyze",
    "stream",
)

#: Entry-point group through which other installed packages add subcommands (``pito bench``
#: comes from ``pito_bench``, outside the core, so the core never imports the benchmark,
#: which starts the desktop app in a subprocess).
PLUGIN_GROUP = "pito.commands"


def _plugins():
    """The ``register`` functions other installed packages offer, sorted by command name."""
    return sorted(entry_points(group=PLUGIN_GROUP), key=lambda ep: ep.name)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="pito",
        description=(
            "pito: calibrate the PITO cube against a reference sensor, evaluate calibrations, "
            "simulate, record and replay. Units are SI everywhere (N, N·m, m, s); faces are 1..6."
        ),
    )
    parser.add_argument("--version", action="version", version=f"pito {__version__}")
    sub = parser.add_subparsers(title="commands", metavar="COMMAND")
    for name in COMMANDS:
        importlib.import_module(f"{__name__}._{name.replace('-', '_')}").register(sub)
    for ep in _plugins():
        ep.load()(sub)
    return parser


#: Optional dependencies → (the distribution to install, the extra of ``pito`` that brings it).
OPTIONAL = {
    "pylsl": ("pylsl", "interop"), "pynwb": ("pynwb", "interop"), "hdmf": ("pynwb", "interop"),
    "mcap": ("mcap", "interop"), "mcap_ros2": ("mcap-ros2-support", "interop"),
    "nwbinspector": ("nwbinspector", "interop"),
    "pandas": ("pandas", "analysis"), "dask": ("dask[distributed]", "analysis"),
    "distributed": ("dask[distributed]", "analysis"), "bokeh": ("bokeh", "analysis"),
}


def missing_dependency(exc: ImportError) -> str | None:
    """One line naming the package and the extra to install for a missing optional dependency (None: not one)."""
    name = (getattr(exc, "name", None) or "").split(".")[0]
    if name in OPTIONAL:
        package, extra = OPTIONAL[name]
        return f"this needs {package}, an optional dependency: pip install 'pito[{extra}]'"
    if "pip install 'pito[" in str(exc):  # pito's own ImportError already says which extra
        return str(exc)
    return None


def _one_line(default):
    """A ``warnings.showwarning`` that prints pito's own warnings as one line on stderr, like its errors, and
    hands the others to ``default``."""

    def show(message, category, filename, lineno, file=None, line=None) -> None:
        if category.__module__.startswith("pito_core"):
            print(f"pito: warning: {message}", file=sys.stderr if file is None else file)
        else:
            default(message, category, filename, lineno, file, line)

    return show


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not hasattr(args, "func"):
        parser.print_help()
        return 2
    try:
        with warnings.catch_warnings():
            warnings.showwarning = _one_line(warnings.showwarning)
            return int(args.func(args) or 0)
    except (ValueError, FileNotFoundError) as exc:  # user errors: one clear line, no traceback
        print(f"pito: error: {exc}", file=sys.stderr)
        return 1
    except ImportError as exc:  # a missing optional dependency: one line naming the extra, exit 2
        line = missing_dependency(exc)
        if line is None:
            raise
        print(f"pito: error: {line}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # output piped into `head` and the like
        sys.stderr.close()
        return 0
    except KeyboardInterrupt:
        print("pito: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())

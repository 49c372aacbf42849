"""The version of pito (one place: the package, the file writers and the CLI read it)."""

__version__ = "0.1.0"

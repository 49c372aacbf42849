"""pito-app: the PySide6 + pyvista + pyqtgraph desktop application (a thin shell over pito_core)."""

from ._compat import protect_singletons

#: True when the PySide6 Signal.emit reference leak was detected and neutralised (see _compat).
SIGNAL_LEAK_WORKAROUND = protect_singletons()

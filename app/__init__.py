"""pito-app: the PySide6 + pyvista + pyqtgraph desktop application (a thin shell over pito_core)."""

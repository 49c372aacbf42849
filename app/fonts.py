"""The app's one font, DejaVu Sans, for Qt and matplotlib alike: it has every glyph the app draws.

The labels use ‖ (norms), · (N·m), ±, σ, Σ, κ, ✔ and arrows; a fallback font without them draws
grey blocks (seen on rotated pyqtgraph axis labels). DejaVu Sans ships with matplotlib (a
dependency), so :func:`install_app_font` registers matplotlib's copy with Qt: the font is there
even where the system has none (``scripts/install-system-deps.sh`` also installs
``fonts-dejavu-core`` for the rest of the desktop).
"""

from __future__ import annotations

import sys
from importlib.util import find_spec
from pathlib import Path

from PySide6.QtGui import QFont, QFontDatabase

__all__ = ["APP_FONT", "GLYPHS", "install_app_font", "matplotlib_font_files", "use_app_font_in_matplotlib"]

APP_FONT = "DejaVu Sans"
#: characters the app's labels use that a font must have
GLYPHS = "‖·±σΣκ✔→−²"


def matplotlib_font_files() -> list[Path]:
    """The DejaVu Sans (and Mono) TrueType files bundled with matplotlib (found without importing it:
    half a second of the app's start-up that the live view does not need)."""
    folder = Path(find_spec("matplotlib").submodule_search_locations[0]) / "mpl-data" / "fonts" / "ttf"
    return sorted(folder.glob("DejaVuSans*.ttf"))


def install_app_font(app, point_size: float | None = None) -> str:
    """Register DejaVu Sans with Qt, make it ``app``'s font and matplotlib's; returns the family set.

    Called once, at startup (``pito-app``; the GUI tests' ``styled`` fixture).
    """
    for path in matplotlib_font_files():
        QFontDatabase.addApplicationFont(str(path))
    font = QFont(APP_FONT)
    if point_size is not None:
        font.setPointSizeF(point_size)
    app.setFont(font)
    if "matplotlib" in sys.modules:  # else the modules that draw with it call use_app_font_in_matplotlib
        use_app_font_in_matplotlib()
    return font.family()


def use_app_font_in_matplotlib() -> None:
    """Make :data:`APP_FONT` matplotlib's first sans-serif font (called where the app draws with matplotlib)."""
    import matplotlib  # deferred: the live view does not need it (see matplotlib_font_files)

    matplotlib.rcParams["font.family"] = "sans-serif"
    matplotlib.rcParams["font.sans-serif"] = [APP_FONT] + [f for f in matplotlib.rcParams["font.sans-serif"] if f != APP_FONT]

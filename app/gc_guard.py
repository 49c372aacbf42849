"""Python's cyclic garbage collection in the GUI thread only.

Why: the collector runs in whichever thread happens to allocate when its thresholds are
crossed. In this application that is often a worker (a background figure render, the live
feed's threads). If the garbage holds a Qt object (a closed dialog, a page with its
menus), its C++ destructor then runs in that worker: it takes Qt's object lock and asks
for the interpreter lock, while the GUI thread, holding the interpreter lock, waits for
the same Qt lock — a deadlock, or a crash when the object belonged to the GUI thread.
:class:`GuiThreadCollector` turns automatic collection off and collects from a timer of
the GUI thread instead, generation by generation, with Python's own thresholds (the
well-known remedy for PyQt/PySide programs). Installed by ``pito-app`` at start-up (not
on import) and by the GUI tests.
"""

from __future__ import annotations

import gc

from PySide6.QtCore import QObject, QTimer

__all__ = ["GuiThreadCollector"]

#: How often the GUI thread looks at the allocation counts (ms).
CHECK_INTERVAL_MS = 200


class GuiThreadCollector(QObject):
    """Run the cyclic garbage collector from the GUI thread's event loop only.

    Parameters
    ----------
    parent : QObject, optional
        Usually the ``QApplication``; the collector must live in the GUI thread.
    interval_ms : int
        How often the allocation counts are checked (ms).

    ``install()`` disables automatic collection and starts the timer; ``uninstall()`` puts
    automatic collection back as it was. ``collections`` counts the collections made.
    """

    def __init__(self, parent: QObject | None = None, interval_ms: int = CHECK_INTERVAL_MS):
        super().__init__(parent)
        self.thresholds = gc.get_threshold()
        self.collections = 0
        self._was_enabled = gc.isenabled()
        self.timer = QTimer(self)
        self.timer.setInterval(int(interval_ms))
        self.timer.timeout.connect(self.check)

    def install(self) -> "GuiThreadCollector":
        self._was_enabled = gc.isenabled()
        gc.disable()
        self.timer.start()
        return self

    def freeze_startup(self) -> None:
        """Move every object made so far (modules, the window) out of all later collections (``gc.freeze``).

        Called once the window is built: those objects live as long as the app, and the first
        collection over them (300 000 objects: 0.08 s of the GUI thread) fell on the first frames;
        later collections go over new objects only."""
        gc.freeze()

    def uninstall(self) -> None:
        self.timer.stop()
        if self._was_enabled:
            gc.enable()

    def check(self) -> None:
        """Collect the oldest generation whose count passed its threshold (as Python would)."""
        counts = gc.get_count()
        for generation in (2, 1, 0):
            if self.thresholds[generation] and counts[generation] > self.thresholds[generation]:
                gc.collect(generation)
                self.collections += 1
                return

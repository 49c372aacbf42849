"""Base of the wizard's pages: a title, a readiness flag that gates Next, enter/leave hooks."""

from __future__ import annotations

from PySide6.QtCore import Signal
from PySide6.QtWidgets import QLabel, QVBoxLayout, QWidget

__all__ = ["WizardPage"]


class WizardPage(QWidget):
    """One step of the calibration wizard.

    Subclasses set ``title`` and ``help``, build their widgets in ``self.body`` (a layout),
    call :meth:`set_ready` when the operator may go on, and may override :meth:`enter`,
    :meth:`leave` and :meth:`on_bundle` (live data from the live feed).
    """

    title = ""
    help = ""
    ready_changed = Signal(bool)

    def __init__(self, model, parent=None):
        super().__init__(parent)
        self.model = model
        self._ready = False
        outer = QVBoxLayout(self)
        outer.setContentsMargins(16, 12, 16, 8)
        heading = QLabel(self.title)
        heading.setObjectName("pageTitle")
        outer.addWidget(heading)
        if self.help:
            sub = QLabel(self.help)
            sub.setObjectName("pageHelp")
            sub.setWordWrap(True)
            outer.addWidget(sub)
        self.body = QVBoxLayout()
        outer.addLayout(self.body, 1)

    def is_ready(self) -> bool:
        return self._ready

    def set_ready(self, ready: bool) -> None:
        ready = bool(ready)
        if ready != self._ready:
            self._ready = ready
            self.ready_changed.emit(ready)

    def enter(self) -> None:
        """Called when the page is shown."""

    def leave(self) -> None:
        """Called when the page is left (forward or back)."""

    def on_bundle(self, bundle) -> None:
        """Live data (a :class:`pito_core.pipeline.LiveBundle`, merged while the GUI drew) while the page is shown."""

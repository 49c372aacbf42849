"""Device health in the status bar: "stalled", rate mismatch, saturation.

A permanent status-bar label updated every 50 ms from the latest bundle's device stats
(``bundle.stats["devices"]``, words from :func:`pito_core.devices._health.health_words`), plus a
"no data" watchdog when no bundle with samples came for 150 ms. Shows the stall count.
"""

from __future__ import annotations

import time

from PySide6.QtCore import QTimer
from PySide6.QtWidgets import QLabel

from pito_core.devices import health_words

__all__ = ["HealthIndicator", "install_health_indicator"]


class HealthIndicator(QLabel):
    """Status-bar label: "devices ok" or the health words (red); ``stalls`` counts the stalls seen."""

    def __init__(self, parent=None):
        super().__init__("devices: –", parent)
        self.stats: dict | None = None
        self.last_data = None  # time.monotonic() of the last bundle with samples
        self.stalls = 0
        self._stalled = False
        self.timer = QTimer(self)
        self.timer.setInterval(50)
        self.timer.timeout.connect(self.refresh)
        self.timer.start()

    def on_bundle(self, bundle) -> None:
        stats = getattr(bundle, "stats", None) or {}
        if stats.get("replay"):
            self.stats, self.last_data = None, None
            return
        self.stats = stats
        if len(getattr(bundle, "time", ())):
            self.last_data = time.monotonic()

    def words(self) -> list[str]:
        if self.stats is None:
            return []
        words = health_words(self.stats.get("devices") or {})
        if self.last_data is not None and time.monotonic() - self.last_data > 0.15 and not any("stalled" in w for w in words):
            words.append(f"stalled ({(time.monotonic() - self.last_data) * 1e3:.0f} ms without data)")
        return words

    def refresh(self) -> None:
        words = self.words()
        stalled = any("stalled" in w for w in words)
        if stalled and not self._stalled:
            self.stalls += 1
        self._stalled = stalled
        if self.stats is None:
            text, style = "devices: –", ""
        elif words:
            text, style = "devices: " + "; ".join(words) + f"  (stalls: {self.stalls})", "color: #d55e00; font-weight: bold;"
        else:
            text, style = f"devices ok (stalls: {self.stalls})", ""
        if text != self.text():  # 20 times a second: touch the widget (a relayout, a repolish) only on a change
            self.setText(text)
        if style != self.styleSheet():
            self.setStyleSheet(style)


def install_health_indicator(window) -> HealthIndicator:
    """Add the indicator to ``window``'s status bar, fed by ``window.feed.bundle``."""
    ind = HealthIndicator(window)
    window.statusBar().addPermanentWidget(ind)
    window.feed.bundle.connect(ind.on_bundle)
    window.health = ind
    return ind

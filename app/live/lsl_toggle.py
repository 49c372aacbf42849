"""The live view's "LSL" toggle: publish ``pito-wrenches`` and ``pito-contacts`` while it is on.

The toggle creates a :class:`pito_core.interop.LslPublisher` on the live feed (the
calibration and object shown; the feed's pipeline then solves the contacts of each sample on
that object, ``LiveBundle.arrived_contacts``, the publisher solves none) and pushes every
bundle the feed sends to the GUI (bundles are merged, never dropped, so every sample is
published once). The label next to it names the streams.
Without the ``interop`` extra (pylsl) the toggle is disabled with the reason as its tooltip.
LSL discovery multicasts on the network unless ``LSLAPICFG`` names a machine-only config
(docs/interop.md).
"""

from __future__ import annotations

import importlib.util

from PySide6.QtWidgets import QHBoxLayout, QLabel, QPushButton, QWidget

from pito_core.interop import (
    CONTACT_CHANNEL_COUNT,
    CONTACT_STREAM,
    CONTACT_TYPE,
    WRENCH_CHANNELS,
    WRENCH_STREAM,
    WRENCH_TYPE,
    LslPublisher,
)

__all__ = ["LslToggle", "install_lsl_toggle"]


class LslToggle(QWidget):
    """A checkable "LSL" button and a label with the stream names.

    Parameters
    ----------
    feed : app.live.feed.LiveFeed
        Its ``calibration`` and ``assembly`` describe the streams, ``set_sample_contacts`` asks its
        pipeline for every sample's contacts; its ``bundle``
        signal delivers the samples.
    publisher_factory : callable(feed) -> sink, optional
        Default :class:`pito_core.interop.LslPublisher`.
    """

    def __init__(self, feed, publisher_factory=None, simulated: bool = False, parent=None):
        super().__init__(parent)
        self.feed = feed
        self.simulated = simulated
        self.publisher = None
        self.button = QPushButton("LSL")
        self.button.setCheckable(True)
        self.button.setToolTip(f"Publish the face wrenches ({WRENCH_STREAM}, {WRENCH_TYPE}, {6 * len(WRENCH_CHANNELS)} ch) "
                               f"and contacts ({CONTACT_STREAM}, {CONTACT_TYPE}, {CONTACT_CHANNEL_COUNT} ch) as Lab "
                               "Streaming Layer streams")
        self.label = QLabel("")
        lay = QHBoxLayout(self)
        lay.setContentsMargins(0, 0, 0, 0)
        lay.addWidget(self.button)
        lay.addWidget(self.label)
        if publisher_factory is None:
            if importlib.util.find_spec("pylsl") is not None:  # present, not loaded until publishing starts
                publisher_factory = lambda feed: LslPublisher(feed, simulated=self.simulated)  # noqa: E731
            else:
                self.button.setEnabled(False)
                self.button.setToolTip("LSL unavailable: pylsl is not installed (pip install -e '.[interop]')")
        self.factory = publisher_factory
        self.button.toggled.connect(self.set_publishing)
        feed.bundle.connect(self.on_bundle)

    def set_publishing(self, on: bool) -> None:
        """Start (a new publisher with the feed's calibration and object) or stop publishing."""
        if on:
            try:
                self.publisher = self.factory(self.feed)
            except (ValueError, RuntimeError) as exc:  # no calibration yet, liblsl failure
                self.publisher = None
                self.button.blockSignals(True)
                self.button.setChecked(False)
                self.button.blockSignals(False)
                self.label.setText(f"LSL off: {exc}")
                return
            names = getattr(self.publisher, "names", ("pito-wrenches", "pito-contacts"))
            self.label.setText("streaming " + ", ".join(names))
        else:
            pub, self.publisher = self.publisher, None
            if pub is not None and hasattr(pub, "close"):
                pub.close()
            self.label.setText("")

    def on_bundle(self, bundle) -> None:
        if self.publisher is not None:
            try:
                self.publisher(bundle)
            except Exception as exc:  # noqa: BLE001 - shown, publishing stops
                self.button.setChecked(False)
                self.label.setText(f"LSL stopped: {type(exc).__name__}: {exc}")


def install_lsl_toggle(view, feed, simulated: bool = False) -> LslToggle:
    """Put an :class:`LslToggle` into ``view``'s toolbar, after its Replay button."""
    toggle = LslToggle(feed, simulated=simulated, parent=view)
    for lay in view.findChildren(QHBoxLayout):
        i = lay.indexOf(view.replay)
        if i >= 0:
            lay.insertWidget(i + 1, toggle)
            break
    else:
        raise RuntimeError("live view: toolbar with the Replay button not found")
    view.lsl = toggle
    return toggle

"""The live view's "LSL" toggle: publish ``pito-wrenches`` and ``pito-contacts`` while it is on.

The toggle creates a :class:`pito_core.interop.LslPublisher` on the worker's pipeline (the
calibration and object shown) and pushes every bundle the worker emits (bundles are merged,
never dropped, so every sample is published once). The label next to it names the streams.
Without the ``interop`` extra (pylsl) the toggle is disabled with the reason as its tooltip.
LSL discovery multicasts on the network unless ``LSLAPICFG`` names a machine-only config
(docs/interop.md).
"""

from __future__ import annotations

import importlib.util

from PySide6.QtWidgets import QHBoxLayout, QLabel, QPushButton, QWidget

from pito_core.interop import LslPublisher

__all__ = ["LslToggle", "install_lsl_toggle"]


class LslToggle(QWidget):
    """A checkable "LSL" button and a label with the stream names.

    Parameters
    ----------
    worker : app.workers.DeviceWorker
        Its ``pipeline`` computes the wrenches; its ``bundle`` signal delivers them.
    publisher_factory : callable(pipeline) -> sink, optional
        Default :class:`pito_core.interop.LslPublisher`.
    """

    def __init__(self, worker, publisher_factory=None, simulated: bool = False, parent=None):
        super().__init__(parent)
        self.worker = worker
        self.simulated = simulated
        self.publisher = None
        self.button = QPushButton("LSL")
        self.button.setCheckable(True)
        self.button.setToolTip("Publish the face wrenches (pito-wrenches, Force, 36 ch) and contacts "
                               "(pito-contacts, Contact, 72 ch) as Lab Streaming Layer streams")
        self.label = QLabel("")
        lay = QHBoxLayout(self)
        lay.setContentsMargins(0, 0, 0, 0)
        lay.addWidget(self.button)
        lay.addWidget(self.label)
        if publisher_factory is None:
            if importlib.util.find_spec("pylsl") is not None:  # present, not loaded until publishing starts
                publisher_factory = lambda pipe: LslPublisher(pipe, simulated=self.simulated)  # noqa: E731
            else:
                self.button.setEnabled(False)
                self.button.setToolTip("LSL unavailable: pylsl is not installed (pip install -e '.[interop]')")
        self.factory = publisher_factory
        self.button.toggled.connect(self.set_publishing)
        worker.bundle.connect(self.on_bundle)

    def set_publishing(self, on: bool) -> None:
        """Start (a new publisher on the current pipeline) or stop publishing."""
        if on:
            try:
                self.publisher = self.factory(self.worker.pipeline)
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


def install_lsl_toggle(view, worker, simulated: bool = False) -> LslToggle:
    """Put an :class:`LslToggle` into ``view``'s toolbar, after its Replay button."""
    toggle = LslToggle(worker, simulated=simulated, parent=view)
    for lay in view.findChildren(QHBoxLayout):
        i = lay.indexOf(view.replay)
        if i >= 0:
            lay.insertWidget(i + 1, toggle)
            break
    else:
        raise RuntimeError("live view: toolbar with the Replay button not found")
    view.lsl = toggle
    return toggle

"""The calibration wizard: a list of steps, one page per step, Back/Next gated by each page."""

from __future__ import annotations

from PySide6.QtCore import Qt, Signal
from PySide6.QtWidgets import (
    QHBoxLayout, QLabel, QListWidget, QListWidgetItem, QPushButton, QStackedWidget, QVBoxLayout, QWidget,
)

from .devices_page import DevicesPage
from .load_page import LoadPage
from .method_page import MethodPage
from .model import WizardModel
from .mount_page import MountPage
from .results_page import ResultsPage
from .tare_page import TarePage

__all__ = ["CalibrationWizard", "PAGE_NAMES"]

PAGE_NAMES = ("method", "mount", "devices", "tare", "load", "results")


class CalibrationWizard(QWidget):
    """Six steps: method, mount, devices, tare, loading, results.

    Parameters
    ----------
    model : WizardModel
    """

    page_changed = Signal(str)

    def __init__(self, model: WizardModel, parent=None):
        super().__init__(parent)
        self.model = model
        self.pages = {
            "method": MethodPage(model),
            "mount": MountPage(model),
            "devices": DevicesPage(model),
            "tare": TarePage(model),
            "load": LoadPage(model),
            "results": ResultsPage(model),
        }
        self.steps = QListWidget()
        self.steps.setObjectName("steps")
        self.steps.setFixedWidth(180)
        self.steps.setFocusPolicy(Qt.FocusPolicy.NoFocus)
        for name, page in self.pages.items():
            self.steps.addItem(QListWidgetItem(page.title))
        self.stack = QStackedWidget()
        for page in self.pages.values():
            self.stack.addWidget(page)
            page.ready_changed.connect(self._update_buttons)
        self.back = QPushButton("◂ Back")
        self.next = QPushButton("Next ▸")
        self.next.setObjectName("primary")
        self.hint = QLabel()
        self.hint.setObjectName("hint")
        nav = QHBoxLayout()
        nav.addWidget(self.back)
        nav.addWidget(self.hint, 1)
        nav.addWidget(self.next)
        right = QVBoxLayout()
        right.addWidget(self.stack, 1)
        right.addLayout(nav)
        lay = QHBoxLayout(self)
        lay.setContentsMargins(6, 6, 6, 6)
        lay.addWidget(self.steps)
        lay.addLayout(right, 1)
        self.back.clicked.connect(self.backward)
        self.next.clicked.connect(self.forward)
        self.pages["results"].redo_requested = lambda face: self.go(PAGE_NAMES.index("load"))
        self.pages["mount"].skip_requested = lambda: self.go("results")
        self.index = 0
        self.go(0)

    @property
    def current(self):
        return self.pages[PAGE_NAMES[self.index]]

    @property
    def current_name(self) -> str:
        return PAGE_NAMES[self.index]

    def forward(self) -> None:
        """Next: the next page, or the next stage (validation pass, extra mount) after a loading page."""
        m = self.model
        if self.current_name == "load" and m.stage + 1 < len(m.stages):
            m.set_stage(m.stage + 1)
            self.go("load" if m.current.kind == "validation" else "mount")
        elif self.current_name == "mount" and m.stage > 0:
            self.go("tare")  # the devices are connected already
        else:
            self.go(self.index + 1)

    def backward(self) -> None:
        """Back: the previous page, or the previous stage's loading page."""
        m = self.model
        if (self.current_name == "load" and m.current.kind == "validation") or (
                self.current_name == "mount" and m.stage > 0):
            m.set_stage(m.stage - 1)
            self.go("load")
        elif self.current_name == "tare" and m.stage > 0:
            self.go("mount")
        else:
            self.go(self.index - 1)

    def _stage_text(self, page: str) -> str:
        """The stage a step list item runs now (a second line), or ""."""
        st = self.model.current
        if st.kind == "validation" and page == "load":
            return "\n     2nd mount\n     validation" if st.of == "completing" else "\n     validation"
        if st.kind == "completing" and page in ("mount", "tare", "load"):
            return "\n     2nd mount"
        return ""

    def go(self, index) -> None:
        """Show page ``index`` (int or name); forward moves need the current page ready."""
        if isinstance(index, str):
            index = PAGE_NAMES.index(index)
        index = max(0, min(len(PAGE_NAMES) - 1, index))
        if index != self.index:
            self.current.leave()
        self.index = index
        self.stack.setCurrentIndex(index)
        names = list(self.pages)
        for k in range(self.steps.count()):
            it = self.steps.item(k)
            page = self.pages[names[k]]
            it.setText(page.title + self._stage_text(names[k]))
            it.setSelected(k == index)
            f = it.font()
            f.setBold(k == index)
            it.setFont(f)
        self.steps.setCurrentRow(index)
        self.current.enter()
        self._update_buttons()
        self.page_changed.emit(self.current_name)

    def _update_buttons(self, *_) -> None:
        page = self.current
        self.back.setEnabled(self.index > 0)
        last = self.index == len(PAGE_NAMES) - 1
        self.next.setVisible(not last)
        self.next.setEnabled(page.is_ready() and not last)
        hints = {
            "method": "Choose a method, then Next.",
            "mount": "Confirm the mount to go on.",
            "devices": "Connect both devices; Next when data flows.",
            "tare": "Record a still tare to go on.",
            "load": "Next when every face is covered (✔)." + (
                " Then: " + ("the validation pass." if self.model.stage + 1 < len(self.model.stages)
                             and self.model.stages[self.model.stage + 1].kind == "validation"
                             else "the second mount.") if self.model.stage + 1 < len(self.model.stages) else ""),
            "results": "Accept, then save the calibration and export the report.",
        }
        self.hint.setText("" if page.is_ready() and not last else hints[self.current_name])

    def on_bundle(self, bundle) -> None:
        """Live data from the live feed, to the page on screen."""
        self.current.on_bundle(bundle)

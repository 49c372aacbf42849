"""A read-only Qt table model over a pandas DataFrame; rows of implausible phases are tinted."""

from __future__ import annotations

import numpy as np
from PySide6.QtCore import QAbstractTableModel, QModelIndex, Qt
from PySide6.QtGui import QBrush, QColor

__all__ = ["DataFrameModel"]

_IMPLAUSIBLE = QBrush(QColor("#f6c6c0"))


def _text(v) -> str:
    if isinstance(v, (float, np.floating)):
        return "—" if not np.isfinite(v) else f"{v:.4g}"
    if v is None or str(v) == "<NA>":
        return "—"
    return str(v)


class DataFrameModel(QAbstractTableModel):
    """Rows of ``frame`` (a DataFrame); a row whose ``plausible`` is False gets a red background."""

    def __init__(self, frame=None, parent=None):
        super().__init__(parent)
        self.frame = None
        self.set_frame(frame)

    def set_frame(self, frame) -> None:
        self.beginResetModel()
        self.frame = frame
        self._values = [] if frame is None else frame.to_numpy(object).tolist()
        self._bad = [] if frame is None or "plausible" not in frame else list(frame["plausible"].eq(False).fillna(False))
        self.endResetModel()

    def rowCount(self, parent=QModelIndex()) -> int:  # noqa: N802 (Qt)
        return 0 if parent.isValid() else len(self._values)

    def columnCount(self, parent=QModelIndex()) -> int:  # noqa: N802
        return 0 if parent.isValid() or self.frame is None else len(self.frame.columns)

    def data(self, index, role=Qt.ItemDataRole.DisplayRole):
        if not index.isValid():
            return None
        if role == Qt.ItemDataRole.DisplayRole:
            return _text(self._values[index.row()][index.column()])
        if role == Qt.ItemDataRole.BackgroundRole and self._bad[index.row()]:
            return _IMPLAUSIBLE
        if role == Qt.ItemDataRole.ToolTipRole and self._bad[index.row()]:
            return "not single contacts in this phase: read its metrics with care"
        return None

    def headerData(self, section, orientation, role=Qt.ItemDataRole.DisplayRole):  # noqa: N802
        if role != Qt.ItemDataRole.DisplayRole or self.frame is None:
            return None
        return str(self.frame.columns[section]) if orientation == Qt.Orientation.Horizontal else str(section + 1)

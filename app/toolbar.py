"""The main window's toolbar: the sketching tools, pose and undo actions, and Generate at the
right. On a window too narrow for its labels the longest ones shorten, so that Generate stays on
the bar instead of going into the overflow menu (at 1024 px it did)."""
from __future__ import annotations

from PySide6.QtCore import QEvent, QObject, Qt
from PySide6.QtGui import QAction
from PySide6.QtWidgets import QMainWindow, QSizePolicy, QWidget

STYLE = ("QToolBar { spacing: 2px; padding: 2px; }"
         "QToolBar QToolButton { padding: 4px 9px; }"
         "QToolBar QToolButton:checked { background: #2e86ab; color: white; border-radius: 3px; }"
         "QToolButton#generate { background: #3c8d5a; color: white; font-weight: bold;"
         " border-radius: 3px; padding: 4px 14px; }"
         "QToolButton#generate:hover { background: #347d4f; }"
         "QToolButton#generate:disabled { background: #b9c9bd; color: #f4f4f4; }")


class MainToolbar(QObject):
    """Builds the bar into `window` and keeps its labels fitting the window's width.
    groups: runs of actions, separated on the bar; generate: the actions at its right end;
    short: the label each action takes on a narrow window (its tooltip keeps the full name)."""

    def __init__(self, window: QMainWindow, groups: list[list[QAction]], generate: list[QAction],
                 short: dict[QAction, str]):
        super().__init__(window)
        self.bar = bar = window.addToolBar("Tools")
        bar.setObjectName("Tools")
        bar.setMovable(False)
        bar.setToolButtonStyle(Qt.ToolButtonTextOnly)
        for i, group in enumerate(groups):
            if i:
                bar.addSeparator()
            bar.addActions(group)
        spacer = QWidget()
        spacer.setSizePolicy(QSizePolicy.Expanding, QSizePolicy.Preferred)
        bar.addWidget(spacer)
        bar.addActions(generate)
        bar.widgetForAction(generate[0]).setObjectName("generate")  # the primary action stands out
        window.setStyleSheet(STYLE)
        self._window = window
        self._labels = {action: (action.iconText(), label) for action, label in short.items()}
        self._full_width = bar.sizeHint().width()
        self.compact = False
        window.installEventFilter(self)

    def eventFilter(self, watched: QObject, event: QEvent) -> bool:
        if event.type() == QEvent.Resize:
            compact = self._window.width() < self._full_width
            if compact != self.compact:
                self.compact = compact
                for action, (full, short) in self._labels.items():
                    action.setIconText(short if compact else full)
        return False

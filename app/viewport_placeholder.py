"""Stands in for the 3D viewport (app/viewport.py) until that module is in the build; it keeps
the viewport's API so the window wires the same way. Delete this file once viewport.py lands."""
from __future__ import annotations

from PySide6.QtCore import Qt, Signal
from PySide6.QtWidgets import QLabel


class ViewportPlaceholder(QLabel):
    frameChanged = Signal(int)

    def __init__(self, parent=None):
        super().__init__("3D view\n(renderer not in this build)", parent)
        self.setAlignment(Qt.AlignCenter)
        self.setStyleSheet("background: #2b2d31; color: #9a9ca3;")
        self.setMinimumSize(240, 180)

    def set_clip(self, clip) -> None:
        pass

    def set_preview(self, clip) -> None:
        pass

    def set_storyboard(self, storyboard) -> None:
        pass

    def set_frame(self, frame: int) -> None:
        pass

    def grab_png(self, path) -> None:
        self.grab().save(str(path))

"""Shortcuts that work whichever panel has focus, except while typing text.

Qt offers every key press to the focused widget first (a ShortcutOverride event): a spin box in
the Properties panel takes Ctrl+Z as its own undo and swallows the tool letters. This filter
lets the window's shortcuts win over fields that do not take free text; a key the window has no
shortcut for still reaches the field (digits, arrows, Backspace for a number).
"""
from __future__ import annotations

from PySide6.QtCore import QEvent, QObject, Qt
from PySide6.QtWidgets import QAbstractSpinBox, QApplication, QLineEdit, QPlainTextEdit, QTextEdit


def _typing_text(widget) -> bool:
    """Whether the focused widget takes free text (where letters and Ctrl+Z are its own)."""
    if isinstance(widget, (QTextEdit, QPlainTextEdit)):
        return not widget.isReadOnly()
    if isinstance(widget, QLineEdit):     # a spin box's editor is a QLineEdit for a number
        return not widget.isReadOnly() and not isinstance(widget.parent(), QAbstractSpinBox)
    return False


def _window_key(event) -> bool:
    """Keys a number field has no use for: letters, and anything with Ctrl."""
    return bool(event.modifiers() & Qt.ControlModifier) or Qt.Key_A <= event.key() <= Qt.Key_Z


class WindowShortcutsFirst(QObject):
    """Installed on the application; `window` is the main window whose shortcuts should win."""

    def __init__(self, window):
        super().__init__(window)
        self._window = window
        QApplication.instance().installEventFilter(self)

    def eventFilter(self, watched, event) -> bool:
        if event.type() == QEvent.ShortcutOverride and _window_key(event):
            focus = QApplication.focusWidget()
            if focus is watched and focus is not None and focus.window() is self._window and not _typing_text(focus):
                event.ignore()          # not the field's: the shortcut map gets the key
                return True
        return False

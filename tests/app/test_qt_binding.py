"""Guards against a broken Qt binding: PySide6 6.12.0 drops one reference to None on every call
that returns nothing, and on Python 3.11 the interpreter aborts once None's count runs out
(minutes of painting and playback). pyproject.toml pins it out; this keeps it out."""
import sys

from PySide6.QtWidgets import QWidget


def test_void_calls_keep_none_alive(qtbot):
    widget = QWidget()
    qtbot.addWidget(widget)
    before = sys.getrefcount(None)
    for _ in range(2000):
        widget.update()
    assert sys.getrefcount(None) - before > -100

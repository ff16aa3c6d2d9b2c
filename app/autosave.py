"""Autosave and crash recovery.

While the document is dirty, every `interval_ms` the storyboard is written (atomically) to a
recovery file in the user's data folder, beside a note of the file it came from. A clean save or
a deliberate close removes both, so a recovery file found at start means the last session ended
without either: a crash. Then the app offers to reopen it.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from PySide6.QtCore import QObject, QTimer

from engine.atomic import write_text
from engine.storyboard import Storyboard

from .document import Document

RECOVERY_FILE = "recovery.storyboard.json"
SOURCE_NOTE = "recovery.source.txt"


@dataclass
class Recovery:
    storyboard_path: Path
    source: Path | None      # the file the unsaved work belongs to, None for an untitled document

    def load(self) -> Storyboard:
        return Storyboard.load(self.storyboard_path)


def find_recovery(directory: Path) -> Recovery | None:
    path = Path(directory) / RECOVERY_FILE
    if not path.exists():
        return None
    note = Path(directory) / SOURCE_NOTE
    source = note.read_text(encoding="utf-8").strip() if note.exists() else ""
    return Recovery(path, Path(source) if source else None)


class Autosaver(QObject):
    def __init__(self, document: Document, directory: Path, interval_ms: int = 30_000,
                 parent: QObject | None = None):
        super().__init__(parent)
        self._doc = document
        self.directory = Path(directory)
        self._timer = QTimer(self)
        self._timer.timeout.connect(self.save_now)
        self._timer.start(interval_ms)
        document.dirtyChanged.connect(lambda dirty: None if dirty else self.clear())

    def save_now(self) -> None:
        """Write the recovery file if there is unsaved work; errors only skip this round."""
        if not self._doc.dirty:
            return
        try:
            self.directory.mkdir(parents=True, exist_ok=True)
            self._doc.storyboard.save(self.directory / RECOVERY_FILE)
            write_text(self.directory / SOURCE_NOTE, str(self._doc.path or ""))
        except OSError as e:
            print(f"autosave skipped: {e}")

    def clear(self) -> None:
        for name in (RECOVERY_FILE, SOURCE_NOTE):
            (self.directory / name).unlink(missing_ok=True)

    def stop(self) -> None:
        self._timer.stop()

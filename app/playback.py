"""Playback state: plays the document's playhead at the storyboard's fps, looping."""
from __future__ import annotations

from PySide6.QtCore import QObject, QTimer, Signal

from .document import Document


class Playback(QObject):
    playingChanged = Signal(bool)

    def __init__(self, document: Document, parent: QObject | None = None):
        super().__init__(parent)
        self._doc = document
        self._timer = QTimer(self)
        self._timer.timeout.connect(lambda: self.step(1))

    @property
    def playing(self) -> bool:
        return self._timer.isActive()

    def play(self) -> None:
        if not self.playing:
            self._timer.start(max(1, round(1000 / self._doc.storyboard.fps)))
            self.playingChanged.emit(True)

    def pause(self) -> None:
        if self.playing:
            self._timer.stop()
            self.playingChanged.emit(False)

    def toggle(self) -> None:
        self.pause() if self.playing else self.play()

    def step(self, frames: int) -> None:
        """Move the playhead by `frames`, wrapping around the clip."""
        n = self._doc.storyboard.length
        self._doc.set_frame((self._doc.frame + frames) % n)

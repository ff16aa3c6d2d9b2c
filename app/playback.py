"""Playback state: the one clock that moves the document's playhead (napari style: a model with
change signals; the timeline header, the menus and the 3D view only observe it or ask it).

The playhead position is computed from elapsed wall time x fps x speed, not by counting timer
ticks, so playback keeps real time when a tick comes late (slow painting, a busy machine): it
skips frames instead of slowing down. Each tick sets document.frame once; the views re-render
on their next paint.
"""
from __future__ import annotations

import math

from PySide6.QtCore import QElapsedTimer, QObject, Qt, QTimer, Signal

from .document import Document

SPEEDS = (0.25, 0.5, 1.0, 2.0, 4.0)   # the rates offered in the UI; set_speed clamps to their range
MIN_TICK_MS = 10                      # no point ticking faster than a display refreshes


def speed_label(speed: float) -> str:
    return f"{speed:g}\u00d7"


class Playback(QObject):
    playingChanged = Signal(bool)
    loopChanged = Signal(bool)
    speedChanged = Signal(float)

    def __init__(self, document: Document, parent: QObject | None = None):
        super().__init__(parent)
        self._doc = document
        self._loop = True
        self._speed = 1.0
        self._clock = QElapsedTimer()
        self._origin = 0.0     # playhead position (fractional frames) when the clock last started
        self._shown = 0        # the frame this clock last put on the playhead
        self._timer = QTimer(self)
        self._timer.setTimerType(Qt.PreciseTimer)
        self._timer.timeout.connect(self._tick)
        # A new fps or length changes the frames-per-second conversion: restart from here.
        document.storyboardChanged.connect(self._restart_clock)

    # ---- state -------------------------------------------------------------------------------
    @property
    def playing(self) -> bool:
        return self._timer.isActive()

    @property
    def loop(self) -> bool:
        return self._loop

    @property
    def speed(self) -> float:
        return self._speed

    def set_loop(self, loop: bool) -> None:
        if bool(loop) != self._loop:
            self._loop = bool(loop)
            self.loopChanged.emit(self._loop)

    def set_speed(self, speed: float) -> None:
        speed = min(max(float(speed), SPEEDS[0]), SPEEDS[-1])
        if speed != self._speed:
            self._restart_clock()   # the time played so far counts at the old rate
            self._speed = speed
            self._timer.setInterval(self._tick_ms())
            self.speedChanged.emit(speed)

    # ---- transport -----------------------------------------------------------------------------
    def play(self) -> None:
        if self.playing or self._doc.storyboard.length < 2:
            return
        if not self._loop and self._doc.frame >= self._doc.storyboard.length - 1:
            self._doc.set_frame(0)   # play at the end without looping starts over
        self._anchor(self._doc.frame)
        self._timer.start(self._tick_ms())
        self.playingChanged.emit(True)

    def pause(self) -> None:
        if self.playing:
            self._timer.stop()
            self.playingChanged.emit(False)

    def toggle(self) -> None:
        self.pause() if self.playing else self.play()

    def to_key(self, way: int) -> None:
        """The playhead to the nearest frame with a key after it (way 1) or before it (-1)."""
        keys = [f for f in self._doc.storyboard.keyframes() if (f - self._doc.frame) * way > 0]
        if keys:
            self._doc.set_frame(min(keys) if way > 0 else max(keys))

    def step(self, frames: int) -> None:
        """Move the playhead by `frames`: around the clip when looping, else up to its ends.
        While playing, playback goes on from the new frame."""
        n = self._doc.storyboard.length
        target = self._doc.frame + frames
        self._doc.set_frame(target % n if self._loop else target)

    # ---- clock ---------------------------------------------------------------------------------
    def _tick_ms(self) -> int:
        return max(MIN_TICK_MS, round(1000.0 / (self._doc.storyboard.fps * self._speed)))

    def _anchor(self, position: float) -> None:
        self._origin = position
        self._shown = self._doc.frame
        self._clock.start()

    def _position(self) -> float:
        """Where the playhead is now, in fractional frames (may run past the end)."""
        return self._origin + self._clock.elapsed() / 1000.0 * self._doc.storyboard.fps * self._speed

    def _restart_clock(self) -> None:
        if self.playing:
            n = self._doc.storyboard.length
            position = self._position()
            self._anchor(position % n if self._loop else min(position, n - 1))

    def _tick(self) -> None:
        if self._doc.frame != self._shown:   # someone scrubbed or stepped: go on from there
            self._anchor(self._doc.frame)
        n = self._doc.storyboard.length
        frame = math.floor(self._position())
        if self._loop:
            frame %= n
        elif frame >= n - 1:
            self._doc.set_frame(n - 1)
            self.pause()
            return
        self._shown = frame
        self._doc.set_frame(frame)

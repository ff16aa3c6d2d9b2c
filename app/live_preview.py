"""Motion that follows the pointer: while a joint or an object is dragged on the canvas, or a
figure moved or turned on the floor plan, previews of the dragged storyboard regenerate on the
preview student (engine.models.preview); on release the full generation follows.

Pointer moves arrive far faster than previews finish (~0.1 s each here), so they are coalesced:
the first move of a burst starts a zero timer and, when it fires (the moves already queued
handled), the newest dragged storyboard goes to the session, which lets a running preview finish
while the drag goes on and runs only the newest request after it (GenerationSession.preview).
The app runs them, as every generation, in a process of its own (app.engine_process), where the
window's drawing does not slow them.
"""
from __future__ import annotations

from collections.abc import Callable

from PySide6.QtCore import QObject, QSettings, QTimer

from engine.storyboard import Storyboard

from .generation import GenerationSettings
from .session import GenerationSession

ENABLED_KEY = "generation/live_preview"
# The moves handled before the timer fires become one preview. Held 15 ms, the last move's preview
# started up to 15 ms late (pointer stop to picture, scripts/preview_latency.py, alternated three
# times: median 157 / 190 / 147 ms -> 143 / 172 / 104 ms).
COALESCE_MS = 0


class LivePreview(QObject):
    def __init__(self, views, session: GenerationSession, settings: Callable[[], GenerationSettings],
                 generate: Callable[[], None], preferences: QSettings, parent: QObject | None = None):
        """views: the widgets whose `dragged(Storyboard)` and `dragEnded()` signals drive it."""
        super().__init__(parent)
        self._session, self._settings, self._generate, self._preferences = session, settings, generate, preferences
        self.enabled = str(preferences.value(ENABLED_KEY, "true")).lower() == "true"
        self._latest: Storyboard | None = None
        self._previewed = False            # this drag has asked for a preview: its release generates
        self._timer = QTimer(self)
        self._timer.setSingleShot(True)
        self._timer.setInterval(COALESCE_MS)
        self._timer.timeout.connect(self._send)
        for view in views:
            view.dragged.connect(self._on_dragged)
            view.dragEnded.connect(self._on_released)

    def set_enabled(self, on: bool) -> None:
        self.enabled = bool(on)
        self._preferences.setValue(ENABLED_KEY, "true" if on else "false")

    def _on_dragged(self, storyboard: Storyboard) -> None:
        if not self.enabled:
            return
        self._latest = storyboard
        if not self._timer.isActive():
            self._timer.start()

    def _send(self) -> None:
        if self._latest is not None:
            self._session.preview(self._latest, self._settings())
            self._latest, self._previewed = None, True

    def _on_released(self) -> None:
        self._timer.stop()
        self._latest = None
        if self._previewed:
            self._previewed = False
            self._generate()

"""One generation at a time, as a model the widgets observe (napari style: no widgets here).

The session owns what a generation is while it runs: the storyboard it was asked for (a copy:
edits during the run do not reach it), the settings, the newest streamed step and its preview,
and the runner thread. When it ends, the result goes into the document as a take
(`Document.add_take`; a preview's as motion shown, `Document.set_result`),
which keeps it; the session then says whether that result is outdated by edits since.

    session.start(settings) -> str | None    None when started, else why not (one line)
    session.preview(storyboard, settings)    a preview of a dragged copy of the storyboard
    session.cancel()
    session.running, session.latest (StepEvent | None), session.outdated (bool)
Signals: runningChanged(bool), stepped(StepEvent), finished(GenerationResult), failed(str),
cancelled(), outdatedChanged(bool).
"""
from __future__ import annotations

import copy
import time
from dataclasses import asdict, replace
from collections.abc import Callable

import numpy as np
from PySide6.QtCore import QObject, QTimer, Signal

from engine.sampling.events import GenerationResult, StepEvent
from engine.storyboard import Storyboard, StoryboardError
from engine.takes import Take

from .document import Document
from .generation import MACHINE_SETTINGS, GenerationSettings, StepStream
from .worker import GenerationRunner

# A preview request newer than the running preview waits for it while the drag goes on (cancelled
# at every request, a preview that takes 0.1-0.2 s never finished under a pointer moving every
# 16 or 50 ms); once requests stop (the pointer rests: no request for 2.5 times the recent gap
# between them, within SETTLE_MS: the window stalls 50 ms drawing a step), a running preview less
# than half done gives way to the newest.
SETTLE_MS = (80, 250)


class GenerationSession(QObject):
    runningChanged = Signal(bool)
    stepped = Signal(object)          # StepEvent: its preview is decoded already (on the worker)
    finished = Signal(object)         # GenerationResult, after the document holds it
    failed = Signal(str)
    cancelled = Signal()
    outdatedChanged = Signal(bool)

    def __init__(self, document: Document, generate: Callable[[Storyboard, GenerationSettings], StepStream],
                 parent: QObject | None = None):
        super().__init__(parent)
        self._doc = document
        self.generate = generate          # storyboard, settings -> a stream of steps (the sampler, or a fake)
        self._runner = GenerationRunner(self)
        self.storyboard: Storyboard | None = None     # what the running (or last) generation was asked for
        self.settings: GenerationSettings | None = None
        self.latest: StepEvent | None = None          # the newest streamed step while running
        self._pending: tuple[Storyboard, GenerationSettings] | None = None   # to run when the current ends
        self._outdated = False
        self._document_version = 0   # bumped when the document is replaced (new, open, recover) ...
        self._run_version = 0        # ... and what it was when the current run started: its result
                                     # belongs to the storyboard it was asked for, not to the next one
        self._started_at = 0.0
        self._preview_s = 0.15       # how long a preview takes here (the last finished one's time)
        self._settle = QTimer(self)
        self._settle.setSingleShot(True)
        self._last_request, self._request_gap = 0.0, 0.0   # s: of preview requests, while a drag goes on
        self._settle.timeout.connect(self._on_settled)
        self._runner.runningChanged.connect(self.runningChanged)
        self._runner.step.connect(self._on_step)
        self._runner.finished.connect(self._on_finished)
        self._runner.failed.connect(self._on_failed)
        self._runner.cancelled.connect(self._on_cancelled)
        document.storyboardChanged.connect(self._update_outdated)
        document.resultChanged.connect(self._update_outdated)
        document.replaced.connect(self._on_replaced)

    @property
    def running(self) -> bool:
        return self._runner.running

    @property
    def outdated(self) -> bool:
        return self._outdated

    @property
    def cancelling(self) -> bool:
        """The run was asked to stop and its end has not landed: a new request waits for it."""
        return self._runner.cancelling

    @property
    def busy(self) -> bool:
        """A full generation runs and has not been cancelled: a new one would have to wait."""
        return self.running and not self.settings.preview and not self.cancelling

    def start(self, settings: GenerationSettings) -> str | None:
        """Generate the document's storyboard as it is now; None when started (or queued behind
        a preview or a cancelled generation, which ends first), else why not."""
        if self.busy:
            return "A generation is running: wait for it, or press Esc to cancel it."
        storyboard = copy.deepcopy(self._doc.storyboard)
        problem = _why_not(storyboard)
        if problem is None:
            self._queue(storyboard, settings)
        return problem

    def preview(self, storyboard: Storyboard, settings: GenerationSettings) -> None:
        """A preview of `storyboard` (the document's, with a drag in progress applied). Of the
        requests that arrive while a preview runs only the newest runs, after it: the running one
        is shown first while the drag goes on, and cancelled once the pointer rests if it is less
        than half done (SETTLE_MS). A full generation running is cancelled: the drag changes what
        it was asked. A storyboard that cannot be generated is skipped (the release says why)."""
        if _why_not(storyboard) is None:
            self._queue(copy.deepcopy(storyboard), replace(settings, preview=True))

    def cancel(self) -> None:
        self._pending = None
        self._runner.cancel()

    def _queue(self, storyboard: Storyboard, settings: GenerationSettings) -> None:
        self._pending = (storyboard, settings)
        if settings.preview:
            now = time.monotonic()
            gap = now - self._last_request
            if gap < SETTLE_MS[1] / 1000:      # the same drag: how often its requests come
                self._request_gap = 0.7 * self._request_gap + 0.3 * gap
            self._last_request = now
        if not self.running:
            self._start_pending()
        elif settings.preview and self.settings.preview:   # restarted by every request: fires when they stop
            self._settle.start(int(np.clip(2500 * self._request_gap, *SETTLE_MS)))
        else:
            self._runner.cancel()           # its end starts the pending request

    def _on_settled(self) -> None:
        if (self.running and self.settings.preview and self._pending is not None
                and time.monotonic() - self._started_at < self._preview_s / 2):
            self._runner.cancel()

    def _start_pending(self) -> None:
        self._settle.stop()
        if self._pending is None:
            return
        (storyboard, settings), self._pending = self._pending, None
        self.storyboard, self.settings, self.latest = storyboard, settings, None
        self._started_at = time.monotonic()
        self._run_version = self._document_version
        generate = self.generate
        self._runner.start(lambda: generate(storyboard, settings), streams_steps=settings.streams_steps)

    def shutdown(self) -> None:
        """Cancel and join the thread (window close, tests)."""
        self._runner.shutdown()

    def _on_step(self, event: StepEvent) -> None:
        self.latest = event
        self.stepped.emit(event)

    def _on_replaced(self) -> None:
        """A new document: what runs or waits was asked for the old one."""
        self._document_version += 1
        self._pending = None
        if self.running:
            self._runner.cancel()

    def _on_finished(self, result: GenerationResult) -> None:
        clips = list(result.clips)
        self.latest = None
        if self._run_version != self._document_version:   # it ended before the cancel reached it
            self.cancelled.emit()
            self._start_pending()
            return
        storyboard, settings = self.storyboard, self.settings
        if settings.preview:
            self._preview_s = time.monotonic() - self._started_at
        # The request waiting starts before this result is shown: the views' drawing it took
        # 7-13 ms of the GUI before the newest preview could start (after the pointer stopped).
        self._start_pending()
        if settings.preview or not clips:
            self._doc.set_result(clips, clips[0].phase if clips else None, source=storyboard, preview=settings.preview)
        else:
            kept = {k: v for k, v in asdict(settings).items() if k not in MACHINE_SETTINGS}
            self._doc.add_take(Take(clips, settings.seed, kept, storyboard.to_json()))
        self.finished.emit(result)

    def _on_failed(self, message: str) -> None:
        self.latest = None
        self.failed.emit(message)
        self._start_pending()

    def _on_cancelled(self) -> None:
        self.latest = None
        if self._pending is None:       # cancelled by the person, not replaced by a newer request
            self.cancelled.emit()
        self._start_pending()

    def _update_outdated(self) -> None:
        outdated = self._doc.result_outdated
        if outdated != self._outdated:
            self._outdated = outdated
            self.outdatedChanged.emit(outdated)


def _why_not(storyboard: Storyboard) -> str | None:
    """Why a storyboard cannot be generated (one line), or None."""
    try:
        storyboard.validate()
    except StoryboardError as e:
        return f"The storyboard cannot be generated from: {e}"
    if not (storyboard.keyposes or storyboard.trajectories or storyboard.contacts or storyboard.object_keys):
        # The model would make up two people who walk into each other.
        return ("Nothing to generate from yet: place a keypose (K), draw a path (T) or add a contact (C) "
                "for the people to follow.")
    return None

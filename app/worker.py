"""Generation on a QThread, after napari's generator workers.

The worker drives a generator of StepEvents on its own thread. Steps reach the GUI through a
one-slot mailbox: the worker overwrites the latest event and signals only when the GUI has taken
the previous one, so a fast sampler never builds a backlog in the GUI's event queue (the GUI
simply skips to the newest step) and a slow one delivers every step. In the app the stream is
the generation process' (app.engine_process), which decodes the steps to show itself: those are
handed over as they come. Decoding a step's preview
costs about a third of the step itself, and drawing it takes the same two cores where OpenGL
runs in software (under Xvfb a generation took 2.8 s with every step drawn, 1.4-1.9 s with ten a
second, 1.0-1.2 s with none), so the worker hands over at most one step per `preview_interval_s`
(10 a second: a 1 s generation still looks live) and always the last. A live preview hands over
none (GenerationSettings.streams_steps).
Cancel sets a flag the worker checks between steps; it then closes the generator, which cancels
the sampler. A stream that can be told at once (the generation process') is told too.
"""
from __future__ import annotations

import threading
import time
import traceback
from collections.abc import Callable

from PySide6.QtCore import QObject, QThread, Signal, Slot

from engine.sampling.events import GenerationResult, StepEvent

from .generation import STEP_INTERVAL_S, StepStream


class GenerationWorker(QObject):
    stepReady = Signal()                 # take_latest() has an event
    finished = Signal(object)            # GenerationResult
    failed = Signal(str)                 # one-line message
    cancelled = Signal()

    def __init__(self, make_stream: Callable[[], StepStream], preview_interval_s: float | None = STEP_INTERVAL_S):
        """preview_interval_s: the least time between two steps handed over; None: no step is."""
        super().__init__()
        self._make_stream = make_stream
        self._preview_interval_s = preview_interval_s
        self._cancel = threading.Event()
        self._lock = threading.Lock()
        self._latest: StepEvent | None = None
        self._stream: StepStream | None = None

    def cancel(self) -> None:
        """Thread-safe; the worker stops before its next step, or sooner where the stream can be
        told at once (app.engine_process.RemoteStream: the child stops between the stages of its
        finishing, during which the worker waits inside next())."""
        self._cancel.set()
        tell = getattr(self._stream, "cancel", None)
        if tell is not None:
            tell()

    @property
    def cancel_requested(self) -> bool:
        return self._cancel.is_set()

    def take_latest(self) -> StepEvent | None:
        with self._lock:
            event, self._latest = self._latest, None
        return event

    def _post(self, event: StepEvent) -> None:
        with self._lock:
            waiting = self._latest is not None
            self._latest = event
        if not waiting:
            self.stepReady.emit()

    @Slot()
    def run(self) -> None:
        stream, handed_over = None, -float("inf")
        try:
            stream = self._stream = self._make_stream()
            while True:
                if self._cancel.is_set():
                    stream.close()
                    self.cancelled.emit()
                    return
                try:
                    event = next(stream)
                except StopIteration as stop:
                    result: GenerationResult = stop.value
                    self.finished.emit(result)
                    return
                if self._preview_interval_s is None or event.decode is None:   # none, or not this one
                    continue
                now = time.monotonic()
                # A step that comes decoded was chosen by the generation process: handed over as it comes.
                if event.decoded or now - handed_over >= self._preview_interval_s or event.step == event.num_steps - 1:
                    event.preview  # decoded (unless it came so) here, in the worker, not on the GUI thread
                    self._post(event)
                    handed_over = now
        except Exception as e:  # any sampler failure becomes a message; the document is untouched
            if stream is not None:
                stream.close()
            if self._cancel.is_set():     # the stream was told to stop, and did so
                self.cancelled.emit()
                return
            traceback.print_exc()
            self.failed.emit(f"{type(e).__name__}: {e}".splitlines()[0])


class GenerationRunner(QObject):
    """Owns the thread of the current generation: start, cancel, and a clean shutdown."""
    started = Signal()
    step = Signal(object)            # StepEvent, on the GUI thread, newest first-come
    finished = Signal(object)        # GenerationResult
    failed = Signal(str)
    cancelled = Signal()
    runningChanged = Signal(bool)

    def __init__(self, parent: QObject | None = None):
        super().__init__(parent)
        self._thread: QThread | None = None
        self._worker: GenerationWorker | None = None

    @property
    def running(self) -> bool:
        return self._worker is not None

    def start(self, make_stream: Callable[[], StepStream], streams_steps: bool = True) -> bool:
        """Run `make_stream()` to completion on a new thread, its steps handed over (`step`) if
        `streams_steps`. False when one is already running."""
        if self.running:
            return False
        self._thread = QThread()
        self._thread.setObjectName("generation")
        self._worker = GenerationWorker(make_stream, STEP_INTERVAL_S if streams_steps else None)
        self._worker.moveToThread(self._thread)
        self._thread.started.connect(self._worker.run)
        self._worker.stepReady.connect(self._on_step_ready)
        self._worker.finished.connect(self._on_finished)
        self._worker.failed.connect(self._on_failed)
        self._worker.cancelled.connect(self._on_cancelled)
        self._thread.start()
        self.runningChanged.emit(True)
        self.started.emit()
        return True

    def cancel(self) -> None:
        if self._worker is not None:
            self._worker.cancel()

    @property
    def cancelling(self) -> bool:
        """Running, and asked to stop: its end has not landed yet."""
        return self._worker is not None and self._worker.cancel_requested

    def shutdown(self, timeout_ms: int = 5000) -> None:
        """Cancel and join the thread (window close, tests)."""
        if self._worker is not None:
            self._worker.cancel()
        if self._thread is not None:
            self._thread.quit()
            self._thread.wait(timeout_ms)
        self._release()

    def _on_step_ready(self) -> None:
        event = self._worker.take_latest() if self._worker else None
        if event is not None:
            self.step.emit(event)

    def _current(self) -> bool:
        """Whether the signal being handled comes from the current worker (one from a worker
        already let go, e.g. by shutdown, may still be queued: it is ignored)."""
        return self._worker is not None and self.sender() is self._worker

    def _on_finished(self, result: GenerationResult) -> None:
        if not self._current():
            return
        self._on_step_ready()  # a last step may still sit in the mailbox
        self._end()
        self.finished.emit(result)

    def _on_failed(self, message: str) -> None:
        if not self._current():
            return
        self._end()
        self.failed.emit(message)

    def _on_cancelled(self) -> None:
        if not self._current():
            return
        self._end()
        self.cancelled.emit()

    def _end(self) -> None:
        self._thread.quit()
        self._thread.wait()
        self._release()

    def _release(self) -> None:
        if self._worker is not None:
            self._worker.deleteLater()
            self._thread.deleteLater()
            self._worker = self._thread = None
            self.runningChanged.emit(False)

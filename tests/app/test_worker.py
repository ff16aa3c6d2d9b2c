"""The generation thread's hand-over of steps to the GUI: at most one per STEP_INTERVAL_S (and
the last) of the steps it decodes itself; every step that comes decoded (the generation process
chose it), and none that cannot be decoded here. A cancel reaches a stream that can be told at once
while the worker waits on it."""
import threading

import numpy as np

from app.worker import GenerationRunner, GenerationWorker
from engine.sampling.events import GenerationResult, StepEvent

from .fakes import walking_clip


def stream(kinds):
    """Steps of the given kinds, as fast as they go: "here" (decodable on the worker), "decoded"
    (came decoded) or "elsewhere" (decode None)."""
    clip = walking_clip(20, 20.0)
    for step, kind in enumerate(kinds):
        event = StepEvent(step, len(kinds), 1.0 - step / len(kinds), np.zeros(0),
                          None if kind == "elsewhere" else (lambda: clip), np.zeros((20, 3)))
        if kind == "decoded":
            event.preview
        yield event
    return GenerationResult([clip], 0.0, 0.0, len(kinds))


def handed_over(qtbot, monkeypatch, kinds):
    """The steps the worker puts in the GUI's mailbox (which keeps the newest one the GUI has not
    taken yet)."""
    steps, post = [], GenerationWorker._post
    monkeypatch.setattr(GenerationWorker, "_post", lambda self, event: (steps.append(event.step), post(self, event)))
    runner = GenerationRunner()
    with qtbot.waitSignal(runner.finished, timeout=5000):
        runner.start(lambda: stream(kinds))
    runner.shutdown()
    return steps


def test_steps_decoded_here_are_thinned_to_the_first_and_the_last(qtbot, monkeypatch):
    assert handed_over(qtbot, monkeypatch, ["here"] * 6) == [0, 5]


def test_steps_that_come_decoded_are_all_handed_over_and_the_others_none(qtbot, monkeypatch):
    kinds = ["elsewhere", "decoded", "elsewhere", "decoded", "elsewhere", "decoded"]
    assert handed_over(qtbot, monkeypatch, kinds) == [1, 3, 5]


class WaitingStream:
    """A stream whose second step waits until it is told to cancel, then ends in an error (as
    app.engine_process.RemoteStream does when the child answers the cancel)."""

    def __init__(self):
        self.told = threading.Event()
        self._steps = iter(stream(["here"]))

    def __iter__(self):
        return self

    def __next__(self):
        if self._steps is not None:
            step, self._steps = next(self._steps), None
            return step
        assert self.told.wait(5), "never told"
        raise RuntimeError("the run was cancelled in the generation process")

    def close(self):
        pass

    def cancel(self):
        self.told.set()


def test_a_cancel_tells_a_stream_that_can_be_told_and_its_end_is_a_cancel(qtbot):
    runner, remote = GenerationRunner(), WaitingStream()
    with qtbot.waitSignal(runner.step, timeout=5000):
        runner.start(lambda: remote)
    with qtbot.waitSignal(runner.cancelled, timeout=5000):
        runner.cancel()                 # the worker is inside next(): only the stream can hear it now
    assert remote.told.is_set()
    runner.shutdown()

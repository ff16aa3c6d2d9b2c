"""The generation thread's hand-over of steps to the GUI: at most one per STEP_INTERVAL_S (and
the last) of the steps it decodes itself; every step that comes decoded (the generation process
chose it), and none that cannot be decoded here."""
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

"""The real sampler through the real worker and main window: a bundled example storyboard, a
small untrained bundle and a few steps. Every step reaches the phase strip and the 3D view in
order, the result lands in the document, cancel stops a run, and no thread outlives it.
Energy guidance is off to keep the steps short (it costs seconds a step on a loaded 2-core
machine); the sampler's own tests cover it."""
import gc
import time
from functools import lru_cache

import numpy as np
import pytest
import torch  # noqa: F401  as main() does: loaded before the window
from PySide6.QtCore import Qt, QThread

import app.generation
from app.examples import EXAMPLES_DIR
from app.generation import GenerationSettings, start_generation
from engine.models.bundle import untrained_bundle
from engine.render import RenderUnavailableError, shared_context


@lru_cache(maxsize=1)
def small_bundle():
    return untrained_bundle()


def paced_generation(storyboard, settings):
    """The real stream with a pause after each step: the worker's mailbox rightly skips a step the
    GUI has not taken yet, and this test wants to see every one (0.2 s was too short for the first
    step's first paint of the view on a busy host, or once torch was warm from earlier tests)."""
    stream = start_generation(storyboard, settings)
    try:
        while True:
            yield next(stream)
            time.sleep(0.6)
    except StopIteration as stop:
        return stop.value
    finally:
        stream.close()


@pytest.fixture
def real_window(make_window, monkeypatch):
    try:
        shared_context()
    except RenderUnavailableError as e:
        pytest.skip(str(e))
    monkeypatch.setattr(app.generation, "_bundle", small_bundle)
    window = make_window(generate=paced_generation)
    assert window.open_example(EXAMPLES_DIR / "box_handoff.json")
    window.viewport.warm_up()  # as after the first paint: the renderer exists, its shaders compile soon after
    return window


def running_qthreads(qapp) -> list:
    return [t for t in gc.get_objects()
            if issubclass(type(t), QThread) and t is not qapp.thread() and t.isRunning()]


def record_calls(monkeypatch, obj, name: str) -> list:
    """Record each argument `obj.name` is called with, and still call it."""
    calls, original = [], getattr(obj, name)
    monkeypatch.setattr(obj, name, lambda value: (calls.append(value), original(value))[1])
    return calls


def test_real_generation_streams_every_step_to_the_strip_and_the_view(qtbot, qapp, real_window, monkeypatch,
                                                                      dialogs):
    window = real_window
    sb = window.doc.storyboard
    window.doc.set_settings(GenerationSettings(steps=3, seed=1, use_energy=False))
    events = []
    window.session.stepped.connect(events.append)
    previews = record_calls(monkeypatch, window.viewport, "set_preview")
    phases = record_calls(monkeypatch, window.phase_strip, "set_phase")

    with qtbot.waitSignal(window.session.finished, timeout=60_000) as finished:
        window.generate()
    result = finished.args[0]

    assert [e.step for e in events] == [0, 1, 2] and all(e.num_steps == 3 for e in events)
    assert previews == [e.preview for e in events]            # the same objects, in step order
    assert phases[:3] == [e.phase for e in events] and phases[3] is window.doc.phase
    for e in events:
        assert e.preview.num_frames == sb.length and np.isfinite(e.preview.joints).all()
        assert e.phase.shape == (sb.length, 3)
    assert window.doc.clip is result.clips[0] and window.doc.phase is not None
    assert window.viewport.num_frames == sb.length
    assert window.progress.isHidden() and window.act_generate.isEnabled()
    assert dialogs.errors == []
    assert running_qthreads(qapp) == []


def test_cancel_mid_run_keeps_the_previous_result(qtbot, qapp, real_window, dialogs):
    window = real_window
    window.doc.set_settings(GenerationSettings(steps=40, use_energy=False))
    events = []
    window.session.stepped.connect(events.append)
    with qtbot.waitSignal(window.session.cancelled, timeout=60_000):
        window.generate()
        qtbot.waitUntil(lambda: len(events) >= 1, timeout=30_000)
        qtbot.keyClick(window, Qt.Key_Escape)
    assert len(events) < 40
    assert window.doc.clip is None and window.viewport.num_frames == 0  # as before the run
    assert window.act_generate.isEnabled() and not window.act_cancel.isEnabled()
    assert dialogs.errors == []
    assert running_qthreads(qapp) == []

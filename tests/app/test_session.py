"""The generation session as a model: it starts from a copy of the storyboard, refuses what it
cannot run in one line, streams steps, hands the result to the document, and says when edits
have made that result outdated."""
import copy
from dataclasses import replace

from app import commands as cmd
from app.document import Document
from app.generation import GenerationSettings
from app.session import GenerationSession

from .fakes import FakeSampler, sample_storyboard


def make_session(sampler=None):
    doc = Document(sample_storyboard())
    session = GenerationSession(doc, sampler or FakeSampler(delay_s=0.01))
    return doc, session


def test_a_generation_streams_and_its_result_goes_to_the_document(qtbot):
    doc, session = make_session()
    steps, running = [], []
    session.stepped.connect(steps.append)
    session.runningChanged.connect(running.append)
    with qtbot.waitSignal(session.finished, timeout=10_000):
        assert session.start(GenerationSettings(steps=4)) is None
        assert session.running and session.start(GenerationSettings()) is not None   # one at a time
    # At most 10 a second, newest first-come (a step the GUI thread has not taken yet gives way to
    # the next: under load step 0 can be), the last always.
    assert [e.step for e in steps] == sorted({e.step for e in steps}) and steps[-1].step == 3
    assert running == [True, False]
    assert doc.clip is not None and session.latest is None and not session.outdated


def test_a_preview_hands_over_no_steps_and_the_request_behind_it_starts_before_it_is_shown(qtbot):
    """A drag's preview is done in a tenth of a second: its steps are neither decoded nor drawn
    (they took the cores from it), and the newer request waiting for it is running by the time
    the views draw its result."""
    doc, session = make_session()
    steps, running_when_shown = [], []
    session.stepped.connect(steps.append)
    doc.resultChanged.connect(lambda: running_when_shown.append((doc.result_is_preview, session.running)))
    moved = copy.deepcopy(doc.storyboard)
    moved.keyposes[0].points[0] += 0.1
    with qtbot.waitSignal(session.finished, timeout=10_000):
        session.preview(doc.storyboard, GenerationSettings(steps=3))
        session.preview(moved, GenerationSettings(steps=3))    # waits for the first
    assert steps == [] and running_when_shown == [(True, True)]
    qtbot.waitUntil(lambda: not session.running, timeout=10_000)
    assert steps == [] and running_when_shown[-1] == (True, False)
    assert session.storyboard.to_json() == moved.to_json() and doc.clip is not None


def test_edits_during_a_run_do_not_reach_it_and_make_its_result_outdated(qtbot):
    sampler = FakeSampler(delay_s=0.05)
    doc, session = make_session(sampler)
    flags = []
    session.outdatedChanged.connect(flags.append)
    with qtbot.waitSignal(session.finished, timeout=10_000):
        session.start(GenerationSettings(steps=4))
        qtbot.waitUntil(lambda: len(sampler.yielded) >= 1, timeout=5000)
        doc.undo_stack.push(cmd.SetTiming(doc, 30.0))
    assert session.storyboard.fps == 20.0 and doc.storyboard.fps == 30.0
    assert session.outdated and flags == [True]
    doc.undo_stack.undo()
    assert not session.outdated and flags == [True, False]


def test_a_storyboard_that_cannot_be_generated_is_refused_in_one_line(qtbot):
    doc, session = make_session()
    bad = doc.storyboard.keyposes[0]
    doc.storyboard.keyposes.append(replace(bad, agent="nobody"))
    problem = session.start(GenerationSettings())
    assert problem and "\n" not in problem and "nobody" in problem and not session.running


def test_cancel_and_failure_leave_the_documents_result(qtbot):
    doc, session = make_session(FakeSampler(delay_s=0.05))
    with qtbot.waitSignal(session.cancelled, timeout=10_000):
        session.start(GenerationSettings(steps=50))
        session.cancel()
    session.generate = FakeSampler(fail_at=1)
    with qtbot.waitSignal(session.failed, timeout=10_000) as failed:
        session.start(GenerationSettings(steps=3))
    assert "patience" in failed.args[0] and doc.clip is None and not session.running


def test_an_empty_storyboard_says_what_is_missing(qtbot):
    doc = Document()
    session = GenerationSession(doc, FakeSampler())
    problem = session.start(GenerationSettings())
    assert problem and "keypose" in problem and "path" in problem and not session.running


def test_a_run_for_a_document_that_was_replaced_leaves_the_new_one_alone(qtbot):
    """New or Open while a generation runs: its motion never lands in the next document, whether
    the cancel reaches it between steps or it ends first."""
    for cancel_arrives in (True, False):
        sampler = FakeSampler(delay_s=0.05)
        doc, session = make_session(sampler)
        if not cancel_arrives:
            session._runner.cancel = lambda: None
        with qtbot.waitSignal(session.runningChanged, timeout=10_000, check_params_cb=lambda running: not running):
            session.start(GenerationSettings(steps=6))
            qtbot.waitUntil(lambda: len(sampler.yielded) >= 1, timeout=5000)
            doc.replace_storyboard(sample_storyboard(), None)
        assert doc.takes == [] and doc.clips == [] and doc.clip is None
        with qtbot.waitSignal(session.finished, timeout=10_000):   # and the next one runs as usual
            assert session.start(GenerationSettings(steps=2)) is None
        assert len(doc.takes) == 1

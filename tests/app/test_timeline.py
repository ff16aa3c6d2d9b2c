"""Timeline and phase strip: scrub, retime by dragging a marker, add and span with the mouse."""
from dataclasses import replace

import numpy as np
import pytest
from PySide6.QtCore import QPoint, Qt

from app import commands as cmd
from app.document import Document
from app.phase_strip import MAX_POINTS, PhaseStrip
from app.timeline import RULER_H, ROW_H, Timeline, frame_to_x, ruler_steps

from .fakes import phase_schedule, sample_storyboard


@pytest.fixture
def doc():
    return Document(sample_storyboard())


@pytest.fixture
def timeline(qtbot, doc):
    widget = Timeline(doc)
    widget.resize(900, 120)
    qtbot.addWidget(widget)
    widget.show()
    return widget


def at(timeline, frame, row=None) -> QPoint:
    y = RULER_H // 2 if row is None else RULER_H + row * ROW_H + ROW_H // 2
    return QPoint(round(frame_to_x(frame, timeline._doc.storyboard.length, timeline.width())), y)


def test_scrub_and_span(qtbot, timeline, doc):
    qtbot.mouseClick(timeline, Qt.LeftButton, pos=at(timeline, 42))
    assert doc.frame == 42
    qtbot.mousePress(timeline, Qt.LeftButton, Qt.ShiftModifier, at(timeline, 20))
    qtbot.mouseMove(timeline, at(timeline, 35))
    qtbot.mouseRelease(timeline, Qt.LeftButton, Qt.ShiftModifier, at(timeline, 35))
    assert doc.span == (20, 35)


def test_drag_a_marker_to_retime_then_undo(qtbot, timeline, doc):
    qtbot.mousePress(timeline, Qt.LeftButton, pos=at(timeline, 60, row=1))
    qtbot.mouseMove(timeline, at(timeline, 70, row=1))
    qtbot.mouseRelease(timeline, Qt.LeftButton, pos=at(timeline, 75, row=1))
    assert cmd.find_keypose(doc.storyboard, "B", 75) is not None
    assert cmd.find_keypose(doc.storyboard, "B", 60) is None
    assert cmd.find_keypose(doc.storyboard, "A", 60) is not None   # other tracks stay
    doc.undo_stack.undo()
    assert cmd.find_keypose(doc.storyboard, "B", 60) is not None


def test_a_marker_stops_at_its_neighbours_and_replaces_none(qtbot, timeline, doc):
    before = sorted(k.frame for k in doc.storyboard.keyposes if k.agent == "B")
    assert before == [0, 60, 119]
    qtbot.mousePress(timeline, Qt.LeftButton, pos=at(timeline, 60, row=1))
    qtbot.mouseMove(timeline, at(timeline, 100, row=1))
    qtbot.mouseRelease(timeline, Qt.LeftButton, pos=QPoint(timeline.width() + 50, at(timeline, 0, row=1).y()))
    assert sorted(k.frame for k in doc.storyboard.keyposes if k.agent == "B") == [0, 118, 119]   # past the end
    qtbot.mousePress(timeline, Qt.LeftButton, pos=at(timeline, 118, row=1))
    qtbot.mouseRelease(timeline, Qt.LeftButton, pos=at(timeline, 0, row=1))
    assert sorted(k.frame for k in doc.storyboard.keyposes if k.agent == "B") == [0, 1, 119]
    cmd.find_keypose(doc.storyboard, "B", 0).hold = 25            # B holds its first pose to frame 25
    qtbot.mousePress(timeline, Qt.LeftButton, pos=at(timeline, 1, row=1))
    qtbot.mouseMove(timeline, at(timeline, 10, row=1))
    qtbot.mouseRelease(timeline, Qt.LeftButton, pos=at(timeline, 10, row=1))
    assert sorted(k.frame for k in doc.storyboard.keyposes if k.agent == "B") == [0, 26, 119]   # not inside the hold


def test_double_click_adds_the_previous_keypose_where_the_pelvis_stroke_takes_it(qtbot, timeline, doc):
    from engine.geometry.polylines import resample_polyline
    qtbot.mouseDClick(timeline, Qt.LeftButton, pos=at(timeline, 30, row=0))
    added = cmd.find_keypose(doc.storyboard, "A", 30)
    assert added is not None
    stroke = next(t for t in doc.storyboard.trajectories if t.agent == "A" and t.joint == "pelvis")
    along = resample_polyline(stroke.points, stroke.end - stroke.start + 1)
    walked = along[30 - stroke.start] - along[0]
    assert np.linalg.norm(walked) > 0.2
    assert added.points == pytest.approx(cmd.find_keypose(doc.storyboard, "A", 0).points + walked)


def test_phase_strip_shows_stacked_occupancy_and_scrubs(qtbot, doc):
    strip = PhaseStrip(doc)
    strip.resize(900, 100)
    qtbot.addWidget(strip)
    strip.show()
    phase = phase_schedule(doc.storyboard.length, 0.7)
    strip.set_phase(phase)
    tops = [c.getData()[1] for c in strip._curves]
    assert tops[1] == pytest.approx(phase[:, 0]) and tops[3] == pytest.approx(np.ones(len(phase)), abs=1e-6)
    qtbot.mouseClick(strip.viewport(), Qt.LeftButton, pos=QPoint(strip.width() // 2, 40))
    assert 40 < doc.frame < 80
    long = np.repeat(phase, 240, axis=0)                     # 28800 frames: a 2-minute clip at 240 fps
    strip.set_phase(long)
    x, top = strip._curves[1].getData()
    assert len(x) <= MAX_POINTS and x[0] == 0 and x[-1] == len(long) - 1
    assert top == pytest.approx(long[x.astype(int), 0])


def test_empty_phase_strip_shows_a_hint(qtbot, doc):
    strip = PhaseStrip(doc)
    qtbot.addWidget(strip)
    assert strip.empty_hint.isVisible() and "generating" in strip.empty_hint.toPlainText()
    strip.set_phase(phase_schedule(doc.storyboard.length, 0.7))
    assert not strip.empty_hint.isVisible()
    strip.set_phase(None)
    assert strip.empty_hint.isVisible()
    alone = replace(doc.storyboard, contacts=[], objects=[], object_keys=[], object_paths=[])
    doc.replace_storyboard(alone, None)       # two people walking: nothing is approached or carried
    strip.set_phase(phase_schedule(doc.storyboard.length, 0.7))
    assert strip.empty_hint.isVisible() and "no contacts" in strip.empty_hint.toPlainText()


def test_a_keys_hold_and_ease_are_set_in_properties_and_drawn_on_the_timeline(qtbot, make_window):
    """Real keys in the Hold field and clicks on the Ease boxes; undo restores; the timeline
    draws the hold as a bar in the agent's row."""
    window = make_window()
    window.doc.replace_storyboard(sample_storyboard(), None)
    doc, props = window.doc, window.properties
    doc.set_frame(30)                                    # no key of A here: nothing to time
    assert not props.hold.isEnabled()
    doc.set_frame(60)
    assert props.hold.isEnabled() and props.hold.maximum() == 58    # ends before A's key at 119
    props.hold.setFocus()
    qtbot.keyClick(props.hold, Qt.Key_A, Qt.ControlModifier)
    qtbot.keyClicks(props.hold, "12")
    qtbot.keyClick(props.hold, Qt.Key_Return)
    qtbot.mouseClick(props.ease_in, Qt.LeftButton, pos=QPoint(8, props.ease_in.height() // 2))
    key = cmd.find_keypose(doc.storyboard, "A", 60)
    assert (key.hold, key.ease_in, key.ease_out) == (12, True, False)
    again = type(doc.storyboard).from_json(doc.storyboard.to_json())
    assert cmd.find_keypose(again, "A", 60).hold == 12
    # The bar: the row's pixels between the key and the hold's end are the agent's colour.
    timeline = window.timeline
    image = timeline.grab().toImage()
    row = next(i for i, t in enumerate(timeline.tracks()) if t.owner == "A")
    y = RULER_H + row * ROW_H + ROW_H // 2
    x = round(frame_to_x(66, doc.storyboard.length, timeline.width()))
    assert image.pixelColor(x, y).name() != image.pixelColor(x, y - 6).name()
    doc.undo_stack.undo()
    doc.undo_stack.undo()
    key = cmd.find_keypose(doc.storyboard, "A", 60)
    assert (key.hold, key.ease_in) == (0, False) and props.hold.value() == 0


@pytest.mark.parametrize("length, width", [(120, 900), (60, 1200), (2400, 700), (28800, 900)])
def test_the_ruler_keeps_its_labels_apart_on_any_clip(length, width):
    tick, every = ruler_steps(length, width)
    assert every % tick == 0 and every * width / length >= 40 and tick * width / length >= 5
    if length == 120:
        assert (tick, every) == (5, 10)                                # a 6 s clip as it always was

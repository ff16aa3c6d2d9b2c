"""Timeline and phase strip: scrub, retime by dragging a marker, add and span with the mouse."""
import numpy as np
import pytest
from PySide6.QtCore import QPoint, Qt

from app import commands as cmd
from app.document import Document
from app.phase_strip import PhaseStrip
from app.timeline import RULER_H, ROW_H, Timeline, frame_to_x

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


def test_double_click_adds_a_copy_of_the_previous_keypose(qtbot, timeline, doc):
    qtbot.mouseDClick(timeline, Qt.LeftButton, pos=at(timeline, 30, row=0))
    added = cmd.find_keypose(doc.storyboard, "A", 30)
    assert added is not None
    assert added.points == pytest.approx(cmd.find_keypose(doc.storyboard, "A", 0).points)


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


def test_empty_phase_strip_shows_a_hint(qtbot, doc):
    strip = PhaseStrip(doc)
    qtbot.addWidget(strip)
    assert strip.empty_hint.isVisible() and "generating" in strip.empty_hint.toPlainText()
    strip.set_phase(phase_schedule(doc.storyboard.length, 0.7))
    assert not strip.empty_hint.isVisible()
    strip.set_phase(None)
    assert strip.empty_hint.isVisible()

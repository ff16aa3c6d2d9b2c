"""Playback: the one clock of the playhead, its header controls and menu, its keys anywhere in
the window, and the 3D view following the document's frame.

Timing checks are bounds the clock cannot break (a frame is never shown before its time), with
generous timeouts on the other side, so a busy machine does not fail them."""
import time

import pytest
from PySide6.QtCore import QElapsedTimer, Qt

from app.document import Document
from app.playback import SPEEDS, Playback
from app.timeline import PlaybackControls

from .fakes import walking_clip


@pytest.fixture
def doc():
    return Document()   # 120 frames at 20 fps


@pytest.fixture
def playback(doc):
    clock = Playback(doc)
    yield clock
    clock.pause()


def test_advances_by_elapsed_time_at_the_given_speed(qtbot, doc, playback):
    playback.set_speed(2.0)   # 40 frames a second
    watch = QElapsedTimer()
    watch.start()
    playback.play()
    assert playback.playing
    qtbot.waitUntil(lambda: doc.frame >= 30, timeout=10_000)
    frame, elapsed_s = doc.frame, watch.elapsed() / 1000
    assert frame <= elapsed_s * 20 * 2.0 + 1   # never ahead of real time
    playback.pause()
    assert not playback.playing

    playback.set_speed(0.25)   # 5 frames a second
    doc.set_frame(0)
    watch.restart()
    playback.play()
    qtbot.wait(400)
    assert doc.frame <= watch.elapsed() / 1000 * 20 * 0.25 + 1


def test_keeps_real_time_when_painting_is_slow_and_stops_at_the_end_without_loop(qtbot, doc, playback):
    # Every frame change blocks the event loop for 100 ms, like a slow paint. A clock that
    # counted ticks would need 119 x 100 ms = 12 s to reach the end; real time at 4x is 1.5 s.
    doc.frameChanged.connect(lambda _: time.sleep(0.1))
    playback.set_loop(False)
    playback.set_speed(4.0)
    watch = QElapsedTimer()
    watch.start()
    playback.play()
    qtbot.waitUntil(lambda: not playback.playing, timeout=8_000)
    assert doc.frame == doc.storyboard.length - 1
    assert watch.elapsed() >= 1000 * 119 / 80 - 50   # it did not get there early either
    playback.play()   # at the end without looping, play starts over
    assert playback.playing and doc.frame == 0


def test_loops_around_the_end(qtbot, doc, playback):
    playback.set_speed(4.0)
    doc.set_frame(110)
    playback.play()
    qtbot.waitUntil(lambda: doc.frame < 100, timeout=10_000)
    assert playback.playing


def test_scrubbing_while_playing_goes_on_from_there(qtbot, doc, playback):
    playback.play()
    qtbot.waitUntil(lambda: doc.frame >= 1, timeout=10_000)
    doc.set_frame(80)
    qtbot.waitUntil(lambda: doc.frame > 80, timeout=10_000)
    assert doc.frame < 100   # it went on from 80, not back to where the clock was


def test_step_wraps_with_loop_and_stops_at_the_ends_without(doc, playback):
    playback.step(-1)
    assert doc.frame == 119
    playback.step(1)
    assert doc.frame == 0
    playback.set_loop(False)
    playback.step(-1)
    assert doc.frame == 0
    doc.set_frame(119)
    playback.step(1)
    assert doc.frame == 119


def test_loop_and_speed_signal_once_and_speed_is_clamped(playback):
    loops, speeds = [], []
    playback.loopChanged.connect(loops.append)
    playback.speedChanged.connect(speeds.append)
    assert playback.loop and playback.speed == 1.0
    playback.set_loop(False)
    playback.set_loop(False)
    playback.set_speed(2.0)
    playback.set_speed(2.0)
    playback.set_speed(100.0)
    playback.set_speed(0.0)
    assert loops == [False] and speeds == [2.0, SPEEDS[-1], SPEEDS[0]]


def test_header_controls_change_and_follow_the_model(qtbot, doc, playback):
    controls = PlaybackControls(playback)
    qtbot.addWidget(controls)
    controls.show()
    assert controls.loop_button.isChecked() and controls.speed_box.currentData() == 1.0
    qtbot.mouseClick(controls.loop_button, Qt.LeftButton)
    assert not playback.loop
    controls.speed_box.setCurrentIndex(controls.speed_box.findData(0.5))
    assert playback.speed == 0.5
    playback.set_speed(4.0)
    playback.set_loop(True)
    assert controls.speed_box.currentText() == "4\u00d7" and controls.loop_button.isChecked()
    qtbot.mouseClick(controls.play_button, Qt.LeftButton)
    assert playback.playing and controls.play_button.text() == "Pause" and not controls.play_button.icon().isNull()


def test_menu_entries_change_and_follow_the_model(window):
    playback = window.playback
    window.act_loop.trigger()
    assert not playback.loop and not window.playback_controls.loop_button.isChecked()
    window.speed_actions[0.25].trigger()
    assert playback.speed == 0.25 and window.playback_controls.speed_box.currentData() == 0.25
    playback.set_speed(2.0)
    assert window.speed_actions[2.0].isChecked() and not window.speed_actions[0.25].isChecked()
    playback.set_loop(True)
    assert window.act_loop.isChecked()


@pytest.mark.parametrize("focus", ["canvas", "viewport"])
def test_space_and_arrows_work_with_focus_on(qtbot, window, focus):
    doc, widget = window.doc, getattr(window, focus)
    window.activateWindow()
    widget.setFocus()
    qtbot.keyClick(widget, Qt.Key_Right)
    qtbot.keyClick(widget, Qt.Key_Right)
    qtbot.keyClick(widget, Qt.Key_Left)
    assert doc.frame == 1
    qtbot.keyClick(widget, Qt.Key_Space)
    assert window.playback.playing
    qtbot.waitUntil(lambda: doc.frame > 2, timeout=10_000)
    qtbot.keyClick(widget, Qt.Key_Space)
    assert not window.playback.playing


def test_viewport_requests_reach_the_playback(window):
    window.viewport.stepRequested.emit(3)
    assert window.doc.frame == 3
    window.viewport.playToggleRequested.emit()
    assert window.playback.playing


def test_viewport_follows_the_document_frame(qtbot, window):
    doc = window.doc
    doc.set_result([walking_clip(doc.storyboard.length, doc.storyboard.fps)], None)
    doc.set_frame(30)
    assert window.viewport.frame == 30
    window.playback.set_speed(4.0)
    window.playback.play()
    qtbot.waitUntil(lambda: doc.frame > 40, timeout=10_000)
    window.playback.pause()
    assert window.viewport.frame == doc.frame

"""Live preview: a joint dragged with real mouse events regenerates previews of the dragged
storyboard (coalesced; a running one shown while the drag goes on, the newest after it), and the
release runs the full generation of the storyboard as it now is."""
import numpy as np
import pytest
from PySide6.QtCore import QEventLoop, QPoint, Qt, QTimer

from app import commands as cmd
from app.generation_actions import PREVIEW_NOTICE
from engine.skeleton import JOINT_INDEX

from .fakes import FakeSampler, sample_storyboard

WRIST = JOINT_INDEX["r_wrist"]


class Recording(FakeSampler):
    """A slow fake sampler that records what each run was asked for."""

    def __init__(self):
        super().__init__(delay_s=0.01)
        self.asked = []             # (settings, the dragged wrist's point) per run started

    def __call__(self, storyboard, settings):
        self.asked.append((settings, cmd.find_keypose(storyboard, "A", 60).points[WRIST].copy()))
        return super().__call__(storyboard, settings)


def px(canvas, uv) -> QPoint:
    x, y = canvas.to_px(uv)
    return QPoint(round(x), round(y))


def drag_wrist(qtbot, window, offsets, pause_ms=5) -> np.ndarray:
    """Press on A's right wrist at frame 60 and move through `offsets` (metres), then rest;
    the button stays down. -> where the pointer rests, in sketch metres."""
    canvas = window.canvas
    start = cmd.find_keypose(window.doc.storyboard, "A", 60).points[WRIST].copy()
    qtbot.mousePress(canvas, Qt.LeftButton, pos=px(canvas, start))
    for offset in offsets:
        qtbot.mouseMove(canvas, px(canvas, start + offset))
        qtbot.wait(pause_ms)
    qtbot.wait(200)                  # the pointer rests: the newest preview must arrive
    end = px(canvas, start + offsets[-1])
    return canvas.to_uv(np.array([end.x(), end.y()], float))


def test_dragging_a_joint_previews_it_and_the_release_generates(qtbot, make_window):
    sampler = Recording()
    window = make_window(generate=sampler)
    window.doc.replace_storyboard(sample_storyboard(), None)
    window.doc.set_frame(60)
    window.doc.set_tool("select")
    before = cmd.find_keypose(window.doc.storyboard, "A", 60).points[WRIST].copy()
    offsets = [np.array([0.01 * i, 0.004 * i]) for i in range(1, 31)]
    resting = drag_wrist(qtbot, window, offsets)
    previews = [point for settings, point in sampler.asked if settings.preview]
    assert 1 <= len(previews) < len(offsets)                           # coalesced
    qtbot.waitUntil(lambda: not window.session.running, timeout=5000)
    assert window.doc.clip is not None
    assert np.allclose(cmd.find_keypose(window.doc.storyboard, "A", 60).points[WRIST], before)   # not yet an edit
    assert window.viewport.notice == PREVIEW_NOTICE          # the drag's preview: ahead of the sketch, not behind it
    canvas = window.canvas
    qtbot.mouseRelease(canvas, Qt.LeftButton, pos=px(canvas, resting))
    qtbot.waitUntil(lambda: not sampler.asked[-1][0].preview and not window.session.running, timeout=5000)
    posed = cmd.find_keypose(window.doc.storyboard, "A", 60).points[WRIST]
    assert np.linalg.norm(posed - before) > 0.1                        # the release made the edit ...
    assert np.allclose(previews[-1], posed)                            # ... the newest preview showed it
    assert np.allclose(sampler.asked[-1][1], posed)                    # and the full run has it
    assert not window.session.outdated and window.viewport.notice == ""   # the full take is no preview


def rest(ms: int) -> None:
    """Let the event loop (and the generation thread) run for ms: QTest.qWait keeps Python's lock."""
    loop = QEventLoop()
    QTimer.singleShot(ms, loop.quit)
    loop.exec()


@pytest.mark.parametrize("every_ms", [16, 60])
def test_previews_finish_while_the_pointer_keeps_moving(qtbot, make_window, every_ms):
    """A preview takes ~0.14 s here and the pointer moves every 16 or 60 ms for a second: previews
    must still be shown during the drag (each new one cancelling the last, none ever was)."""
    sampler = Recording()
    sampler.delay_s = 0.015
    window = make_window(generate=sampler)
    window.doc.replace_storyboard(sample_storyboard(), None)
    window.doc.set_frame(60)
    window.doc.set_tool("select")
    shown = []
    window.session.finished.connect(lambda result: shown.append(window.doc.result_is_preview))
    canvas = window.canvas
    start = cmd.find_keypose(window.doc.storyboard, "A", 60).points[WRIST].copy()
    qtbot.mousePress(canvas, Qt.LeftButton, pos=px(canvas, start))
    moves = 1000 // every_ms
    for i in range(1, moves + 1):
        qtbot.mouseMove(canvas, px(canvas, start + (0.24, 0.12) * np.array(i / moves)))
        rest(every_ms)
    assert sum(shown) >= 3                                   # shown while the pointer moved
    rest(400)                                                # it rests: the newest is shown
    assert window.session.settings.preview and not window.session.running
    assert np.allclose(sampler.asked[-1][1], canvas.to_uv(np.array([px(canvas, start + (0.24, 0.12)).x(),
                                                                      px(canvas, start + (0.24, 0.12)).y()], float)))
    qtbot.mouseRelease(canvas, Qt.LeftButton, pos=px(canvas, start + (0.24, 0.12)))


def test_live_preview_can_be_switched_off(qtbot, make_window):
    sampler = Recording()
    window = make_window(generate=sampler)
    window.doc.replace_storyboard(sample_storyboard(), None)
    window.doc.set_frame(60)
    window.doc.set_tool("select")
    window.act_live.trigger()
    assert not window.live_preview.enabled
    drag_wrist(qtbot, window, [np.array([0.05, 0.0]), np.array([0.1, 0.0])])
    assert sampler.asked == []


def test_moving_a_figure_on_the_floor_plan_previews_it(qtbot, make_window):
    from app.floor_plan import standing_place
    sampler = Recording()
    window = make_window(generate=sampler)
    window.doc.replace_storyboard(sample_storyboard(), None)
    window.floor_plan_dock.raise_()
    plan = window.floor_plan
    qtbot.waitUntil(lambda: plan.isVisible() and plan.width() > 100)
    plan.fit()
    key = cmd.find_keypose(window.doc.storyboard, "A", 60)
    start = standing_place(window.doc.storyboard, key)

    def at(xz):
        x, y = plan.to_px(xz)
        return QPoint(round(x), round(y))

    qtbot.mousePress(plan, Qt.LeftButton, pos=at(start))
    for step in np.linspace(0.05, 0.6, 12):
        qtbot.mouseMove(plan, at(start + (step, 0.0)))
        qtbot.wait(5)
    qtbot.wait(200)
    assert any(settings.preview for settings, _ in sampler.asked)                # previewed while dragged
    qtbot.waitUntil(lambda: not window.session.running, timeout=5000)
    qtbot.mouseRelease(plan, Qt.LeftButton, pos=at(start + (0.6, 0.0)))
    qtbot.waitUntil(lambda: not sampler.asked[-1][0].preview and not window.session.running, timeout=5000)
    moved = cmd.find_keypose(window.doc.storyboard, "A", 60)
    assert np.linalg.norm(standing_place(window.doc.storyboard, moved) - start - (0.6, 0.0)) < 0.05
    assert np.allclose(sampler.asked[-1][1], moved.points[WRIST])                # the full run has the move
    # A second drag: its release's take replaces the first's (one take per posing session).
    takes = len(window.doc.takes)
    start = standing_place(window.doc.storyboard, moved)
    qtbot.mousePress(plan, Qt.LeftButton, pos=at(start))
    for step in np.linspace(0.05, 0.3, 6):
        qtbot.mouseMove(plan, at(start + (0.0, step)))
        qtbot.wait(5)
    qtbot.wait(200)
    qtbot.waitUntil(lambda: not window.session.running, timeout=5000)
    qtbot.mouseRelease(plan, Qt.LeftButton, pos=at(start + (0.0, 0.3)))
    qtbot.waitUntil(lambda: not sampler.asked[-1][0].preview and not window.session.running, timeout=5000)
    assert len(window.doc.takes) == takes and window.doc.takes[-1].settings["after_drag"]
    assert "after a drag" in window.properties.take.itemText(takes - 1)

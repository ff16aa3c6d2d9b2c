"""Sketching on the canvas with real mouse events."""
from dataclasses import replace

import numpy as np
import pytest
from PySide6.QtCore import QPoint, Qt

from app import commands as cmd
from app.canvas import SketchCanvas
from app.document import Document
from engine.skeleton import JOINT_INDEX

from .fakes import sample_storyboard, walking_clip


@pytest.fixture
def canvas(qtbot):
    widget = SketchCanvas(Document())
    widget.resize(800, 600)
    qtbot.addWidget(widget)
    widget.show()
    qtbot.waitExposed(widget)
    return widget


def px(canvas, uv) -> QPoint:
    x, y = canvas.to_px(uv)
    return QPoint(round(x), round(y))


def drag(qtbot, canvas, points_uv, button=Qt.LeftButton):
    qtbot.mousePress(canvas, button, pos=px(canvas, points_uv[0]))
    for uv in points_uv[1:]:
        qtbot.mouseMove(canvas, px(canvas, uv))
    qtbot.mouseRelease(canvas, button, pos=px(canvas, points_uv[-1]))


def test_pixels_and_metres_round_trip(canvas):
    uv = np.array([[0.3, -0.2], [1.0, 1.0]])
    assert canvas.to_uv(canvas.to_px(uv)) == pytest.approx(uv)


def test_draw_a_trajectory(qtbot, canvas):
    doc = canvas._doc
    doc.set_tool("trajectory")
    doc.select(agent="B", joint="r_wrist")
    stroke = np.stack([np.linspace(-0.8, 0.8, 40), 0.2 * np.sin(np.linspace(0, 3, 40))], -1)
    drag(qtbot, canvas, stroke)
    [t] = doc.storyboard.trajectories
    assert (t.agent, t.joint, t.start, t.end) == ("B", "r_wrist", 0, doc.storyboard.length - 1)
    assert t.points[0] == pytest.approx(stroke[0], abs=0.01)
    assert t.points[-1] == pytest.approx(stroke[-1], abs=0.01)
    doc.storyboard.validate()

    # A stroke that starts and ends on the path redraws just that part.
    bump = np.stack([np.linspace(-0.2, 0.2, 15), np.array([0.0] + [0.5] * 13 + [0.0])], -1)
    bump[:, 1] += np.interp(bump[:, 0], t.points[:, 0], t.points[:, 1])
    bump[1:-1, 1] = 0.6
    drag(qtbot, canvas, bump)
    [redrawn] = doc.storyboard.trajectories
    assert redrawn.points[:, 1].max() > 0.4
    assert redrawn.points[0] == pytest.approx(t.points[0]) and redrawn.points[-1] == pytest.approx(t.points[-1])

    doc.undo_stack.undo()
    assert doc.storyboard.trajectories[0].points == pytest.approx(t.points)
    doc.undo_stack.undo()
    assert doc.storyboard.trajectories == []
    doc.undo_stack.redo()
    assert doc.storyboard.trajectories[0].points == pytest.approx(t.points)


def test_a_persons_stroke_covers_their_keys_unless_frames_are_selected(qtbot, canvas):
    """Keys at frames 10 and 90: a pelvis stroke drawn with no frames selected runs from 10 to 90,
    not over the whole clip (after the last key it walked the person off along the view)."""
    doc = canvas._doc
    doc.set_tool("keypose")
    for frame, u in ((10, -0.6), (90, 0.6)):
        doc.set_frame(frame)
        qtbot.mouseClick(canvas, Qt.LeftButton, pos=px(canvas, (u, 0.0)))
    doc.set_tool("trajectory")
    doc.select(agent="A", joint="pelvis")
    drag(qtbot, canvas, np.stack([np.linspace(-0.6, 0.6, 20), np.full(20, 0.1)], -1))
    [t] = doc.storyboard.trajectories
    assert (t.start, t.end) == (10, 90)
    messages = []
    canvas.message.connect(messages.append)
    drag(qtbot, canvas, [np.array([0.0, 0.3]), np.array([0.02, 0.31]), np.array([0.03, 0.3])])   # a 5-pixel slip
    assert len(doc.storyboard.trajectories) == 1 and "too short" in messages[-1]
    doc.select(agent="B", joint="pelvis")                     # B has no keys: the whole clip
    drag(qtbot, canvas, np.stack([np.linspace(-0.6, 0.6, 20), np.full(20, -0.4)], -1))
    assert (doc.storyboard.trajectories[-1].start, doc.storyboard.trajectories[-1].end) == (0, doc.storyboard.length - 1)


def test_place_and_pose_a_keypose(qtbot, canvas):
    doc = canvas._doc
    doc.set_tool("keypose")
    doc.set_frame(30)
    qtbot.mouseClick(canvas, Qt.LeftButton, pos=px(canvas, (0.0, 0.0)))
    k = cmd.find_keypose(doc.storyboard, "A", 30)
    assert k is not None and k.mask.all()
    wrist = JOINT_INDEX["r_wrist"]
    start = k.points[wrist].copy()
    target = start + (0.15, 0.5)
    drag(qtbot, canvas, [start, start + (0.05, 0.2), target])
    moved = cmd.find_keypose(doc.storyboard, "A", 30).points[wrist]
    assert moved == pytest.approx(target, abs=1.5 / canvas.zoom)
    assert doc.selection.joint == "r_wrist"
    doc.undo_stack.undo()
    assert cmd.find_keypose(doc.storyboard, "A", 30).points[wrist] == pytest.approx(start)
    doc.undo_stack.redo()
    assert cmd.find_keypose(doc.storyboard, "A", 30).points[wrist] == pytest.approx(moved)



def test_a_frame_change_during_a_joint_drag_edits_the_key_the_drag_started_on(qtbot, canvas):
    """A key press that moves the timeline while a joint is held (PageDown to the next key) must
    not write the dragged pose onto the key it lands on."""
    doc = canvas._doc
    doc.set_tool("keypose")
    for frame, u in ((30, 0.0), (60, 0.4)):
        doc.set_frame(frame)
        qtbot.mouseClick(canvas, Qt.LeftButton, pos=px(canvas, (u, 0.0)))
    later = cmd.find_keypose(doc.storyboard, "A", 60).points.copy()
    doc.set_frame(30)
    wrist = JOINT_INDEX["r_wrist"]
    start = cmd.find_keypose(doc.storyboard, "A", 30).points[wrist].copy()
    qtbot.mousePress(canvas, Qt.LeftButton, pos=px(canvas, start))
    qtbot.mouseMove(canvas, px(canvas, start + (0.05, 0.2)))
    doc.set_frame(60)                                                    # as PageDown does
    qtbot.mouseMove(canvas, px(canvas, start + (0.1, 0.4)))
    qtbot.mouseRelease(canvas, Qt.LeftButton, pos=px(canvas, start + (0.1, 0.4)))
    assert cmd.find_keypose(doc.storyboard, "A", 60).points == pytest.approx(later)
    assert cmd.find_keypose(doc.storyboard, "A", 30).points[wrist] == pytest.approx(start + (0.1, 0.4), abs=2 / canvas.zoom)


def test_object_contact_and_erase_tools(qtbot, canvas):
    doc = canvas._doc
    doc.replace_storyboard(sample_storyboard(), None)
    doc.set_frame(90)
    doc.set_tool("object")
    drag(qtbot, canvas, [np.array([-1.5, -0.9]), np.array([-1.2, -0.6]), np.array([-1.0, -0.5])])
    key = doc.storyboard.object_keys[-1]
    assert key.frame == 90 and len(key.outline) == 4
    # Contact: A's right hand to the box's far grip on its right (+x) end: anchor 3.
    doc.set_tool("contact")
    hand = cmd.find_keypose(doc.storyboard, "A", 60).points[JOINT_INDEX["r_wrist"]]
    doc.set_frame(60)
    doc.set_span((60, 80))
    messages = []
    canvas.message.connect(messages.append)
    qtbot.mouseClick(canvas, Qt.LeftButton, pos=px(canvas, hand))
    box = doc.storyboard.object_keys[0].outline
    grips = canvas._anchors_2d("box1", box)
    assert len(grips) == 4 and np.all(grips[:2, 0] < box[:, 0].mean()) and np.all(grips[2:, 0] > box[:, 0].mean())
    qtbot.mouseClick(canvas, Qt.LeftButton, pos=px(canvas, grips[3]))
    c = doc.storyboard.contacts[-1]
    assert (c.agent, c.hand, c.object, c.anchor, c.start, c.end) == ("A", "right", "box1", 3, 60, 80)
    # Not a stale prompt; and A's right hand already holds the box over 60-119: said so.
    assert messages[-1] == ("Contact added: A right hand \u2192 box1 anchor 3   [60\u201380]"
                            " (this hand also holds on over frames 60-119)")
    assert np.allclose(canvas._contact_ends(c)[1], grips[3])                   # the line goes to that grip
    count = len(doc.storyboard.trajectories)
    doc.set_tool("erase")
    t = doc.storyboard.trajectories[0]
    qtbot.mouseClick(canvas, Qt.LeftButton, pos=px(canvas, t.points[len(t.points) // 3]))
    assert len(doc.storyboard.trajectories) == count - 1
    assert messages[-1] == "Erase trajectory (Ctrl+Z brings it back)"
    doc.set_frame(90)                      # inside the box drawn there: the box goes, whatever crosses it
    keys = len(doc.storyboard.object_keys)
    qtbot.mouseClick(canvas, Qt.LeftButton, pos=px(canvas, key.outline.mean(axis=0)))
    assert len(doc.storyboard.object_keys) == keys - 1 and len(doc.storyboard.trajectories) == count - 1
    assert messages[-1].startswith("Delete object key")
    doc.storyboard.validate()


def test_a_grip_another_hand_holds_then_makes_both_take_grips_of_their_own(qtbot, canvas):
    """At a hand-off an artist clicks the same grip for both people; two hands cannot hold one
    (finishing put the giver's hands on the taker's, 58 cm from where they were drawn), so the two
    take the grips that fit where their hands are drawn (engine.grips)."""
    doc = canvas._doc
    doc.replace_storyboard(sample_storyboard(), None)
    doc.set_frame(60)
    doc.set_span((60, 80))
    doc.set_tool("contact")
    messages = []
    canvas.message.connect(messages.append)
    box = doc.storyboard.object_keys[0].outline
    grips = canvas._anchors_2d("box1", box)
    held = len(doc.storyboard.contacts)
    for agent, side in (("A", "r_wrist"), ("B", "l_wrist")):
        qtbot.mouseClick(canvas, Qt.LeftButton, pos=px(canvas, cmd.find_keypose(doc.storyboard, agent, 60).points[JOINT_INDEX[side]]))
        qtbot.mouseClick(canvas, Qt.LeftButton, pos=px(canvas, grips[3]))
    a, b = doc.storyboard.contacts[held:]
    assert (a.agent, b.agent) == ("A", "B") and a.anchor != b.anchor
    assert messages[-1].endswith("(grips chosen again: one hand to a grip, the left hand on its left)"
                                 " (this hand also holds on over frames 60-119)")
    doc.undo_stack.undo()
    assert [c.anchor for c in doc.storyboard.contacts] == [c.anchor for c in doc.storyboard.contacts[:held]] + [3]


def test_a_contact_line_goes_to_the_generated_grip_between_object_keys(qtbot, canvas):
    doc = canvas._doc
    sb = sample_storyboard()
    doc.replace_storyboard(sb, None)
    c = next(c for c in sb.contacts if c.object)
    frame = next(k.frame for k in sb.keyposes if k.agent == c.agent and c.start <= k.frame <= c.end
                 and all(o.frame != k.frame for o in sb.object_keys))
    doc.set_frame(frame)
    stale = canvas._contact_ends(c)[1]                         # no motion yet: the latest key's grip
    clip = walking_clip(sb.length, sb.fps)
    anchors = np.zeros((sb.length, 1, 4, 3)) + (0.7, 1.0, -0.4)
    doc.set_result([replace(clip, obj_anchors=anchors)], None)
    grip = canvas._contact_ends(c)[1]
    assert np.allclose(grip, sb.camera.project(anchors[frame, 0, c.anchor]))
    assert np.linalg.norm(grip - stale) > 0.1
    # The contact tool takes that grip too (the stale key's, where nothing is drawn, it refused).
    anchors[:, 0, 1] = (0.3, 1.0, -0.4)                       # grip 1 apart from the others
    doc.set_result([replace(clip, obj_anchors=anchors)], None)
    doc.set_tool("contact")
    count = len(doc.storyboard.contacts)
    other = next(a for a in doc.storyboard.agents if a.id != c.agent).id
    hand = canvas._hand_position(other, "left")
    doc.set_span((frame, frame + 5))
    qtbot.mouseClick(canvas, Qt.LeftButton, pos=px(canvas, hand))
    qtbot.mouseClick(canvas, Qt.LeftButton, pos=px(canvas, sb.camera.project(anchors[frame, 0, 1])))
    assert len(doc.storyboard.contacts) == count + 1 and doc.storyboard.contacts[-1].object == "box1"


def test_what_was_in_view_stays_in_view_when_the_canvas_shrinks(qtbot, canvas):
    canvas._doc.replace_storyboard(sample_storyboard(), None)
    canvas.frame_sketch()
    corners = [canvas.to_uv(np.array(c, float)) for c in ((0, 0), (canvas.width(), canvas.height()))]
    canvas.resize(canvas.width() // 2, canvas.height() * 2 // 3)
    for uv in corners:                                      # the old view's corners are still inside
        x, y = canvas.to_px(uv)
        assert -1 <= x <= canvas.width() + 1 and -1 <= y <= canvas.height() + 1


def test_wheel_zoom_keeps_the_point_under_the_cursor(qtbot, canvas):
    from PySide6.QtCore import QPointF
    from PySide6.QtGui import QWheelEvent
    at = QPointF(200, 150)
    before = canvas.to_uv([200, 150])
    event = QWheelEvent(at, canvas.mapToGlobal(at), QPoint(), QPoint(0, 240), Qt.NoButton,
                        Qt.NoModifier, Qt.NoScrollPhase, False)
    canvas.wheelEvent(event)
    assert canvas.zoom > 170
    assert canvas.to_uv([200, 150]) == pytest.approx(before)


def test_sketching_far_out_stays_inside_what_a_storyboard_may_hold(qtbot, canvas, tmp_path):
    """Panning and drawing as far as the mouse goes still saves a storyboard that loads again."""
    from engine.storyboard import SKETCH_LIMIT_M, Storyboard
    canvas.zoom = 20.0                                        # the widest zoom
    for _ in range(40):                                       # middle-button drags, 700 px each
        qtbot.mousePress(canvas, Qt.MiddleButton, pos=QPoint(750, 300))
        qtbot.mouseMove(canvas, QPoint(50, 300))
        qtbot.mouseRelease(canvas, Qt.MiddleButton, pos=QPoint(50, 300))
    assert abs(canvas.pan[0]) <= SKETCH_LIMIT_M
    doc = canvas._doc
    doc.set_tool("trajectory")
    doc.select(agent="A", joint="pelvis")
    drag(qtbot, canvas, [canvas.to_uv([x, 300]) for x in range(100, 800, 20)])
    doc.set_tool("keypose")
    qtbot.mouseClick(canvas, Qt.LeftButton, pos=QPoint(790, 300))
    assert doc.storyboard.trajectories and doc.storyboard.keyposes
    doc.storyboard.save(tmp_path / "far.json")
    Storyboard.load(tmp_path / "far.json")


def test_labels_stay_inside_the_canvas(canvas):
    from PySide6.QtCore import QPointF, QRectF
    from app.canvas_paint import fit_inside
    bounds = QRectF(0, 0, 100, 50)
    assert fit_inside(QRectF(90, 45, 30, 10), bounds) == QRectF(70, 40, 30, 10)
    assert fit_inside(QRectF(-5, -8, 30, 10), bounds) == QRectF(0, 0, 30, 10)
    assert fit_inside(QRectF(10, 10, 30, 10), bounds) == QRectF(10, 10, 30, 10)
    # A path that starts at the bottom-right corner: its label is moved in, whole.
    label = "B r_wrist  0\u2013119"
    for baseline in (QPointF(canvas.width() - 4, canvas.height() + 10), QPointF(-30, 2)):
        rect = canvas.label_rect(baseline, label, canvas.font())
        assert QRectF(canvas.rect()).contains(rect) and rect.width() > 40


def test_a_path_of_other_frames_is_not_spliced_and_an_overlap_is_refused(qtbot, canvas):
    doc = canvas._doc
    doc.set_tool("trajectory")
    doc.select(agent="A", joint="pelvis")
    doc.set_span((0, 40))
    first = np.stack([np.linspace(-0.8, 0.0, 30), np.zeros(30)], -1)
    drag(qtbot, canvas, first)
    messages = []
    canvas.message.connect(messages.append)
    # Starts where the first ends, for frames 41-119: a path of its own, not a redraw of the first.
    doc.set_span((41, 119))
    drag(qtbot, canvas, np.stack([np.linspace(0.0, 0.8, 30), np.zeros(30)], -1))
    assert [(t.start, t.end) for t in doc.storyboard.trajectories] == [(0, 40), (41, 119)]
    assert doc.storyboard.trajectories[0].points[-1] == pytest.approx(first[-1], abs=0.01)
    # Frames 20-60 overlap both: refused, with a message, and nothing changes.
    doc.set_span((20, 60))
    drag(qtbot, canvas, np.stack([np.linspace(-0.5, 0.5, 30), np.full(30, 0.4)], -1))
    assert len(doc.storyboard.trajectories) == 2 and "already covers frames" in messages[-1]
    # Another joint over the same frames is fine.
    doc.select(agent="A", joint="r_wrist")
    drag(qtbot, canvas, np.stack([np.linspace(-0.5, 0.5, 30), np.full(30, 0.4)], -1))
    assert len(doc.storyboard.trajectories) == 3


def test_a_path_is_redrawn_from_a_stroke_started_on_it_after_the_clip_grew(qtbot, canvas):
    doc = canvas._doc
    doc.set_tool("trajectory")
    doc.select(agent="A", joint="pelvis")
    drag(qtbot, canvas, np.stack([np.linspace(-0.8, 0.8, 30), np.zeros(30)], -1))     # frames 0-119
    doc.undo_stack.push(cmd.SetTiming(doc, doc.storyboard.fps, 200))
    drag(qtbot, canvas, np.array([[-0.2, 0.0], [0.0, 0.3], [0.2, 0.0]]))               # starts and ends on it
    [path] = doc.storyboard.trajectories
    assert (path.start, path.end) == (0, 119) and path.points[:, 1].max() > 0.2


def test_the_contact_tool_takes_the_nearest_hand_of_any_person(qtbot, canvas):
    """At a hand-off A's and B's hands are both under the pointer: the click takes the nearer,
    whichever person it belongs to, and the second click the other person's."""
    doc = canvas._doc
    doc.replace_storyboard(sample_storyboard(), None)
    doc.set_frame(60)
    doc.set_span((60, 70))
    sb = doc.storyboard
    wrist = JOINT_INDEX["r_wrist"]
    a_hand = cmd.find_keypose(sb, "A", 60).points[wrist]
    b_pose = cmd.find_keypose(sb, "B", 60)
    b_pose.points[JOINT_INDEX["l_wrist"]] = a_hand + (0.06, 0.0)     # B's left hand 6 cm right of A's
    doc.set_tool("contact")
    qtbot.mouseClick(canvas, Qt.LeftButton, pos=px(canvas, a_hand + (0.05, 0.0)))   # nearer B's
    qtbot.mouseClick(canvas, Qt.LeftButton, pos=px(canvas, a_hand + (0.02, 0.0)))   # A's, B excluded
    c = doc.storyboard.contacts[-1]
    assert (c.agent, c.hand, c.other_agent, c.other_hand) == ("B", "left", "A", "right")


def test_inside_a_hold_the_held_pose_is_drawn(qtbot, canvas):
    doc = canvas._doc
    doc.replace_storyboard(sample_storyboard(), None)
    canvas.frame_sketch()
    doc.select(agent="B")                                   # A's neighbouring keys are not onion-skinned
    key = cmd.find_keypose(doc.storyboard, "A", 60)
    spots = [px(canvas, (key.points[JOINT_INDEX[a]] + key.points[JOINT_INDEX[b]]) / 2)
             for a, b in (("l_knee", "l_ankle"), ("r_knee", "r_ankle"), ("spine1", "spine2"))]

    def drawn(frame, hold):                                 # the colours at the middles of three bones
        doc.undo_stack.push(cmd.SetKeyTiming(doc, "A", 60, hold, False, False))
        doc.set_frame(frame)
        image = canvas.grab().toImage()
        return [image.pixelColor(p.x() + dx, p.y() + dy).name() for p in spots for dx in (-1, 0, 1) for dy in (-1, 0, 1)]

    assert drawn(66, 10) != drawn(66, 0)                    # held through frame 70: drawn at 66
    assert drawn(75, 10) == drawn(75, 0)                    # and not after the hold

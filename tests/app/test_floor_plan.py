"""The floor plan (app/floor_plan.py) by real mouse events: a figure dragged on the floor moves
its sketch as the camera sees it; a walk drawn on the floor is the pelvis path, kept in floor
coordinates, replaced when drawn again over the same frames, refused over other frames; its
arrow's tip dragged turns the figure where it stands."""
import numpy as np
import pytest
from PySide6.QtCore import QPoint, QPointF, QRectF, Qt
from PySide6.QtGui import QWheelEvent
from PySide6.QtWidgets import QApplication

from app import commands as cmd
from app.document import Document
from app.examples import EXAMPLES_DIR
from app.floor_plan import DISC_R, FloorPlan, standing_place
from engine.facing import depth_of, facing, lift
from engine.finishing.held import sketched_rest
from engine.poses import library_pose
from engine.storyboard import Storyboard, floor_path_points

from .fakes import sample_storyboard, walking_clip


@pytest.fixture
def plan(qtbot):
    doc = Document(sample_storyboard())
    widget = FloorPlan(doc)
    widget.resize(500, 400)
    qtbot.addWidget(widget)
    widget.show()
    qtbot.waitExposed(widget)
    widget.fit()
    return widget, doc


def px(widget, xz) -> QPoint:
    x, y = widget.to_px(np.asarray(xz, float))
    return QPoint(round(x), round(y))


def drag(qtbot, widget, points):
    qtbot.mousePress(widget, Qt.LeftButton, Qt.NoModifier, points[0])
    for p in points[1:]:
        qtbot.mouseMove(widget, p)
    qtbot.mouseRelease(widget, Qt.LeftButton, Qt.NoModifier, points[-1])


def test_dragging_a_figure_moves_where_it_stands(qtbot, plan):
    widget, doc = plan
    key = cmd.find_keypose(doc.storyboard, "B", 60)
    start = standing_place(doc.storyboard, key)
    target = start + (0.0, 1.0)                                  # a metre back along world z
    drag(qtbot, widget, [px(widget, start), px(widget, start + (0.0, 0.5)), px(widget, target)])
    moved = cmd.find_keypose(doc.storyboard, "B", 60)
    assert doc.selection.agent == "B" and doc.frame == 60
    assert np.linalg.norm(standing_place(doc.storyboard, moved) - target) < 2.5 / widget.zoom
    bones = lambda p: np.linalg.norm(np.diff(p, axis=0), axis=1)
    assert np.allclose(bones(moved.points), bones(key.points))  # the figure moves whole
    assert doc.undo_stack.undoText() == "Move on the floor plan"


def test_a_walk_drawn_on_the_floor_is_the_pelvis_path(qtbot, plan):
    widget, doc = plan
    doc.select(agent="A")
    index = next(i for i, t in enumerate(doc.storyboard.trajectories) if t.agent == "A" and t.joint == "pelvis")
    count = len(doc.storyboard.trajectories)
    walk = [np.array([x, 2.0 + 0.1 * np.sin(3 * x)]) for x in np.linspace(-1.5, 1.0, 15)]
    drag(qtbot, widget, [px(widget, p) for p in walk])        # no span: the whole clip, A's path replaced
    path = doc.storyboard.trajectories[index]
    assert len(doc.storyboard.trajectories) == count
    assert (path.agent, path.joint, path.start, path.end) == ("A", "pelvis", 0, 119) and path.floor is not None
    assert np.allclose(path.points, floor_path_points(doc.storyboard.camera, path.floor))
    assert np.linalg.norm(path.floor[0] - walk[0]) < 0.05 and np.linalg.norm(path.floor[-1] - walk[-1]) < 0.05
    assert doc.undo_stack.undoText() == "Redraw walk on the floor plan"
    messages = []
    widget.message.connect(messages.append)
    doc.set_span((40, 80))                                        # overlapping other frames: refused
    drag(qtbot, widget, [px(widget, p + (0.0, 1.0)) for p in walk])
    assert len(doc.storyboard.trajectories) == count and "already covers frames 0-119" in messages[0]
    doc.undo_stack.undo()
    assert doc.storyboard.trajectories[index].floor is None       # the sketched path is back
    doc.set_span(None)
    doc.set_tool("trajectory")                                    # the path tool: a walk from the figure
    key = cmd.find_keypose(doc.storyboard, "A", 0)
    start = standing_place(doc.storyboard, key)
    drag(qtbot, widget, [px(widget, start + (0.1 * i, 0.0)) for i in range(8)])
    assert np.allclose(standing_place(doc.storyboard, cmd.find_keypose(doc.storyboard, "A", 0)), start)
    assert np.linalg.norm(doc.storyboard.trajectories[index].floor[0] - start) < 0.05


def test_dragging_the_arrow_turns_the_figure_where_it_stands(qtbot, plan):
    widget, doc = plan
    key = cmd.find_keypose(doc.storyboard, "B", 60)
    sb = doc.storyboard
    doc.undo_stack.push(cmd.SetKeypose(doc, "B", 60, key.points, key.mask, depth=depth_of(library_pose("stand"), sb.camera)))
    key = cmd.find_keypose(sb, "B", 60)
    before = facing(lift(key.points, sb.camera, key.depth))
    place = standing_place(sb, key)
    tip = place + 0.45 * np.array([np.sin(before), np.cos(before)])
    quarter = before + np.pi / 2
    target = place + 0.45 * np.array([np.sin(quarter), np.cos(quarter)])
    middle = place + 0.45 * np.array([np.sin(before + 0.8), np.cos(before + 0.8)])
    drag(qtbot, widget, [px(widget, tip), px(widget, middle), px(widget, target)])
    turned_key = cmd.find_keypose(sb, "B", 60)
    after = facing(lift(turned_key.points, sb.camera, turned_key.depth))
    assert abs(np.angle(np.exp(1j * (after - quarter)))) < 0.06           # a quarter turn, to a pixel
    assert np.linalg.norm(standing_place(sb, turned_key) - place) < 0.01   # turned where it stands
    assert doc.undo_stack.undoText() == "Turn on the floor plan"
    again = type(sb).from_json(sb.to_json())
    assert np.allclose(cmd.find_keypose(again, "B", 60).depth, turned_key.depth)   # the turn is saved


def test_the_plan_keeps_everyone_in_view_until_the_wheel_zooms(qtbot, plan):
    widget, doc = plan

    def all_in_view():
        return all(widget.rect().contains(px(widget, standing_place(doc.storyboard, k))) for k in doc.storyboard.keyposes)

    widget.resize(220, 180)                      # a narrow dock
    qtbot.waitUntil(lambda: widget.width() == 220)
    assert all_in_view()
    centre = QPointF(110, 90)
    wheel = QWheelEvent(centre, widget.mapToGlobal(centre), QPoint(0, 0), QPoint(0, 1200), Qt.NoButton,
                        Qt.NoModifier, Qt.NoScrollPhase, False)
    zoom = widget.zoom
    QApplication.sendEvent(widget, wheel)
    assert widget.zoom > zoom
    widget.resize(400, 300)                      # the artist's zoom is kept
    qtbot.waitUntil(lambda: widget.width() == 400)
    assert widget.zoom > zoom


def test_a_figure_moved_off_the_sketch_view_is_brought_into_it(qtbot, make_window):
    window = make_window()
    window.doc.replace_storyboard(sample_storyboard(), None)
    window.floor_plan_dock.raise_()
    plan, canvas = window.floor_plan, window.canvas
    qtbot.waitUntil(lambda: plan.isVisible() and plan.width() > 100)
    plan.fit()
    key = cmd.find_keypose(window.doc.storyboard, "B", 119)
    start = standing_place(window.doc.storyboard, key)
    target = start + (3.0, 0.0)                                  # 3 m to the right: off the sketch view
    plan.zoom = 40.0
    drag(qtbot, plan, [px(plan, start), px(plan, start + (1.5, 0.0)), px(plan, target)])
    moved = cmd.find_keypose(window.doc.storyboard, "B", 119)
    inside = [canvas.rect().contains(QPoint(*np.round(canvas.to_px(p)).astype(int))) for p in moved.points]
    assert all(inside)



def tinted(widget, xz, radius: int = 1) -> bool:
    """Whether the plan shows wood near floor point xz (its paper and grid are grey-white)."""
    image, centre = widget.grab().toImage(), px(widget, xz)
    colors = [image.pixelColor(centre.x() + dx, centre.y() + dy)
              for dx in range(-radius, radius + 1) for dy in range(-radius, radius + 1)]
    return any(c.red() - c.blue() > 20 and c.blue() < 235 for c in colors)


def test_an_object_key_shows_its_footprint_and_the_generated_object_its_way(qtbot, plan):
    """A key at a frame nobody holds the box is a footprint on the floor; one in a hold is not
    drawn (the box is in the hands, its height unknown)."""
    widget, doc = plan
    held = doc.storyboard.object_keys[0]                 # box1 at frame 60, where its hold starts
    assert not tinted(widget, sketched_rest(doc.storyboard, 0, held.frame, held.frame)[[0, 2]], radius=0)
    doc.undo_stack.push(cmd.SetObjectKey(doc, "box1", 10, held.outline + (0.3, 0.0)))
    place = sketched_rest(doc.storyboard, 0, 10, 10)[[0, 2]]
    assert tinted(widget, place, radius=0)
    clip = walking_clip(doc.storyboard.length, doc.storyboard.fps)
    way = clip.obj_pose[len(clip.obj_pose) // 4, 0, [0, 2]]
    assert not tinted(widget, way)
    doc.set_result([clip], None)
    assert tinted(widget, way)


@pytest.mark.parametrize("name", ["box_handoff", "carry_table", "handshake", "let_go"])
def test_labels_cover_no_disc_and_no_other_label(qtbot, name):
    """People standing together at their keys (every bundled example, in a small dock): each
    label lies in the view, clear of every key's disc and of the other labels (they overprinted)."""
    doc = Document(Storyboard.load(EXAMPLES_DIR / f"{name}.json"))
    widget = FloorPlan(doc)
    widget.resize(440, 420)
    qtbot.addWidget(widget)
    widget.show()
    qtbot.waitExposed(widget)
    widget.fit()
    widget.grab()
    labels = widget.label_rects
    assert len(labels) >= 2
    discs = [np.asarray(widget.to_px(standing_place(doc.storyboard, k))) for k in doc.storyboard.keyposes]
    for i, rect in enumerate(labels):
        assert widget.rect().toRectF().contains(rect)
        assert not any(rect.intersects(other) for other in labels[i + 1:])
        for x, y in discs:   # the disc's square
            assert not rect.intersects(QRectF(x - DISC_R, y - DISC_R, 2 * DISC_R, 2 * DISC_R))

"""Issue 22's target: authoring a box hand-off storyboard from an empty canvas with at most 25
pointer drags, every one a real mouse drag in the window (clicks, menu picks and keys are not
drags). A carries the box from the left, hands it over to B in the middle, B carries it away."""
import numpy as np
from PySide6.QtCore import QPoint, Qt

from app import commands as cmd
from app.timeline import RULER_H, frame_to_x
from engine.skeleton import FEET, JOINT_INDEX

MAX_DRAGS = 25


class Artist:
    """Real mouse and keyboard events on the window's widgets, counting the drags."""

    def __init__(self, qtbot, window):
        self.qtbot, self.window, self.doc, self.canvas = qtbot, window, window.doc, window.canvas
        self.drags = 0
        window.activateWindow()
        qtbot.waitExposed(window)
        self.focus_canvas()

    def focus_canvas(self) -> None:
        self.canvas.setFocus()
        self.qtbot.waitUntil(self.canvas.hasFocus)

    def px(self, uv) -> QPoint:
        x, y = self.canvas.to_px(np.asarray(uv, float))
        return QPoint(round(x), round(y))

    def drag(self, widget, points: list[QPoint], modifiers=Qt.NoModifier) -> None:
        self.drags += 1
        self.qtbot.mousePress(widget, Qt.LeftButton, modifiers, points[0])
        for p in points[1:]:
            self.qtbot.mouseMove(widget, p)
        self.qtbot.mouseRelease(widget, Qt.LeftButton, modifiers, points[-1])

    def sketch(self, uvs) -> None:
        self.drag(self.canvas, [self.px(uv) for uv in uvs])

    def click(self, uv) -> None:
        self.qtbot.mouseClick(self.canvas, Qt.LeftButton, pos=self.px(uv))

    def key(self, key) -> None:
        self.qtbot.keyClick(self.canvas, key)

    def frame(self, frame: int) -> None:
        timeline = self.window.timeline
        x = round(frame_to_x(frame, self.doc.storyboard.length, timeline.width()))
        self.qtbot.mouseClick(timeline, Qt.LeftButton, pos=QPoint(x, RULER_H // 2))
        assert self.doc.frame == frame

    def span(self, first: int, last: int) -> None:
        timeline = self.window.timeline
        xs = [round(frame_to_x(f, self.doc.storyboard.length, timeline.width())) for f in (first, (first + last) // 2, last)]
        self.drag(timeline, [QPoint(x, RULER_H // 2) for x in xs], Qt.ShiftModifier)
        assert self.doc.span == (first, last)

    def choose(self, combo, index: int) -> None:
        """Arrow keys on a Properties combo box until it shows the item (separators are skipped)."""
        combo.setFocus()
        for _ in range(combo.count()):
            if combo.currentIndex() == index:
                break
            self.qtbot.keyClick(combo, Qt.Key_Down if index > combo.currentIndex() else Qt.Key_Up)
        assert combo.currentIndex() == index
        self.focus_canvas()

    def agent(self, agent: str) -> None:
        self.choose(self.window.properties.agent, self.window.properties.agent.findData(agent))
        assert self.doc.selection.agent == agent

    def joint(self, joint: str) -> None:
        self.choose(self.window.properties.joint, self.window.properties.joint.findText(joint))
        assert self.doc.selection.joint == joint

    def stamp(self, name: str) -> None:
        edit = next(a.menu() for a in self.window.menuBar().actions() if a.text() == "&Edit")
        library = next(a.menu() for a in edit.actions() if a.text() == "Stamp &Pose")
        next(a for a in library.actions() if a.text().lower() == name).trigger()

    def pose(self, agent: str, frame: int) -> np.ndarray:
        return cmd.find_keypose(self.doc.storyboard, agent, frame).points


def test_a_box_hand_off_in_at_most_25_drags(qtbot, make_window):
    window = make_window()
    window.resize(1366, 768)
    artist = Artist(qtbot, window)
    doc = artist.doc
    pelvis, wrists = JOINT_INDEX["pelvis"], (JOINT_INDEX["l_wrist"], JOINT_INDEX["r_wrist"])
    places = {"A": {0: -1.2, 60: -0.3, 119: -0.3}, "B": {0: 1.2, 60: 0.3, 119: 1.3}}
    poses = {"A": {0: "carry", 60: "hand over", 119: "stand"}, "B": {0: "stand", 60: "hand over", 119: "carry"}}

    # Keyposes: a click places a figure, the library poses it, a pelvis drag puts it in place.
    for frame in (0, 60, 119):
        artist.frame(frame)
        for agent in ("A", "B"):
            artist.agent(agent)
            artist.key(Qt.Key_K)
            if cmd.find_keypose(doc.storyboard, agent, frame) is None:
                artist.click((places[agent][frame], 0.0))
            artist.stamp(poses[agent][frame])
            hip = artist.pose(agent, frame)[pelvis].copy()
            target = np.array([places[agent][frame], hip[1]])
            if np.linalg.norm(target - hip) > 0.02:
                artist.sketch([hip, (hip + target) / 2, target])
    # The box: a rectangle between A's hands at frame 0, and its path to the right.
    artist.frame(0)
    artist.key(Qt.Key_O)
    hands = artist.pose("A", 0)[list(wrists)].mean(0)
    artist.sketch([hands + (-0.2, -0.15), hands + (0.0, 0.0), hands + (0.2, 0.15)])
    artist.joint("object path")
    artist.key(Qt.Key_T)
    artist.sketch([hands + (x, 0.0) for x in np.linspace(0.0, 2.4, 12)])
    # Pelvis paths for both people over the whole clip.
    for agent, (start, end) in (("A", (-1.2, -0.3)), ("B", (0.3, 1.3))):
        artist.agent(agent)
        artist.joint("pelvis")
        artist.key(Qt.Key_T)
        y = artist.pose(agent, 0)[pelvis][1]
        artist.sketch([(x, y) for x in np.linspace(start, end, 10)])
    # Contacts: A's hands on the box until the hand-off, B's from it.
    artist.key(Qt.Key_C)
    for agent, (first, last), frame in (("A", (0, 62), 0), ("B", (58, 119), 60)):
        artist.frame(frame)
        artist.span(first, last)
        box = doc.storyboard.object_keys[0].outline
        for side, wrist in enumerate(wrists):
            artist.click(artist.pose(agent, frame)[wrist])
            artist.click(np.array([box[:, 0].min() if side == 0 else box[:, 0].max(), box[:, 1].mean()]))

    sb = doc.storyboard
    sb.validate()
    assert artist.drags <= MAX_DRAGS, artist.drags
    assert sorted((k.agent, k.frame) for k in sb.keyposes) == [(a, f) for a in "AB" for f in (0, 60, 119)]
    assert all(k.mask.all() for k in sb.keyposes)
    assert len(sb.object_keys) == 1 and len(sb.object_paths) == 1
    assert sorted((t.agent, t.joint) for t in sb.trajectories) == [("A", "pelvis"), ("B", "pelvis")]
    contacts = sorted((c.agent, c.hand, c.start, c.end, c.object) for c in sb.contacts)
    assert contacts == [("A", "left", 0, 62, "box1"), ("A", "right", 0, 62, "box1"),
                        ("B", "left", 58, 119, "box1"), ("B", "right", 58, 119, "box1")]
    for agent, frame in (("A", 60), ("B", 60), ("B", 119)):      # people stand where they were put
        assert abs(artist.pose(agent, frame)[pelvis][0] - places[agent][frame]) < 0.03
    feet = [artist.pose(a, f)[list(FEET), 1].min() for a in "AB" for f in (0, 60, 119)]
    assert np.ptp(feet) < 0.1                                    # all on one floor line

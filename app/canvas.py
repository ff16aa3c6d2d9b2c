"""The sketch canvas: the storyboard camera's image plane, drawn with QPainter.

Widget pixels map to sketch-plane metres through a zoom (pixels per metre) and a pan (the
sketch point at the widget centre); v points up on the page, so y is flipped. The canvas only
reads the document and pushes commands; everything it shows is redrawn from the document.
"""
from __future__ import annotations

import copy
from dataclasses import dataclass, field

import numpy as np
from PySide6.QtCore import Qt, Signal
from PySide6.QtWidgets import QWidget

from engine.facing import moved_depth
from engine.poses import standing_pose_2d
from engine.rig import drag_pose
from engine.skeleton import JOINT_INDEX, JOINT_NAMES
from engine.storyboard import SKETCH_LIMIT_M, Contact, ObjectPath, Trajectory

from . import commands as cmd
from .canvas_paint import CanvasPainting
from .canvas_scene import CanvasScene
from .document import OBJECT_PATH, Document
from .strokes import clean_stroke, splice

HIT_PX = 9.0            # how close (pixels) a click must be to a joint, stroke or anchor
FRAME_MARGIN_PX = 40.0  # free border around the sketch when framing it
SHORTEST_STROKE_PX = 12  # a shorter stroke is a slip of the mouse (a 6-pixel one became a path of
                         # the head over the whole clip)


@dataclass
class _Gesture:
    """The mouse gesture in progress (None when idle)."""
    kind: str                             # joint | stroke | rect | lasso | move_object | pan
    points: list = field(default_factory=list)   # sketch-plane points, or pixels for pan
    agent: str = ""
    joint: int = 0
    index: int = -1                       # object key index for move_object
    pose: tuple | None = None             # joint drags: the keypose's (points, mask) at the press
    mode: str = "rig"                     # joint drags: engine.rig's mode, from the keys held at the press
    frame: int = 0                        # joint drags: the key's frame (a key pressed mid-drag moves
                                          # the timeline, not the drag: it wrote the pose onto another key)


class SketchCanvas(CanvasScene, CanvasPainting, QWidget):
    message = Signal(str)   # a hint for the status bar
    dragged = Signal(object)   # Storyboard: a copy with the joint or object drag in progress applied
    dragEnded = Signal()       # a joint or object drag was released (its edit is in the document)

    def __init__(self, document: Document, parent: QWidget | None = None):
        super().__init__(parent)
        self._doc = document
        self.zoom = 170.0                     # pixels per metre
        self.pan = np.array([0.0, -0.1])      # sketch point at the widget centre
        self.show_onion = True                # the generated motion under the sketch (set_onion)
        self._gesture: _Gesture | None = None
        self._pending_hand: tuple[str, str] | None = None   # contact tool: (agent, hand) picked
        self._press_modifiers = Qt.NoModifier                 # of the last press: the rig's mode
        self.setMinimumSize(320, 240)
        self.setMouseTracking(False)
        self.setFocusPolicy(Qt.StrongFocus)
        for signal in (document.storyboardChanged, document.frameChanged, document.selectionChanged,
                       document.resultChanged, document.referenceChanged, document.spanChanged):
            signal.connect(self.update)
        document.toolChanged.connect(self._on_tool)
        document.replaced.connect(self.frame_sketch)
        self._on_tool(document.tool)

    # ---- coordinates ---------------------------------------------------------------------------
    def set_onion(self, on: bool) -> None:
        if on != self.show_onion:
            self.show_onion = on
            self.update()

    def to_px(self, uv) -> np.ndarray:
        """Sketch points (..., 2) metres -> widget pixels (..., 2)."""
        uv = np.asarray(uv, float)
        centre = np.array([self.width() / 2, self.height() / 2])
        return centre + (uv - self.pan) * np.array([self.zoom, -self.zoom])

    def to_uv(self, px) -> np.ndarray:
        """Widget pixels (..., 2) -> sketch points (..., 2) metres, inside the storyboard's limits
        (with room for a pose or outline placed at the edge), so that every save loads again."""
        px = np.asarray(px, float)
        centre = np.array([self.width() / 2, self.height() / 2])
        uv = self.pan + (px - centre) / np.array([self.zoom, -self.zoom])
        return np.clip(uv, -SKETCH_LIMIT_M + 5.0, SKETCH_LIMIT_M - 5.0)

    def _set_pan(self, pan) -> None:
        self.pan = np.clip(pan, -SKETCH_LIMIT_M / 2, SKETCH_LIMIT_M / 2)

    def resizeEvent(self, event):
        """What was in view stays in view as the canvas shrinks or grows (shrunk with the
        window, it showed 59% of the sketch until F)."""
        old, new = event.oldSize(), event.size()
        if old.width() > 0 and old.height() > 0 and self.isVisible():
            ratio = min(new.width() / old.width(), new.height() / old.height())
            self.zoom = float(np.clip(self.zoom * ratio, 20.0, 2000.0))
        super().resizeEvent(event)

    def frame_sketch(self) -> None:
        """Zoom and pan so that every keypose, path and object outline is in view (F)."""
        sb = self._doc.storyboard
        points = [k.points[k.mask] for k in sb.keyposes] + [t.points for t in sb.trajectories]
        points += [k.outline for k in sb.object_keys] + [p.points for p in sb.object_paths]
        points = [np.asarray(p, float).reshape(-1, 2) for p in points]
        points = np.concatenate(points) if points else np.zeros((0, 2))
        if len(points) == 0:
            return
        lo, hi = points.min(0), points.max(0)
        # Leave room for labels, joint handles and the frame counter at the top.
        usable = np.array([self.width() - 2 * FRAME_MARGIN_PX, self.height() - 2 * FRAME_MARGIN_PX - 24])
        self.zoom = float(np.clip(np.min(np.maximum(usable, 1) / np.maximum(hi - lo, 0.2)), 20.0, 2000.0))
        self.pan = (lo + hi) / 2 + np.array([0.0, 12.0 / self.zoom])
        self.update()

    def keep_in_view(self, points: np.ndarray) -> None:
        """Pan just enough that sketch points (L, 2) are in view (frame all if they do not fit)."""
        margin = FRAME_MARGIN_PX / self.zoom
        half = np.array([self.width(), self.height()]) / (2 * self.zoom) - margin
        lo, hi = points.min(0) - self.pan, points.max(0) - self.pan
        if np.any(hi - lo > 2 * half):
            self.frame_sketch()
            return
        self._set_pan(self.pan + np.maximum(hi - half, 0.0) + np.minimum(lo + half, 0.0))
        self.update()

    def keyPressEvent(self, event):
        if event.key() == Qt.Key_F and not event.modifiers():
            self.frame_sketch()
        else:
            super().keyPressEvent(event)

    def _hit(self) -> float:
        return HIT_PX / self.zoom

    # ---- mouse ---------------------------------------------------------------------------------
    def mousePressEvent(self, event):
        px = np.array([event.position().x(), event.position().y()])
        uv = self.to_uv(px)
        if event.button() == Qt.MiddleButton:
            self._gesture = _Gesture("pan", [px])
            return
        if event.button() == Qt.RightButton:
            self._pending_hand = None
            self.update()
            return
        if event.button() != Qt.LeftButton:
            return
        tool = self._doc.tool
        self._press_modifiers = event.modifiers()
        handler = getattr(self, f"_press_{tool}")
        handler(uv)
        self.update()

    def mouseMoveEvent(self, event):
        g = self._gesture
        if g is None:
            return
        px = np.array([event.position().x(), event.position().y()])
        if g.kind == "pan":
            self._set_pan(self.pan - (px - g.points[-1]) / np.array([self.zoom, -self.zoom]))
            g.points[-1] = px
        elif g.kind in ("joint", "rect", "move_object"):
            g.points[1:] = [self.to_uv(px)]
            edit = self._drag_edit(g)
            if edit is not None:
                dragged = copy.deepcopy(self._doc.storyboard)
                edit.apply(dragged)
                self.dragged.emit(dragged)
        else:
            g.points.append(self.to_uv(px))
        self.update()

    def mouseReleaseEvent(self, event):
        g, self._gesture = self._gesture, None
        if g is None or g.kind == "pan":
            return
        getattr(self, f"_finish_{g.kind}")(g)
        if g.kind in ("joint", "move_object"):
            self.dragEnded.emit()
        self.update()

    def wheelEvent(self, event):
        """Zoom about the cursor: the sketch point under it stays put."""
        px = np.array([event.position().x(), event.position().y()])
        before = self.to_uv(px)
        self.zoom = float(np.clip(self.zoom * 1.0015 ** event.angleDelta().y(), 20.0, 2000.0))
        self._set_pan(self.pan + before - self.to_uv(px))
        self.update()

    # ---- tools: press ------------------------------------------------------------------------
    def _joint_gesture(self, uv, agent: str, joint: int) -> _Gesture:
        points, mask = self._keypose_points(agent, self._doc.frame)
        return _Gesture("joint", [uv, uv], agent=agent, joint=joint, pose=(points.copy(), mask.copy()),
                        mode=_rig_mode(self._press_modifiers), frame=self._doc.frame)

    def _press_select(self, uv):
        hit = self._joint_at(uv)
        if hit:
            self._doc.select(agent=hit[0], joint=JOINT_NAMES[hit[1]])
            self._gesture = self._joint_gesture(uv, *hit)
            return
        obj = self._object_at(uv)
        if obj:
            self._doc.select(object=obj[0])
            self._gesture = _Gesture("move_object", [uv, uv], index=obj[1])
            return
        stroke = self._stroke_at(uv)
        if stroke:
            s = getattr(self._doc.storyboard, stroke[0])[stroke[1]]
            if stroke[0] == "trajectories":
                self._doc.select(agent=s.agent, joint=s.joint)
            else:
                self._doc.select(object=s.object, joint=OBJECT_PATH)

    def _press_keypose(self, uv):
        hit = self._joint_at(uv)
        if hit:
            self._doc.select(agent=hit[0], joint=JOINT_NAMES[hit[1]])
            self._gesture = self._joint_gesture(uv, *hit)
            return
        agent = self._doc.selection.agent
        if agent and cmd.find_keypose(self._doc.storyboard, agent, self._doc.frame) is None:
            points = standing_pose_2d(self._doc.storyboard.camera) + uv
            self._doc.undo_stack.push(cmd.SetKeypose(self._doc, agent, self._doc.frame, points,
                                                     np.ones(len(points), bool)))
        else:
            self.message.emit("Drag a joint to pose it; Erase removes a joint.")

    def _press_trajectory(self, uv):
        self._gesture = _Gesture("stroke", [uv])

    def _press_object(self, uv):
        shape = self._doc.tool_options.object_shape
        self._gesture = _Gesture("rect" if shape == "rectangle" else "lasso", [uv, uv])

    def _press_contact(self, uv):
        if self._pending_hand is None:
            hand = self._hand_at(uv)
            if hand is None:
                self.message.emit("Contact: click a hand (a wrist of a keypose) first.")
                return
            self._pending_hand = hand
            self.message.emit("Contact: now click an object anchor or another person's hand.")
            return
        agent, which = self._pending_hand
        frame, last = self._doc.frame, self._doc.storyboard.length - 1
        start, end = self._doc.span_or((frame, min(frame + 20, last)))
        anchor, hand = self._anchor_at(uv), self._hand_at(uv, other_than=agent)
        if anchor is not None:
            contact = Contact(agent, which, start, end, object=anchor[0], anchor=anchor[1])
        elif hand is not None:
            contact = Contact(agent, which, start, end, other_agent=hand[0], other_hand=hand[1])
        else:
            self.message.emit("Contact: click an object anchor (side of an object) or another person's hand.")
            return
        self._pending_hand = None
        held = next((c for c in self._doc.storyboard.contacts if (c.agent, c.hand) == (agent, which)
                     and c.start <= end and start <= c.end), None)
        overlap = "" if held is None else f" (this hand also holds on over frames {held.start}-{held.end})"
        before = [c.anchor for c in self._doc.storyboard.contacts] + [contact.anchor]
        self._doc.undo_stack.push(cmd.AddContact(self._doc, contact))
        moved = "" if [c.anchor for c in self._doc.storyboard.contacts] == before else \
            " (grips chosen again: one hand to a grip, the left hand on its left)"
        self.message.emit(f"Contact added: {cmd.describe_contact(self._doc.storyboard.contacts[-1])}{moved}{overlap}")

    def _press_erase(self, uv):
        """Erase what is under the pointer: a joint, else the object key whose outline holds it
        (a box is clicked inside, where paths and contacts cross it too), else a stroke or a
        contact line; the status bar says what went (Ctrl+Z brings it back)."""
        doc = self._doc
        joint, obj = self._joint_at(uv), self._object_at(uv)
        contact, stroke = self._contact_at(uv), self._stroke_at(uv)
        if joint:
            edit = cmd.DeleteKeyposeJoint(doc, joint[0], doc.frame, joint[1])
        elif obj:
            edit = cmd.DeleteObjectKey(doc, obj[1])
        elif stroke:
            edit = cmd.EraseStroke(doc, *stroke)
        elif contact is not None:
            edit = cmd.DeleteContact(doc, contact)
        else:
            return
        doc.undo_stack.push(edit)
        self.message.emit(f"{edit.text()} (Ctrl+Z brings it back)")

    # ---- tools: release ------------------------------------------------------------------------
    def _drag_edit(self, g: _Gesture) -> cmd.StoryboardCommand | None:
        """The edit a joint or object drag makes so far (None before it has moved)."""
        delta = g.points[-1] - g.points[0]
        if g.kind not in ("joint", "move_object") or np.linalg.norm(delta) <= 1e-6:
            return None
        if g.kind == "joint":
            posed, key = self._posed(g), cmd.find_keypose(self._doc.storyboard, g.agent, g.frame)
            depth = None if key is None or key.depth is None else \
                moved_depth(g.pose[0], key.depth, posed, self._doc.storyboard.camera)   # bones kept in depth
            return cmd.SetKeypose(self._doc, g.agent, g.frame, posed, g.pose[1],
                                  "Pose " + JOINT_NAMES[g.joint], depth)
        return cmd.MoveObjectKey(self._doc, g.index, delta)

    def _posed(self, g: _Gesture) -> np.ndarray:
        """The keypose's points (22, 2) with joint drag g applied by the rig."""
        points, mask = g.pose
        pinned = tuple(JOINT_INDEX[j] for j in self._doc.pinned_joints(g.agent))
        return drag_pose(points, mask, g.joint, g.points[-1], g.mode, pinned,
                         standing_pose_2d(self._doc.storyboard.camera))

    def _finish_joint(self, g: _Gesture):
        edit = self._drag_edit(g)
        if edit is not None:
            self._doc.undo_stack.push(edit)

    _finish_move_object = _finish_joint

    def _finish_stroke(self, g: _Gesture):
        raw = np.array(g.points)
        extent = np.linalg.norm(raw.max(0) - raw.min(0)) * self.zoom if len(raw) >= 2 else 0.0   # pixels
        if extent < 3:
            return
        if extent < SHORTEST_STROKE_PX:   # a slip, not a path
            self.message.emit(f"That stroke is too short for a path ({len(raw)} points); drag further to draw one.")
            return
        doc, sel, sb = self._doc, self._doc.selection, self._doc.storyboard
        if sel.joint == OBJECT_PATH:
            if sel.object is None:
                self.message.emit("Select or draw an object before drawing its path.")
                return
            field_name, mine = "object_paths", lambda s: s.object == sel.object
        else:
            field_name, mine = "trajectories", lambda s: s.agent == sel.agent and s.joint == sel.joint
        start, end = doc.span_or(self._stroke_span(field_name, sel.agent))
        for i, s in enumerate(getattr(sb, field_name)):
            if not mine(s) or s.end < start or end < s.start:
                continue
            # A stroke that starts on a path of the same joint it overlaps redraws part of it (the
            # path keeps its frames: after the clip grew, its 0-119 no longer matched 0-199 and the
            # redraw was refused); any other would contradict it.
            redrawn = splice(s.points, raw, 2 * self._hit())
            if redrawn is None:
                self.message.emit(f"A path for the same {'object' if field_name == 'object_paths' else 'joint'} "
                                  f"already covers frames {s.start}-{s.end}: start on it to redraw part of "
                                  "it, erase it, or select frames on the timeline that it does not cover.")
                return
            new = Trajectory(s.agent, s.joint, s.start, s.end, redrawn) if field_name == "trajectories" \
                else ObjectPath(s.object, s.start, s.end, redrawn)
            doc.undo_stack.push(cmd.ReplaceStroke(doc, field_name, i, new, "Redraw part of path"))
            return
        points = clean_stroke(raw)
        item = ObjectPath(sel.object, start, end, points) if field_name == "object_paths" \
            else Trajectory(sel.agent, sel.joint, start, end, points)
        doc.undo_stack.push(cmd.AddStroke(doc, field_name, item,
                                          "Draw object path" if field_name == "object_paths" else "Draw trajectory"))

    def _stroke_span(self, field_name: str, agent: str) -> tuple[int, int]:
        """The frames a new stroke covers where no frames are selected on the timeline: a person's
        from their first keypose to their last (a pelvis path over the whole clip walked a person who
        put a box down at a key 14 frames before the end 1.3 m towards the camera as they stood up:
        a stroke says where on the page, not how deep, and a rising pelvis on the same point of the
        page moves away along the view), the whole clip for an object or a person with fewer keys."""
        sb = self._doc.storyboard
        frames = sorted(k.frame for k in sb.keyposes if k.agent == agent) if field_name == "trajectories" else []
        return (frames[0], frames[-1]) if len(frames) >= 2 and frames[0] < frames[-1] else (0, sb.length - 1)

    def _finish_rect(self, g: _Gesture):
        (u0, v0), (u1, v1) = g.points[0], g.points[-1]
        if min(abs(u1 - u0), abs(v1 - v0)) * self.zoom < 4:
            return
        self._push_object(np.array([[u0, v0], [u1, v0], [u1, v1], [u0, v1]]))

    def _finish_lasso(self, g: _Gesture):
        outline = clean_stroke(np.array(g.points), spacing=0.03)
        if len(outline) >= 3 and np.ptp(outline, axis=0).min() * self.zoom >= 4:
            self._push_object(outline)

    def _push_object(self, outline: np.ndarray):
        doc = self._doc
        ids = [o.id for o in doc.storyboard.objects]
        object_id = doc.selection.object if doc.selection.object in ids else _fresh_id("box", ids)
        doc.undo_stack.push(cmd.SetObjectKey(doc, object_id, doc.frame, outline))
        doc.select(object=object_id)

    def _on_tool(self, tool: str):
        self._pending_hand = None
        self.setCursor(Qt.ArrowCursor if tool == "select" else Qt.CrossCursor)
        self.update()

    # ---- painting ------------------------------------------------------------------------------


def _fresh_id(prefix: str, taken: list[str]) -> str:
    n = 1
    while f"{prefix}{n}" in taken:
        n += 1
    return f"{prefix}{n}"


def _rig_mode(modifiers) -> str:
    """engine.rig's mode for the held keys: Shift turns, Ctrl scales the figure, Alt frees the joint."""
    if modifiers & Qt.AltModifier:
        return "free"
    if modifiers & Qt.ShiftModifier:
        return "rotate"
    if modifiers & Qt.ControlModifier:
        return "scale"
    return "rig"

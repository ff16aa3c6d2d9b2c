"""The sketch canvas: the storyboard camera's image plane, drawn with QPainter.

Widget pixels map to sketch-plane metres through a zoom (pixels per metre) and a pan (the
sketch point at the widget centre); v points up on the page, so y is flipped. The canvas only
reads the document and pushes commands; everything it shows is redrawn from the document.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from PySide6.QtCore import QPointF, QRectF, Qt, Signal
from PySide6.QtGui import QColor, QFont, QFontMetricsF, QPainter, QPainterPath, QPen, QPolygonF
from PySide6.QtWidgets import QWidget

from engine.geometry.polylines import point_polyline_distance
from engine.poses import standing_pose_2d
from engine.skeleton import JOINT_INDEX, JOINT_NAMES, PARENTS
from engine.storyboard import SKETCH_LIMIT_M, Contact, ObjectPath, Trajectory

from . import commands as cmd
from .document import OBJECT_PATH, Document
from .strokes import clean_stroke, splice

HIT_PX = 9.0            # how close (pixels) a click must be to a joint, stroke or anchor
FRAME_MARGIN_PX = 40.0  # free border around the sketch when framing it
LABEL_MARGIN_PX = 3.0   # labels keep this far from the canvas edges
PAPER = QColor("#f6f4ef")
GRID = QColor("#d9d5cc")
GRID_AXIS = QColor("#bdb7aa")
INK = QColor("#2b2b2b")
OBJECT_INK = QColor("#8a6d3b")
HAND_NAMES = {"left": "l_wrist", "right": "r_wrist"}


@dataclass
class _Gesture:
    """The mouse gesture in progress (None when idle)."""
    kind: str                             # joint | stroke | rect | lasso | move_object | pan
    points: list = field(default_factory=list)   # sketch-plane points, or pixels for pan
    agent: str = ""
    joint: int = 0
    index: int = -1                       # object key index for move_object


class SketchCanvas(QWidget):
    message = Signal(str)   # a hint for the status bar

    def __init__(self, document: Document, parent: QWidget | None = None):
        super().__init__(parent)
        self._doc = document
        self.zoom = 170.0                     # pixels per metre
        self.pan = np.array([0.0, -0.1])      # sketch point at the widget centre
        self.show_onion = True                # the generated motion under the sketch (set_onion)
        self._gesture: _Gesture | None = None
        self._pending_hand: tuple[str, str] | None = None   # contact tool: (agent, hand) picked
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

    def keyPressEvent(self, event):
        if event.key() == Qt.Key_F and not event.modifiers():
            self.frame_sketch()
        else:
            super().keyPressEvent(event)

    def _hit(self) -> float:
        return HIT_PX / self.zoom

    # ---- what is on screen at the playhead -----------------------------------------------------
    def _keypose_points(self, agent: str, frame: int) -> tuple[np.ndarray, np.ndarray] | None:
        """(points (22, 2), mask (22,)) of the keypose, with a joint drag in progress applied."""
        k = cmd.find_keypose(self._doc.storyboard, agent, frame)
        if k is None:
            return None
        points, mask = k.points.copy(), k.mask.copy()
        g = self._gesture
        if g and g.kind == "joint" and g.agent == agent and frame == self._doc.frame:
            points[g.joint], mask[g.joint] = g.points[-1], True
        return points, mask

    def _object_outline(self, object_id: str, frame: int) -> tuple[int, np.ndarray, bool] | None:
        """(index, outline, exact) of the object's key at the frame, else its latest earlier key."""
        keys = [(i, k) for i, k in enumerate(self._doc.storyboard.object_keys) if k.object == object_id]
        if not keys:
            return None
        exact = [(i, k) for i, k in keys if k.frame == frame]
        earlier = [(i, k) for i, k in keys if k.frame < frame]
        if exact:
            i, k = exact[0]
        elif earlier:
            i, k = max(earlier, key=lambda ik: ik[1].frame)
        else:
            i, k = min(keys, key=lambda ik: ik[1].frame)
        outline = k.outline
        g = self._gesture
        if g and g.kind == "move_object" and g.index == i:
            outline = outline + (g.points[-1] - g.points[0])
        return i, outline, bool(exact)

    def _anchors_2d(self, outline: np.ndarray) -> np.ndarray:
        """The object's two grasp anchors in the sketch: middle of its left and right sides (2, 2)."""
        lo, hi = outline.min(axis=0), outline.max(axis=0)
        mid = (lo[1] + hi[1]) / 2
        return np.array([[lo[0], mid], [hi[0], mid]])

    def _hand_position(self, agent: str, hand: str) -> np.ndarray | None:
        j = JOINT_INDEX[HAND_NAMES[hand]]
        kp = self._keypose_points(agent, self._doc.frame)
        if kp is not None and kp[1][j]:
            return kp[0][j]
        clip = self._doc.clip
        if clip is not None:
            h = self._doc.storyboard.agent_index(agent)
            if h < clip.num_humans:
                return self._doc.storyboard.camera.project(clip.joints[min(self._doc.frame, clip.num_frames - 1), h, j])
        return None

    # ---- hit tests -------------------------------------------------------------------------------
    def _joint_at(self, uv) -> tuple[str, int] | None:
        """(agent, joint index) of the keypose joint under uv at the playhead, selected agent first."""
        sb, frame = self._doc.storyboard, self._doc.frame
        agents = sorted((a.id for a in sb.agents), key=lambda a: a != self._doc.selection.agent)
        for agent in agents:
            kp = self._keypose_points(agent, frame)
            if kp is None:
                continue
            d = np.linalg.norm(kp[0] - uv, axis=-1)
            d[~kp[1]] = np.inf
            j = int(np.argmin(d))
            if d[j] < self._hit():
                return agent, j
        return None

    def _stroke_at(self, uv) -> tuple[str, int] | None:
        sb = self._doc.storyboard
        for field_name in ("trajectories", "object_paths"):
            for i, s in enumerate(getattr(sb, field_name)):
                if point_polyline_distance([uv], s.points)[0] < self._hit():
                    return field_name, i
        return None

    def _object_at(self, uv) -> tuple[str, int] | None:
        """(object id, key index) of an object key at the playhead containing uv."""
        for obj in self._doc.storyboard.objects:
            found = self._object_outline(obj.id, self._doc.frame)
            if found and found[2]:
                path = QPainterPath()
                path.addPolygon(QPolygonF([QPointF(*p) for p in found[1]]))
                if path.contains(QPointF(*uv)):
                    return obj.id, found[0]
        return None

    def _anchor_at(self, uv) -> tuple[str, int] | None:
        for obj in self._doc.storyboard.objects:
            found = self._object_outline(obj.id, self._doc.frame)
            if found:
                d = np.linalg.norm(self._anchors_2d(found[1]) - uv, axis=-1)
                if d.min() < 2 * self._hit():
                    return obj.id, int(np.argmin(d))
        return None

    def _hand_at(self, uv) -> tuple[str, str] | None:
        for agent in self._doc.storyboard.agents:
            for hand in ("left", "right"):
                p = self._hand_position(agent.id, hand)
                if p is not None and np.linalg.norm(p - uv) < 2 * self._hit():
                    return agent.id, hand
        return None

    def _contact_at(self, uv) -> int | None:
        for i, c in enumerate(self._doc.storyboard.contacts):
            ends = self._contact_ends(c)
            if ends is not None and point_polyline_distance([uv], ends)[0] < self._hit():
                return i
        return None

    def _contact_ends(self, c: Contact) -> np.ndarray | None:
        """(2, 2): the hand and what it holds, when both are visible at the playhead."""
        if not c.start <= self._doc.frame <= c.end:
            return None
        hand = self._hand_position(c.agent, c.hand)
        if c.object is not None:
            found = self._object_outline(c.object, self._doc.frame)
            other = self._anchors_2d(found[1])[min(c.anchor, 1)] if found else None
        else:
            other = self._hand_position(c.other_agent, c.other_hand)
        return None if hand is None or other is None else np.stack([hand, other])

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
        else:
            g.points.append(self.to_uv(px))
        self.update()

    def mouseReleaseEvent(self, event):
        g, self._gesture = self._gesture, None
        if g is None or g.kind == "pan":
            return
        getattr(self, f"_finish_{g.kind}")(g)
        self.update()

    def wheelEvent(self, event):
        """Zoom about the cursor: the sketch point under it stays put."""
        px = np.array([event.position().x(), event.position().y()])
        before = self.to_uv(px)
        self.zoom = float(np.clip(self.zoom * 1.0015 ** event.angleDelta().y(), 20.0, 2000.0))
        self._set_pan(self.pan + before - self.to_uv(px))
        self.update()

    # ---- tools: press ------------------------------------------------------------------------
    def _press_select(self, uv):
        hit = self._joint_at(uv)
        if hit:
            self._doc.select(agent=hit[0], joint=JOINT_NAMES[hit[1]])
            self._gesture = _Gesture("joint", [uv, uv], agent=hit[0], joint=hit[1])
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
            self._gesture = _Gesture("joint", [uv, uv], agent=hit[0], joint=hit[1])
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
        hand = self._hand_at(uv)
        if self._pending_hand is None:
            if hand is None:
                self.message.emit("Contact: click a hand (a wrist of a keypose) first.")
                return
            self._pending_hand = hand
            self.message.emit("Contact: now click an object anchor or another person's hand.")
            return
        agent, which = self._pending_hand
        frame, last = self._doc.frame, self._doc.storyboard.length - 1
        start, end = self._doc.span_or((frame, min(frame + 20, last)))
        anchor = self._anchor_at(uv)
        if anchor is not None:
            contact = Contact(agent, which, start, end, object=anchor[0], anchor=anchor[1])
        elif hand is not None and hand[0] != agent:
            contact = Contact(agent, which, start, end, other_agent=hand[0], other_hand=hand[1])
        else:
            self.message.emit("Contact: click an object anchor (side of an object) or another person's hand.")
            return
        self._pending_hand = None
        self._doc.undo_stack.push(cmd.AddContact(self._doc, contact))

    def _press_erase(self, uv):
        doc = self._doc
        joint = self._joint_at(uv)
        if joint:
            doc.undo_stack.push(cmd.DeleteKeyposeJoint(doc, joint[0], doc.frame, joint[1]))
            return
        stroke = self._stroke_at(uv)
        if stroke:
            doc.undo_stack.push(cmd.EraseStroke(doc, *stroke))
            return
        contact = self._contact_at(uv)
        if contact is not None:
            doc.undo_stack.push(cmd.DeleteContact(doc, contact))
            return
        obj = self._object_at(uv)
        if obj:
            doc.undo_stack.push(cmd.DeleteObjectKey(doc, obj[1]))

    # ---- tools: release ------------------------------------------------------------------------
    def _finish_joint(self, g: _Gesture):
        if np.linalg.norm(g.points[-1] - g.points[0]) > 1e-6:
            self._doc.undo_stack.push(cmd.MoveKeyposeJoint(self._doc, g.agent, self._doc.frame,
                                                           g.joint, g.points[-1]))

    def _finish_move_object(self, g: _Gesture):
        delta = g.points[-1] - g.points[0]
        if np.linalg.norm(delta) > 1e-6:
            self._doc.undo_stack.push(cmd.MoveObjectKey(self._doc, g.index, delta))

    def _finish_stroke(self, g: _Gesture):
        raw = np.array(g.points)
        if len(raw) < 2 or np.linalg.norm(raw.max(0) - raw.min(0)) * self.zoom < 3:
            return
        doc, sel, sb = self._doc, self._doc.selection, self._doc.storyboard
        if sel.joint == OBJECT_PATH:
            if sel.object is None:
                self.message.emit("Select or draw an object before drawing its path.")
                return
            field_name, mine = "object_paths", lambda s: s.object == sel.object
        else:
            field_name, mine = "trajectories", lambda s: s.agent == sel.agent and s.joint == sel.joint
        strokes = getattr(sb, field_name)
        for i, s in enumerate(strokes):
            if mine(s):
                redrawn = splice(s.points, raw, 2 * self._hit())
                if redrawn is not None:
                    new = Trajectory(s.agent, s.joint, s.start, s.end, redrawn) if field_name == "trajectories" \
                        else ObjectPath(s.object, s.start, s.end, redrawn)
                    doc.undo_stack.push(cmd.ReplaceStroke(doc, field_name, i, new, "Redraw part of path"))
                    return
        start, end = doc.span_or((0, sb.length - 1))
        points = clean_stroke(raw)
        item = ObjectPath(sel.object, start, end, points) if field_name == "object_paths" \
            else Trajectory(sel.agent, sel.joint, start, end, points)
        doc.undo_stack.push(cmd.AddStroke(doc, field_name, item,
                                          "Draw object path" if field_name == "object_paths" else "Draw trajectory"))

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
    def paintEvent(self, event):
        p = QPainter(self)
        p.setRenderHint(QPainter.Antialiasing)
        p.fillRect(self.rect(), PAPER)
        self._paint_grid(p)
        if self.show_onion:
            self._paint_onion(p)
        self._paint_objects(p)
        self._paint_strokes(p)
        self._paint_keyposes(p)
        self._paint_contacts(p)
        self._paint_gesture(p)
        self._paint_hud(p)
        p.end()

    def _poly(self, uv) -> QPolygonF:
        return QPolygonF([QPointF(x, y) for x, y in self.to_px(uv)])

    def _paint_grid(self, p: QPainter):
        """The ground plane y = 0, projected: 0.5 m squares over 10 x 10 m, axes darker."""
        cam = self._doc.storyboard.camera
        ticks = np.arange(-5.0, 5.01, 0.5)
        for t in ticks:
            axis = abs(t) < 1e-9
            p.setPen(QPen(GRID_AXIS if axis else GRID, 1.4 if axis else 0.8))
            for a, b in (((t, 0, -5), (t, 0, 5)), ((-5, 0, t), (5, 0, t))):
                ends = self.to_px(cam.project(np.array([a, b], float)))
                p.drawLine(QPointF(*ends[0]), QPointF(*ends[1]))

    def _stick_lines(self, p: QPainter, uv: np.ndarray, mask: np.ndarray, pen: QPen):
        p.setPen(pen)
        px = self.to_px(uv)
        for j, parent in enumerate(PARENTS):
            if parent >= 0 and mask[j] and mask[parent]:
                p.drawLine(QPointF(*px[j]), QPointF(*px[parent]))

    def _paint_onion(self, p: QPainter):
        """The generated motion (and any reference) at the playhead, faint, to sketch over."""
        sb, frame = self._doc.storyboard, self._doc.frame
        cam = sb.camera
        for clip, alpha in ((self._doc.reference, 60), (self._doc.clip, 90)):
            if clip is None:
                continue
            joints = clip.joints[min(frame, clip.num_frames - 1)]
            for h in range(clip.num_humans):
                color = QColor(sb.agents[h].color if h < len(sb.agents) else "#777777")
                if clip is self._doc.reference:
                    color = QColor("#777777")
                color.setAlpha(alpha)
                pen = QPen(color, 5, Qt.SolidLine, Qt.RoundCap)
                self._stick_lines(p, cam.project(joints[h]), np.ones(len(PARENTS), bool), pen)
                head = self.to_px(cam.project(joints[h, JOINT_INDEX["head"]]))
                p.setBrush(color)
                p.setPen(Qt.NoPen)
                p.drawEllipse(QPointF(*head), 0.09 * self.zoom, 0.09 * self.zoom)
            if clip.obj_pose is not None and clip.obj_size is not None:
                for o in range(clip.num_objects):
                    self._paint_clip_object(p, clip, o, min(frame, clip.num_frames - 1), alpha)
        # Neighbouring keyposes of the selected agent: where the pose comes from and goes to.
        agent = self._doc.selection.agent
        frames = sorted(k.frame for k in sb.keyposes if k.agent == agent)
        before = [f for f in frames if f < frame][-1:]
        after = [f for f in frames if f > frame][:1]
        for f in before + after:
            points, mask = self._keypose_points(agent, f)
            color = QColor(sb.agents[sb.agent_index(agent)].color)
            color.setAlpha(45)
            self._stick_lines(p, points, mask, QPen(color, 1.5, Qt.DashLine, Qt.RoundCap))

    def _paint_clip_object(self, p: QPainter, clip, o: int, frame: int, alpha: int):
        """An object of the generated clip as the projected outline of its bounding box."""
        from engine.objects import local_to_world
        w, h, d = clip.obj_size[o]
        corners = np.array([[sx * w / 2, y, sz * d / 2] for sx in (-1, 1) for y in (0, h) for sz in (-1, 1)])
        world = local_to_world(corners, clip.obj_pose[frame, o].astype(float))
        uv = self._doc.storyboard.camera.project(world)
        hull = _convex_hull(uv)
        color = QColor(OBJECT_INK)
        color.setAlpha(alpha // 2)
        p.setBrush(color)
        p.setPen(Qt.NoPen)
        p.drawPolygon(self._poly(hull))

    def _paint_objects(self, p: QPainter):
        sb, frame = self._doc.storyboard, self._doc.frame
        for obj in sb.objects:
            found = self._object_outline(obj.id, frame)
            if not found:
                continue
            _, outline, exact = found
            selected = obj.id == self._doc.selection.object
            fill = QColor(OBJECT_INK)
            fill.setAlpha(70 if exact else 25)
            p.setBrush(fill)
            pen = QPen(OBJECT_INK, 2.2 if selected else 1.5, Qt.SolidLine if exact else Qt.DashLine)
            p.setPen(pen)
            p.drawPolygon(self._poly(outline))
            p.setPen(OBJECT_INK)
            top = self.to_px([outline[:, 0].min(), outline[:, 1].max()])
            self._draw_label(p, QPointF(top[0], top[1] - 5), f"{obj.id} ({obj.spec.type})")
            if exact:
                p.setBrush(PAPER)
                for a in self._anchors_2d(outline):
                    p.drawEllipse(QPointF(*self.to_px(a)), 4, 4)

    def _paint_strokes(self, p: QPainter):
        sb, sel = self._doc.storyboard, self._doc.selection
        for t in sb.trajectories:
            color = QColor(sb.agents[sb.agent_index(t.agent)].color)
            chosen = t.agent == sel.agent and t.joint == sel.joint
            self._paint_path(p, t.points, color, 3.0 if chosen else 2.0,
                             f"{t.agent} {t.joint}  {t.start}\u2013{t.end}" if chosen else "")
        for path in sb.object_paths:
            chosen = sel.joint == OBJECT_PATH and path.object == sel.object
            self._paint_path(p, path.points, OBJECT_INK, 3.0 if chosen else 2.0,
                             f"{path.object} path  {path.start}\u2013{path.end}" if chosen else "")

    def _paint_path(self, p: QPainter, points: np.ndarray, color: QColor, width: float, label: str):
        p.setPen(QPen(color, width, Qt.SolidLine, Qt.RoundCap, Qt.RoundJoin))
        p.setBrush(Qt.NoBrush)
        p.drawPolyline(self._poly(points))
        px = self.to_px(points)
        p.setBrush(color)
        p.drawEllipse(QPointF(*px[0]), 3.5, 3.5)
        # An arrowhead at the end: which way the joint travels.
        direction = px[-1] - px[max(0, len(px) - 4)]
        if np.linalg.norm(direction) > 1e-6:
            direction = direction / np.linalg.norm(direction)
            normal = np.array([-direction[1], direction[0]])
            tip = px[-1]
            head = [tip, tip - 10 * direction + 5 * normal, tip - 10 * direction - 5 * normal]
            p.drawPolygon(QPolygonF([QPointF(*q) for q in head]))
        if not label:
            return
        small = QFont(self.font())
        small.setPointSizeF(max(7.0, small.pointSizeF() - 1.5))
        p.setFont(small)
        p.setPen(color.darker(130))
        self._draw_label(p, QPointF(px[0][0] + 6, px[0][1] + 14), label)
        p.setFont(self.font())

    def label_rect(self, baseline: QPointF, text: str, font: QFont) -> QRectF:
        """Where a label written from `baseline` goes: moved inside the canvas, whole, if it
        would stick out past an edge (paths and figures often run to the border)."""
        box = QFontMetricsF(font).boundingRect(text).translated(baseline)
        return fit_inside(box, QRectF(self.rect()).adjusted(LABEL_MARGIN_PX, LABEL_MARGIN_PX,
                                                           -LABEL_MARGIN_PX, -LABEL_MARGIN_PX))

    def _draw_label(self, p: QPainter, baseline: QPointF, text: str) -> None:
        p.drawText(self.label_rect(baseline, text, p.font()), Qt.AlignLeft | Qt.AlignVCenter | Qt.TextDontClip, text)

    def _paint_keyposes(self, p: QPainter):
        sb, frame, sel = self._doc.storyboard, self._doc.frame, self._doc.selection
        for agent in sb.agents:
            kp = self._keypose_points(agent.id, frame)
            if kp is None:
                continue
            points, mask = kp
            color = QColor(agent.color)
            active = agent.id == sel.agent
            self._stick_lines(p, points, mask, QPen(color, 3.2 if active else 2.2, Qt.SolidLine, Qt.RoundCap))
            px = self.to_px(points)
            if mask[JOINT_INDEX["head"]]:
                p.setPen(QPen(color, 2.2))
                p.setBrush(Qt.NoBrush)
                p.drawEllipse(QPointF(*px[JOINT_INDEX["head"]]), 0.1 * self.zoom, 0.1 * self.zoom)
            for j in np.flatnonzero(mask):
                chosen = active and JOINT_NAMES[j] == sel.joint
                p.setPen(QPen(INK if chosen else color.darker(140), 1.2))
                p.setBrush(QColor("#ffd166") if chosen else PAPER)
                r = 5.5 if chosen else (4.0 if active else 3.0)
                p.drawEllipse(QPointF(*px[j]), r, r)
            p.setPen(color.darker(120))
            top = px[JOINT_INDEX["head"]] if mask[JOINT_INDEX["head"]] else px[mask].min(axis=0)
            self._draw_label(p, QPointF(top[0] - 4, top[1] - 0.1 * self.zoom - 8), agent.name or agent.id)

    def _paint_contacts(self, p: QPainter):
        for c in self._doc.storyboard.contacts:
            ends = self._contact_ends(c)
            if ends is None:
                continue
            px = self.to_px(ends)
            p.setPen(QPen(QColor("#d1495b"), 2.0, Qt.DashLine))
            p.drawLine(QPointF(*px[0]), QPointF(*px[1]))
            p.setBrush(QColor("#d1495b"))
            p.drawEllipse(QPointF(*px[0]), 4, 4)
        if self._pending_hand is not None:
            where = self._hand_position(*self._pending_hand)
            if where is not None:
                p.setPen(QPen(QColor("#d1495b"), 2))
                p.setBrush(Qt.NoBrush)
                p.drawEllipse(QPointF(*self.to_px(where)), 10, 10)

    def _paint_gesture(self, p: QPainter):
        g = self._gesture
        if g is None or g.kind in ("joint", "move_object", "pan"):
            return
        p.setPen(QPen(INK, 1.5, Qt.DashLine if g.kind != "stroke" else Qt.SolidLine, Qt.RoundCap))
        p.setBrush(Qt.NoBrush)
        if g.kind == "rect":
            a, b = self.to_px(g.points[0]), self.to_px(g.points[-1])
            p.drawRect(QRectF(QPointF(*a), QPointF(*b)).normalized())
        else:
            p.drawPolyline(self._poly(np.array(g.points)))

    def _paint_hud(self, p: QPainter):
        doc = self._doc
        text = f"frame {doc.frame} / {doc.storyboard.length - 1}"
        if doc.selection.agent:
            text += f"   \u00b7   agent {doc.selection.agent}, {doc.selection.joint}"
        p.setPen(QColor("#6b665c"))
        p.drawText(QPointF(12, 20), text)


def fit_inside(box: QRectF, bounds: QRectF) -> QRectF:
    """`box` moved the least it takes to lie inside `bounds` (its top-left wins if it is larger)."""
    dx = min(0.0, bounds.right() - box.right())
    dy = min(0.0, bounds.bottom() - box.bottom())
    moved = box.translated(dx, dy)
    return moved.translated(max(0.0, bounds.left() - moved.left()), max(0.0, bounds.top() - moved.top()))


def _fresh_id(prefix: str, taken: list[str]) -> str:
    n = 1
    while f"{prefix}{n}" in taken:
        n += 1
    return f"{prefix}{n}"


def _convex_hull(points: np.ndarray) -> np.ndarray:
    """Monotone-chain convex hull of (P, 2) points -> (M, 2), counter-clockwise."""
    pts = sorted(map(tuple, np.round(points, 9)))

    def half(seq):
        out = []
        for q in seq:
            while len(out) >= 2 and _turn(out[-2], out[-1], q) <= 0:
                out.pop()
            out.append(q)
        return out[:-1]

    return np.array(half(pts) + half(pts[::-1]))


def _turn(a, b, c) -> float:
    """z of (b - a) x (c - a): positive for a left turn."""
    return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])

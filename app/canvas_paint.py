"""How the sketch canvas draws: paper and grid, the generated motion under the sketch (onion
skin), objects, strokes, keyposes, contacts, the gesture in progress and the frame caption.
Mixed into SketchCanvas (it reads the canvas's document, view transform and gesture)."""
from __future__ import annotations

import numpy as np
from PySide6.QtCore import QPointF, QRectF, Qt
from PySide6.QtGui import QColor, QFont, QFontMetricsF, QPainter, QPen, QPolygonF

from engine.finishing.timing import holds
from engine.skeleton import JOINT_INDEX, JOINT_NAMES, PARENTS

from . import commands as cmd
from .document import OBJECT_PATH
from .poses import key_facing

LABEL_MARGIN_PX = 3.0   # labels keep this far from the canvas edges
FACING_M = 0.35         # length on the floor of the arrow the way a keypose faces
PAPER = QColor("#f6f4ef")
GRID = QColor("#d9d5cc")
GRID_AXIS = QColor("#bdb7aa")
INK = QColor("#2b2b2b")
OBJECT_INK = QColor("#8a6d3b")


class CanvasPainting:
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
                for a in self._anchors_2d(obj.id, outline):
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
        # Beside the arrowhead: the start is where the figure stands, and a label there hid it.
        self._draw_label(p, QPointF(px[-1][0] + 8, px[-1][1] + 14), label)
        p.setFont(self.font())

    def label_rect(self, baseline: QPointF, text: str, font: QFont) -> QRectF:
        """Where a label written from `baseline` goes: moved inside the canvas, whole, if it
        would stick out past an edge (paths and figures often run to the border)."""
        box = QFontMetricsF(font).boundingRect(text).translated(baseline)
        return fit_inside(box, QRectF(self.rect()).adjusted(LABEL_MARGIN_PX, LABEL_MARGIN_PX,
                                                           -LABEL_MARGIN_PX, -LABEL_MARGIN_PX))

    def _draw_label(self, p: QPainter, baseline: QPointF, text: str) -> None:
        """The label over a thin halo of paper, so that it reads over a figure or a stroke."""
        rect, ink = self.label_rect(baseline, text, p.font()), p.pen()
        flags = Qt.AlignLeft | Qt.AlignVCenter | Qt.TextDontClip
        p.setPen(PAPER)
        for dx, dy in ((-1, 0), (1, 0), (0, -1), (0, 1)):
            p.drawText(rect.translated(dx, dy), flags, text)
        p.setPen(ink)
        p.drawText(rect, flags, text)

    def _paint_keyposes(self, p: QPainter):
        sb, frame, sel = self._doc.storyboard, self._doc.frame, self._doc.selection
        for agent in sb.agents:
            kp = self._keypose_points(agent.id, frame)
            if kp is None:
                self._paint_held(p, agent, frame)
                continue
            points, mask = kp
            color = QColor(agent.color)
            active = agent.id == sel.agent
            self._stick_lines(p, points, mask, QPen(color, 3.2 if active else 2.2, Qt.SolidLine, Qt.RoundCap))
            self._paint_facing(p, cmd.find_keypose(sb, agent.id, frame), points, color)
            px = self.to_px(points)
            if mask[JOINT_INDEX["head"]]:
                p.setPen(QPen(color, 2.2))
                p.setBrush(Qt.NoBrush)
                p.drawEllipse(QPointF(*px[JOINT_INDEX["head"]]), 0.1 * self.zoom, 0.1 * self.zoom)
            pinned = self._doc.pinned_joints(agent.id)
            for j in np.flatnonzero(mask):
                chosen = active and JOINT_NAMES[j] == sel.joint
                p.setPen(QPen(INK if chosen else color.darker(140), 1.2))
                p.setBrush(QColor("#ffd166") if chosen else PAPER)
                r = 5.5 if chosen else (4.0 if active else 3.0)
                p.drawEllipse(QPointF(*px[j]), r, r)
                if JOINT_NAMES[j] in pinned:         # a pin: a square around the joint
                    p.setBrush(Qt.NoBrush)
                    p.setPen(QPen(INK, 1.4))
                    p.drawRect(QRectF(px[j][0] - r - 3, px[j][1] - r - 3, 2 * r + 6, 2 * r + 6))
            p.setPen(color.darker(120))
            top = px[JOINT_INDEX["head"]] if mask[JOINT_INDEX["head"]] else px[mask].min(axis=0)
            self._draw_label(p, QPointF(top[0] - 4, top[1] - 0.1 * self.zoom - 8), agent.name or agent.id)

    def _paint_held(self, p: QPainter, agent, frame: int):
        """Inside a keypose's hold (Keypose.hold) the held pose, dashed: the figure stands so."""
        held = [k for k, end in holds(self._doc.storyboard, agent.id) if k.frame < frame <= end]
        if held:
            color = QColor(agent.color)
            color.setAlpha(170)
            self._stick_lines(p, held[0].points, held[0].mask, QPen(color, 2.0, Qt.DashLine, Qt.RoundCap))

    def _paint_facing(self, p: QPainter, key, points: np.ndarray, color: QColor):
        """An arrow on the floor from under the figure's feet the way it faces (engine.facing);
        dashed while the figure's depth is a guess."""
        found = key_facing(self._doc, key, points)
        if found is None:
            return
        yaw, ground, guessed = found
        camera = self._doc.storyboard.camera
        ahead = ground + FACING_M * np.array([np.sin(yaw), 0.0, np.cos(yaw)])
        start, tip = self.to_px(camera.project(np.stack([ground, ahead])))
        draw_arrow(p, start, tip, color.darker(120), dashed=guessed)

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


def draw_arrow(p: QPainter, start: np.ndarray, tip: np.ndarray, color: QColor, dashed: bool = False) -> None:
    """A line from start to tip (px, (2,)) with an arrowhead at the tip."""
    along = (tip - start) / max(np.linalg.norm(tip - start), 1e-9)
    side = np.array([-along[1], along[0]])
    p.setPen(QPen(color, 1.7, Qt.DashLine if dashed else Qt.SolidLine))
    p.drawLine(QPointF(*start), QPointF(*tip))
    p.setPen(QPen(color, 1.0))
    p.setBrush(color)
    p.drawPolygon(QPolygonF([QPointF(*tip), QPointF(*(tip - 8 * along + 4 * side)), QPointF(*(tip - 8 * along - 4 * side))]))


def fit_inside(box: QRectF, bounds: QRectF) -> QRectF:
    """`box` moved the least it takes to lie inside `bounds` (its top-left wins if it is larger)."""
    dx = min(0.0, bounds.right() - box.right())
    dy = min(0.0, bounds.bottom() - box.bottom())
    moved = box.translated(dx, dy)
    return moved.translated(max(0.0, bounds.left() - moved.left()), max(0.0, bounds.top() - moved.top()))


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

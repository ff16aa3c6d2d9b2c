"""The floor plan: the storyboard seen from above, where people stand and walk on the floor.

The sketch gives depth only through the camera's slant (20 degrees: a hand's wobble of 2 cm up
the page is 6 cm in depth), so here it is drawn instead. The plan is turned like the storyboard
camera: right is the camera's right, up is away from the camera (drawn at the bottom).

- Each keypose is a disc where its feet stand (its frame beside it; the playhead's is ringed),
  with an arrow the way it faces (dashed while its depth is only guessed: the sketch alone cannot
  tell a figure facing the camera from one facing away). Dragging a disc moves the figure on the
  floor, dragging the arrow's tip turns it about the vertical (engine.facing): its sketch changes
  as the camera sees it.
- Dragging on the floor (anywhere, with the Trajectory tool) draws the selected person's walk (a
  pelvis path over the timeline's span, or the whole clip), kept in floor coordinates (Trajectory.floor) so the generator walks it
  exactly; drawing again over the same span replaces it.
- Sketched pelvis paths are shown dashed, at the height a walking pelvis has.
- Each object's keys stand where the sketch puts them on the floor (footprints, dashed; only keys
  at frames nobody holds it: in the hands its height is unknown), and once generated its way is
  drawn thin.
"""
from __future__ import annotations

import copy

import numpy as np
from PySide6.QtCore import QLineF, QPointF, QRectF, QSizeF, Qt, Signal
from PySide6.QtGui import QColor, QPainter, QPainterPath, QPen, QPolygonF
from PySide6.QtWidgets import QWidget

from engine.facing import turned
from engine.finishing.held import sketched_rest
from engine.skeleton import FEET
from engine.synth.reach import heading_of
from engine.storyboard import FLOOR_PATH_HEIGHT, Keypose, Storyboard, Trajectory, floor_path_points

from . import commands as cmd
from .canvas_paint import draw_arrow
from .document import Document
from .poses import key_facing, known_depth
from .strokes import clean_stroke

LABEL_PX = 14.0   # key labels closer than this (pixels) merge
DISC_R = 7.0          # px
GRID_M = 1.0          # metres between grid lines
ARROW_M = 0.45        # length of a facing arrow on the floor
OBJECT_COLOR = QColor("#b48a5c")   # the 3D view's light wood
PAPER = QColor("#fbfaf7")
LABEL_BACKING = QColor(PAPER.red(), PAPER.green(), PAPER.blue(), 190)   # a little see-through


def label_place(beside: QRectF, size, taken: list[QRectF], view: QRectF) -> QRectF:
    """Where a label of `size` goes beside the rectangle `beside`: right of it, left, above or
    below, then a line further up or down at each side in turn, the first place that covers
    nothing in `taken` and lies in `view` (else right of it)."""
    w, h, gap = size.width(), size.height(), 2.0
    c = beside.center()
    sides = [QPointF(beside.right() + gap, c.y() - h / 2), QPointF(beside.left() - gap - w, c.y() - h / 2),
             QPointF(c.x() - w / 2, beside.top() - gap - h), QPointF(c.x() - w / 2, beside.bottom() + gap)]
    lines = [0] + [d * k for k in range(1, 5) for d in (1, -1)]
    places = [QRectF(at + QPointF(0, line * h), size) for line in lines for at in sides]
    return next((r for r in places if view.contains(r) and not any(r.intersects(t) for t in taken)), places[0])


def standing_place(sb: Storyboard, key: Keypose) -> np.ndarray:
    """World (x, z) where a keypose stands: under its feet, else under its pelvis."""
    feet = list(FEET)
    if key.mask[feet].all():
        return sb.camera.unproject_to_height(key.points[feet], 0.0).mean(0)[[0, 2]]
    placed = key.points[0] if key.mask[0] else key.points[key.mask].mean(0)
    return sb.camera.unproject_to_height(placed, FLOOR_PATH_HEIGHT)[[0, 2]]


def moved_on_floor(sb: Storyboard, points: np.ndarray, step_xz: np.ndarray) -> np.ndarray:
    """A keypose's sketch points (22, 2) after the figure moves by step_xz (2,) on the floor."""
    return points + sb.camera.basis()[:2] @ np.array([step_xz[0], 0.0, step_xz[1]])


class FloorPlan(QWidget):
    message = Signal(str)
    dragged = Signal(object)   # Storyboard: a copy with the figure drag in progress applied
    dragEnded = Signal()       # a figure drag was released (its edit is in the document)

    def __init__(self, document: Document, parent: QWidget | None = None):
        super().__init__(parent)
        self._doc = document
        self.zoom = 60.0                      # px per metre
        self.centre = np.zeros(2)             # plan (right, away) coordinates at the widget's centre
        self._drag: tuple[str, object, list[np.ndarray]] | None = None   # (figure | turn | walk, key, [xz...])
        self._framed = True                   # the view frames the content (until the wheel zooms)
        self.label_rects: list[QRectF] = []   # where the last paint put its labels (px)
        self.setMinimumSize(160, 140)
        self.setMouseTracking(False)
        for signal in (document.storyboardChanged, document.frameChanged, document.selectionChanged,
                       document.resultChanged):
            signal.connect(self.update)
        document.replaced.connect(self.fit)

    def resizeEvent(self, event):
        if self._framed:                      # a dock resized or first shown: the scene stays framed
            self.fit()

    # ---- geometry ------------------------------------------------------------------------------
    def _axes(self) -> np.ndarray:
        """(2, 2) rows: the plan's right and away directions as world (x, z)."""
        right, _, back = self._doc.storyboard.camera.basis()
        away = -np.array([back[0], back[2]])
        return np.stack([right[[0, 2]], away / max(np.linalg.norm(away), 1e-9)])

    def to_px(self, xz: np.ndarray) -> np.ndarray:
        plan = (np.asarray(xz, float) @ self._axes().T - self.centre) * self.zoom
        return np.array([self.width() / 2, self.height() / 2]) + plan * (1.0, -1.0)

    def to_xz(self, px) -> np.ndarray:
        plan = (np.asarray(px, float) - (self.width() / 2, self.height() / 2)) * (1.0, -1.0) / self.zoom + self.centre
        return plan @ self._axes()        # the axes are orthonormal: their inverse is the transpose

    def fit(self) -> None:
        """Frame every keypose and path, with a margin."""
        self._framed = True
        points = [p for p in self._content() if len(p)]
        if points:
            plan = np.concatenate(points) @ self._axes().T
            lo, hi = plan.min(0) - 0.8, plan.max(0) + 0.8
            self.centre = (lo + hi) / 2
            self.zoom = float(np.clip(min(self.width() / (hi - lo)[0], self.height() / (hi - lo)[1]), 20.0, 300.0))
        self.update()

    def _content(self) -> list[np.ndarray]:
        sb = self._doc.storyboard
        return [np.array([standing_place(sb, k) for k in sb.keyposes]).reshape(-1, 2)] + \
            [self._walk(t) for t in sb.trajectories if t.joint == "pelvis"]

    def _walk(self, t: Trajectory) -> np.ndarray:
        """A pelvis path's points on the floor (L, 2)."""
        if t.floor is not None:
            return t.floor
        return self._doc.storyboard.camera.unproject_to_height(t.points, FLOOR_PATH_HEIGHT)[:, [0, 2]]

    def _yaw(self, key: Keypose) -> float | None:
        found = key_facing(self._doc, key)
        return None if found is None else found[0]

    def _tip(self, key: Keypose) -> np.ndarray | None:
        yaw = self._yaw(key)
        if yaw is None:
            return None
        return standing_place(self._doc.storyboard, key) + ARROW_M * np.array([np.sin(yaw), np.cos(yaw)])

    def _tip_at(self, px) -> Keypose | None:
        for k in self._doc.storyboard.keyposes:
            tip = self._tip(k)
            if tip is not None and np.linalg.norm(self.to_px(tip) - px) <= 6:
                return k
        return None

    def _key_at(self, px) -> Keypose | None:
        sb = self._doc.storyboard
        hits = [(np.linalg.norm(self.to_px(standing_place(sb, k)) - px), k) for k in sb.keyposes]
        hits = [(d - 2 * (k.frame == self._doc.frame), k) for d, k in hits if d <= DISC_R + 3]
        return min(hits, key=lambda h: h[0])[1] if hits else None

    # ---- mouse -----------------------------------------------------------------------------------
    def mousePressEvent(self, event):
        if event.button() != Qt.LeftButton:
            return
        px = np.array([event.position().x(), event.position().y()])
        drawing = self._doc.tool == "trajectory"       # the path tool draws walks even from a figure
        turning = None if drawing else self._tip_at(px)
        key = None if drawing else turning or self._key_at(px)
        if key is not None:
            self._doc.select(agent=key.agent)
            self._doc.set_frame(key.frame)
            self._drag = ("turn" if turning else "figure", key, [self.to_xz(px)] * 2)
        else:
            self._drag = ("walk", None, [self.to_xz(px)])

    def mouseMoveEvent(self, event):
        if self._drag is None:
            return
        xz = self.to_xz([event.position().x(), event.position().y()])
        kind, key, points = self._drag
        if kind in ("figure", "turn"):
            points[-1] = xz
            edit = self._figure_edit()
            if edit is not None:          # the storyboard as it would be, for the live preview
                dragged = copy.deepcopy(self._doc.storyboard)
                edit.apply(dragged)
                self.dragged.emit(dragged)
        else:
            points.append(xz)
        self.update()

    def mouseReleaseEvent(self, event):
        edit = self._figure_edit()
        drag, self._drag = self._drag, None
        if drag is None:
            return
        kind, key, points = drag
        if kind in ("figure", "turn"):
            if edit is not None:
                self._doc.undo_stack.push(edit)
            self.dragEnded.emit()
        elif np.ptp(np.array(points), axis=0).max() * self.zoom >= 4:
            self._draw_walk(clean_stroke(np.array(points)))
        self.update()

    def _figure_edit(self) -> cmd.SetKeypose | None:
        """The edit the figure drag in progress makes (None before it has moved)."""
        if self._drag is None or self._drag[0] not in ("figure", "turn"):
            return None
        kind, key, points = self._drag
        if kind == "figure":
            step = points[-1] - points[0]
            if np.linalg.norm(step) * self.zoom < 1:
                return None
            return cmd.SetKeypose(self._doc, key.agent, key.frame, moved_on_floor(self._doc.storyboard, key.points, step),
                                  key.mask, "Move on the floor plan")
        angle = self._turned_yaw(key, points[-1]) - self._yaw(key)
        if abs(angle) <= 1e-3:
            return None
        turned_points, depth = turned(key.points, self._doc.storyboard.camera, angle, known_depth(self._doc, key))
        return cmd.SetKeypose(self._doc, key.agent, key.frame, turned_points, key.mask, "Turn on the floor plan", depth)

    def _turned_yaw(self, key: Keypose, pointer_xz: np.ndarray) -> float:
        """The facing the pointer asks for: from where the figure stands towards the pointer."""
        towards = pointer_xz - standing_place(self._doc.storyboard, key)
        return float(heading_of(np.array([towards[0], 0.0, towards[1]])))

    def _draw_walk(self, floor: np.ndarray) -> None:
        """The selected person's pelvis path over the span, from floor points (L, 2)."""
        doc, sb = self._doc, self._doc.storyboard
        agent = doc.selection.agent
        start, end = doc.span_or((0, sb.length - 1))
        walk = Trajectory(agent, "pelvis", start, end, floor_path_points(sb.camera, floor), floor)
        for i, t in enumerate(sb.trajectories):
            if t.agent != agent or t.joint != "pelvis" or t.end < start or end < t.start:
                continue
            if (t.start, t.end) != (start, end):
                self.message.emit(f"{agent}'s walk already covers frames {t.start}-{t.end}: select those "
                                  "frames on the timeline to redraw it, or frames it does not cover.")
                return
            doc.undo_stack.push(cmd.ReplaceStroke(doc, "trajectories", i, walk, "Redraw walk on the floor plan"))
            return
        doc.undo_stack.push(cmd.AddStroke(doc, "trajectories", walk, "Draw walk on the floor plan"))

    def wheelEvent(self, event):
        px = np.array([event.position().x(), event.position().y()])
        before = self.to_xz(px)
        self.zoom = float(np.clip(self.zoom * 1.0015 ** event.angleDelta().y(), 20.0, 300.0))
        self.centre += (before - self.to_xz(px)) @ self._axes().T
        self._framed = False
        self.update()

    # ---- painting --------------------------------------------------------------------------------
    def paintEvent(self, event):
        p = QPainter(self)
        p.setRenderHint(QPainter.Antialiasing)
        p.fillRect(self.rect(), PAPER)
        self._paint_grid(p)
        sb, doc = self._doc.storyboard, self._doc
        colors = {a.id: QColor(a.color) for a in sb.agents}
        for t in sb.trajectories:
            if t.joint == "pelvis":
                pen = QPen(colors[t.agent], 2.2 if t.floor is not None else 1.4)
                pen.setStyle(Qt.SolidLine if t.floor is not None else Qt.DashLine)
                p.setPen(pen)
                p.setBrush(Qt.NoBrush)
                p.drawPolyline(QPolygonF([QPointF(*self.to_px(xz)) for xz in self._walk(t)]))
        moving = self._drag[1] if self._drag and self._drag[0] == "figure" else None
        keys = []                    # (key, where its feet stand (x, z)), in frame order
        for k in sorted(sb.keyposes, key=lambda k: k.frame):
            xz = standing_place(sb, k)
            keys.append((k, xz + self._drag[2][-1] - self._drag[2][0] if k is moving else xz))
        # Labels go where they cover no disc and no other label (people standing together
        # overprinted their frames and each other's discs).
        discs = [QRectF(QPointF(*self.to_px(xz)) - QPointF(DISC_R, DISC_R), QSizeF(2 * DISC_R, 2 * DISC_R))
                 for _, xz in keys]
        taken = list(discs)
        self._paint_objects(p, taken)
        labels: list[list] = []      # [disc, agent, frames]: keys standing together share one label
        for (k, xz), disc in zip(keys, discs):
            self._paint_arrow(p, k, xz, colors[k.agent])
            current = k.frame == doc.frame and k.agent == doc.selection.agent
            p.setPen(QPen(QColor("#1d1d1d") if current else colors[k.agent].darker(150), 2.4 if current else 1))
            p.setBrush(colors[k.agent])
            p.drawEllipse(disc)
            gap = [QLineF(lab[0].center(), disc.center()).length() for lab in labels]
            near = next((lab for lab, d in zip(labels, gap) if lab[1] == k.agent and d < LABEL_PX), None)
            if near:
                near[2].append(k.frame)
            else:
                labels.append([disc, k.agent, [k.frame]])
        p.setPen(QColor("#3a3a3a"))
        for disc, agent, frames in labels:
            self._label(p, taken, disc, f"{agent} {', '.join(map(str, frames))}")
        self.label_rects = taken[len(discs):]
        if self._drag and self._drag[0] == "walk" and len(self._drag[2]) > 1:
            p.setPen(QPen(colors.get(doc.selection.agent, QColor("#333")), 2))
            p.drawPolyline(QPolygonF([QPointF(*self.to_px(xz)) for xz in self._drag[2]]))
        self._paint_camera(p)
        p.end()

    def _label(self, p: QPainter, taken: list[QRectF], beside: QRectF, text: str) -> None:
        """Draw text beside the rectangle `beside` (a disc, a footprint's corner) where it covers
        nothing in `taken` (which it joins) and stays in the view (label_place)."""
        size = QRectF(p.fontMetrics().boundingRect(text)).size()
        rect = label_place(beside, size, taken, QRectF(self.rect()))
        taken.append(rect)
        p.fillRect(rect, LABEL_BACKING)   # readable over the paths and arrows it crosses
        p.drawText(rect, Qt.AlignLeft | Qt.AlignVCenter, text)

    def _paint_objects(self, p: QPainter, taken: list[QRectF]) -> None:
        """Each object's footprint where a key of it stands on the floor (a key at a frame nobody
        holds it: in the hands its height is unknown, and taken for the floor it was drawn metres
        off), named with its frame; and, once generated, the way it travels (thin)."""
        sb, clip = self._doc.storyboard, self._doc.clip
        for o, obj in enumerate(sb.objects):
            if clip is not None and clip.obj_pose is not None and o < clip.num_objects:
                p.setPen(QPen(OBJECT_COLOR, 1.2))
                p.setBrush(Qt.NoBrush)
                p.drawPolyline(QPolygonF([QPointF(*self.to_px(xz)) for xz in clip.obj_pose[:, o, [0, 2]]]))
            holds = [(c.start, c.end) for c in sb.contacts if c.object == obj.id]
            half = np.array(obj.spec.size)[[0, 2]] / 2
            for key in sb.object_keys:
                if key.object != obj.id or any(a <= key.frame <= b for a, b in holds):
                    continue
                place = sketched_rest(sb, o, key.frame, key.frame)[[0, 2]]
                corners = self.to_px(place + half * [[-1, -1], [1, -1], [1, 1], [-1, 1]])
                p.setPen(QPen(OBJECT_COLOR.darker(130), 1.2, Qt.DashLine))
                p.setBrush(QColor(OBJECT_COLOR.red(), OBJECT_COLOR.green(), OBJECT_COLOR.blue(), 70))
                p.drawPolygon(QPolygonF([QPointF(*c) for c in corners]))
                p.setPen(OBJECT_COLOR.darker(160))
                self._label(p, taken, QRectF(QPointF(*corners.min(0)), QPointF(*corners.max(0))), f"{obj.id} {key.frame}")

    def _paint_arrow(self, p: QPainter, key: Keypose, xz: np.ndarray, color: QColor) -> None:
        """The way the keypose faces, as an arrow from its disc (towards the pointer while turned);
        dashed where the figure's depth is a guess (no stamped or turned pose, no motion yet)."""
        found = key_facing(self._doc, key)
        if found is None:
            return
        yaw, _, guessed = found
        if self._drag and self._drag[0] == "turn" and self._drag[1] is key:
            yaw = self._turned_yaw(key, self._drag[2][-1])
        ahead = np.array([np.sin(yaw), np.cos(yaw)])
        draw_arrow(p, self.to_px(xz), self.to_px(xz + ARROW_M * ahead), color.darker(130), dashed=guessed)

    def _paint_grid(self, p: QPainter) -> None:
        """World grid lines every GRID_M metres over the visible floor, the axes darker."""
        corners = np.array([self.to_xz(c) for c in ((0, 0), (self.width(), 0), (0, self.height()),
                                                    (self.width(), self.height()))])
        lo, hi = np.floor(corners.min(0) / GRID_M), np.ceil(corners.max(0) / GRID_M)
        for axis in (0, 1):
            for i in np.arange(lo[axis], hi[axis] + 1):
                a, b = np.empty(2), np.empty(2)
                a[axis] = b[axis] = i * GRID_M
                a[1 - axis], b[1 - axis] = lo[1 - axis] * GRID_M, hi[1 - axis] * GRID_M
                p.setPen(QPen(QColor("#c9c4b8" if i == 0 else "#e6e2d8"), 1))
                p.drawLine(QPointF(*self.to_px(a)), QPointF(*self.to_px(b)))

    def _paint_camera(self, p: QPainter) -> None:
        """The storyboard camera below the plan, looking up into it."""
        x, y = self.width() / 2, self.height() - 8
        path = QPainterPath(QPointF(x, y - 12))
        path.lineTo(QPointF(x - 8, y))
        path.lineTo(QPointF(x + 8, y))
        path.closeSubpath()
        p.setPen(Qt.NoPen)
        p.setBrush(QColor("#8a857a"))
        p.drawPath(path)
        p.setPen(QColor("#8a857a"))
        p.drawText(QRectF(x + 12, y - 14, 120, 16), Qt.AlignLeft | Qt.AlignVCenter, "storyboard camera")

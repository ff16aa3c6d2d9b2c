"""What the sketch canvas shows at the playhead and what lies under the pointer, as a part of
SketchCanvas (it reads the canvas's document, gesture, zoom and pan): keypose points, object
outlines and their grips, hands, and the hit tests the tools press on.
"""
from __future__ import annotations

import numpy as np
from PySide6.QtCore import QPointF
from PySide6.QtGui import QPainterPath, QPolygonF

from engine.geometry.polylines import point_polyline_distance
from engine.grips import anchors_in_sketch
from engine.skeleton import JOINT_INDEX
from engine.storyboard import Contact

from . import commands as cmd

HAND_NAMES = {"left": "l_wrist", "right": "r_wrist"}


class CanvasScene:
    """Mixed into SketchCanvas: needs self._doc, self._gesture, self._hit() and self._posed()."""

    # ---- what is on screen at the playhead -----------------------------------------------------
    def _keypose_points(self, agent: str, frame: int) -> tuple[np.ndarray, np.ndarray] | None:
        """(points (22, 2), mask (22,)) of the keypose, with a joint drag in progress applied."""
        k = cmd.find_keypose(self._doc.storyboard, agent, frame)
        if k is None:
            return None
        points, mask = k.points.copy(), k.mask.copy()
        g = self._gesture
        if g and g.kind == "joint" and g.agent == agent and frame == self._doc.frame:
            points = self._posed(g)
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

    def _anchors_2d(self, object_id: str, outline: np.ndarray) -> np.ndarray:
        """The object's K grasp anchors in the sketch (K, 2) (engine.grips.anchors_in_sketch)."""
        sb = self._doc.storyboard
        return anchors_in_sketch(sb.objects[sb.object_index(object_id)].spec.anchors, outline, sb.camera)

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

    def _grip_position(self, object_id: str, anchor: int) -> np.ndarray | None:
        """Where a grip is at the playhead: on the object's key there, else on the generated
        object (a key frames earlier is where the object was, not where the hands are), else on
        its nearest key."""
        sb, frame, clip = self._doc.storyboard, self._doc.frame, self._doc.clip
        found = self._object_outline(object_id, frame)
        o = sb.object_index(object_id)
        if not (found and found[2]) and clip is not None and clip.obj_anchors is not None \
                and clip.obj_anchors.shape[1] == len(sb.objects) and anchor < clip.obj_anchors.shape[2]:
            return sb.camera.project(clip.obj_anchors[min(frame, clip.num_frames - 1), o, anchor])
        anchors = self._anchors_2d(object_id, found[1]) if found else None
        return anchors[anchor] if anchors is not None and anchor < len(anchors) else None

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
        """(object id, anchor) of the grip under uv where the grips are at the playhead
        (_grip_position: on the generated object between keys, where the hands are, not on the
        stale key an artist cannot see grips on)."""
        for obj in self._doc.storyboard.objects:
            grips = [self._grip_position(obj.id, a) for a in range(len(obj.spec.anchors))]
            d = np.array([np.inf if g is None else float(np.linalg.norm(g - uv)) for g in grips])
            if len(d) and d.min() < 2 * self._hit():
                return obj.id, int(np.argmin(d))
        return None

    def _hand_at(self, uv, other_than: str | None = None) -> tuple[str, str] | None:
        """(agent, hand) of the hand nearest uv within reach of a click, of any agent but
        `other_than` (at a hand-off both people's hands are under the pointer)."""
        found = [(float(np.linalg.norm(p - uv)), agent.id, hand) for agent in self._doc.storyboard.agents
                 if agent.id != other_than for hand in ("left", "right")
                 for p in [self._hand_position(agent.id, hand)] if p is not None]
        distance, agent, hand = min(found, default=(np.inf, None, None))
        return (agent, hand) if distance < 2 * self._hit() else None

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
            other = self._grip_position(c.object, c.anchor)
        else:
            other = self._hand_position(c.other_agent, c.other_hand)
        return None if hand is None or other is None else np.stack([hand, other])

"""Every storyboard edit as an undoable QUndoCommand.

Each command names the Storyboard lists it touches and implements `apply`; the base class
snapshots those lists before and after the first redo, so undo and redo are exact restores
(storyboards are small: a deep copy of a few lists costs microseconds).
"""
from __future__ import annotations

import copy

import numpy as np
from PySide6.QtGui import QUndoCommand

from engine.grips import with_grips_fitted
from engine.objects import ObjectSpec, drawn_size, resized_outline
from engine.skeleton import FEET, MIRROR
from engine.storyboard import SPANS, Contact, Keypose, ObjectKey, SceneObject, Storyboard


class StoryboardCommand(QUndoCommand):
    touches: tuple[str, ...] = ()

    def __init__(self, document, text: str):
        super().__init__(text)
        self._doc = document
        self._before: dict | None = None
        self._after: dict | None = None

    def apply(self, sb: Storyboard) -> None:
        raise NotImplementedError

    def redo(self) -> None:
        sb = self._doc.storyboard
        if self._after is None:
            self._before = self._snapshot(sb)
            self.apply(sb)
            self._after = self._snapshot(sb)
        else:
            self._restore(sb, self._after)
        self._doc.notify_edited()

    def undo(self) -> None:
        self._restore(self._doc.storyboard, self._before)
        self._doc.notify_edited()

    def _snapshot(self, sb: Storyboard) -> dict:
        return {name: copy.deepcopy(getattr(sb, name)) for name in self.touches}

    @staticmethod
    def _restore(sb: Storyboard, snapshot: dict) -> None:
        for name, value in snapshot.items():
            setattr(sb, name, copy.deepcopy(value))


def describe_contact(c: Contact) -> str:
    """'A left hand \u2192 box1 anchor 2   [0\u201348]'."""
    held = f"{c.object} anchor {c.anchor}" if c.object is not None else f"{c.other_agent} {c.other_hand} hand"
    return f"{c.agent} {c.hand} hand \u2192 {held}   [{c.start}\u2013{c.end}]"


def find_keypose(sb: Storyboard, agent: str, frame: int) -> Keypose | None:
    return next((k for k in sb.keyposes if k.agent == agent and k.frame == frame), None)


# ---- keyposes -------------------------------------------------------------------------------
class SetKeypose(StoryboardCommand):
    """Add a keypose (or replace the one at that agent and frame). points (22, 2), mask (22,),
    depth (22,) where known (Keypose.depth; None keeps the replaced key's)."""
    touches = ("keyposes",)

    def __init__(self, document, agent: str, frame: int, points: np.ndarray, mask: np.ndarray,
                 text: str = "Add keypose", depth: np.ndarray | None = None):
        super().__init__(document, text)
        self._agent, self._frame = agent, frame
        self._points, self._mask = np.array(points, float), np.array(mask, bool)
        self._depth = None if depth is None else np.array(depth, float)

    def apply(self, sb):
        old = find_keypose(sb, self._agent, self._frame)
        timing = (old.hold, old.ease_in, old.ease_out) if old is not None else (0, False, False)  # kept
        depth = self._depth if self._depth is not None or old is None else old.depth
        sb.keyposes = [k for k in sb.keyposes if k is not old]
        sb.keyposes.append(Keypose(self._agent, self._frame, self._points.copy(), self._mask.copy(), *timing,
                                   None if depth is None else depth.copy()))


class SetKeyTiming(StoryboardCommand):
    """How long the keypose is held (frames) and whether the motion eases into and out of it."""
    touches = ("keyposes",)

    def __init__(self, document, agent: str, frame: int, hold: int, ease_in: bool, ease_out: bool):
        super().__init__(document, "Key timing")
        self._agent, self._frame, self._timing = agent, frame, (hold, ease_in, ease_out)

    def apply(self, sb):
        k = find_keypose(sb, self._agent, self._frame)
        k.hold, k.ease_in, k.ease_out = self._timing


class MoveKeyposeJoint(StoryboardCommand):
    """Place one joint of an existing keypose at uv (2,); also re-adds a removed joint."""
    touches = ("keyposes",)

    def __init__(self, document, agent: str, frame: int, joint: int, uv):
        super().__init__(document, "Move joint")
        self._agent, self._frame, self._joint, self._uv = agent, frame, joint, np.array(uv, float)

    def apply(self, sb):
        k = find_keypose(sb, self._agent, self._frame)
        k.points[self._joint] = self._uv
        k.mask[self._joint] = True


class DeleteKeyposeJoint(StoryboardCommand):
    """Unplace one joint; a keypose left without joints disappears."""
    touches = ("keyposes",)

    def __init__(self, document, agent: str, frame: int, joint: int):
        super().__init__(document, "Delete joint")
        self._agent, self._frame, self._joint = agent, frame, joint

    def apply(self, sb):
        k = find_keypose(sb, self._agent, self._frame)
        k.mask[self._joint] = False
        if not k.mask.any():
            sb.keyposes.remove(k)


class MirrorKeypose(StoryboardCommand):
    """Flip a keypose left-right (left joints become right joints) about where it stands: the
    middle of its feet (about the pelvis, a figure leaning over stepped 10 cm aside), else its
    pelvis."""
    touches = ("keyposes",)

    def __init__(self, document, agent: str, frame: int):
        super().__init__(document, "Mirror keypose")
        self._agent, self._frame = agent, frame

    def apply(self, sb):
        k = find_keypose(sb, self._agent, self._frame)
        feet = [j for j in FEET if k.mask[j]]
        centre = k.points[feet, 0].mean() if feet else k.points[0, 0] if k.mask[0] else k.points[k.mask, 0].mean()
        points, mask = k.points[list(MIRROR)].copy(), k.mask[list(MIRROR)].copy()
        points[:, 0] = 2 * centre - points[:, 0]
        k.points, k.mask = points, mask
        if k.depth is not None:
            k.depth = k.depth[list(MIRROR)].copy()


class DeleteKeypose(StoryboardCommand):
    touches = ("keyposes",)

    def __init__(self, document, agent: str, frame: int):
        super().__init__(document, "Delete keypose")
        self._agent, self._frame = agent, frame

    def apply(self, sb):
        sb.keyposes = [k for k in sb.keyposes if not (k.agent == self._agent and k.frame == self._frame)]


class RetimeKeyframe(StoryboardCommand):
    """Move the keys of one timeline track (an agent's keyposes or an object's keys) from one
    frame to another; a key already at the target frame is replaced (the timeline never asks:
    it stops a dragged key at its neighbours)."""
    touches = ("keyposes", "object_keys")

    def __init__(self, document, kind: str, owner: str, old: int, new: int):
        super().__init__(document, f"Retime keyframe {old} \u2192 {new}")
        self._kind, self._owner, self._old, self._new = kind, owner, old, new

    def apply(self, sb):
        keys = sb.keyposes if self._kind == "agent" else sb.object_keys
        attr = "agent" if self._kind == "agent" else "object"
        moving = [k for k in keys if getattr(k, attr) == self._owner and k.frame == self._old]
        keys[:] = [k for k in keys if not (getattr(k, attr) == self._owner and k.frame == self._new)]
        for k in moving:
            k.frame = self._new
            if self._kind == "agent":
                k.hold = min(k.hold, sb.length - 1 - k.frame)   # a hold stays inside the clip


# ---- strokes: trajectories and object paths ----------------------------------------------------
class AddStroke(StoryboardCommand):
    """Append a Trajectory (field "trajectories") or an ObjectPath (field "object_paths")."""

    def __init__(self, document, field: str, item, text: str = "Draw trajectory"):
        super().__init__(document, text)
        self.touches = (field,)
        self._item = item

    def apply(self, sb):
        getattr(sb, self.touches[0]).append(copy.deepcopy(self._item))


class ReplaceStroke(StoryboardCommand):
    """Replace a whole stroke, or the result of redrawing part of it."""

    def __init__(self, document, field: str, index: int, item, text: str = "Redraw trajectory"):
        super().__init__(document, text)
        self.touches = (field,)
        self._index, self._item = index, item

    def apply(self, sb):
        getattr(sb, self.touches[0])[self._index] = copy.deepcopy(self._item)


class EraseStroke(StoryboardCommand):
    def __init__(self, document, field: str, index: int):
        super().__init__(document, "Erase trajectory")
        self.touches = (field,)
        self._index = index

    def apply(self, sb):
        del getattr(sb, self.touches[0])[self._index]


# ---- objects -------------------------------------------------------------------------------------
class SetObjectKey(StoryboardCommand):
    """Set the silhouette outline (L, 2) of an object at a frame; creates the object if new, as
    large as it is drawn (engine.objects.drawn_size; the size fields change it after)."""
    touches = ("objects", "object_keys")

    def __init__(self, document, object_id: str, frame: int, outline: np.ndarray, kind: str = "box"):
        super().__init__(document, "Draw object")
        self._object, self._frame, self._outline, self._kind = object_id, frame, np.array(outline, float), kind

    def apply(self, sb):
        if self._object not in [o.id for o in sb.objects]:
            sb.objects.append(SceneObject(self._object, ObjectSpec(self._kind, drawn_size(self._kind, self._outline, sb.camera))))
        sb.object_keys = [k for k in sb.object_keys if not (k.object == self._object and k.frame == self._frame)]
        sb.object_keys.append(ObjectKey(self._object, self._frame, self._outline.copy()))


class MoveObjectKey(StoryboardCommand):
    touches = ("object_keys",)

    def __init__(self, document, index: int, delta):
        super().__init__(document, "Move object")
        self._index, self._delta = index, np.array(delta, float)

    def apply(self, sb):
        sb.object_keys[self._index].outline = sb.object_keys[self._index].outline + self._delta


class DeleteObjectKey(StoryboardCommand):
    touches = ("object_keys",)

    def __init__(self, document, index: int):
        super().__init__(document, "Delete object key")
        self._index = index

    def apply(self, sb):
        del sb.object_keys[self._index]


class SetObjectSpec(StoryboardCommand):
    """Change an object's type and size (metres, w x h x d); its anchors follow the new shape, and
    its drawings the new size (engine.objects.resized_outline)."""
    touches = ("objects", "object_keys")

    def __init__(self, document, object_id: str, kind: str, size: tuple[float, float, float]):
        super().__init__(document, "Change object")
        self._object, self._kind, self._size = object_id, kind, tuple(size)

    def apply(self, sb):
        obj = sb.objects[sb.object_index(self._object)]
        for key in (k for k in sb.object_keys if k.object == self._object):
            key.outline = resized_outline(key.outline, obj.spec.size, self._size, sb.camera)
        obj.spec = ObjectSpec(self._kind, self._size)


# ---- timing --------------------------------------------------------------------------------------
class SetTiming(StoryboardCommand):
    """A new frame rate (every key and span keeps its time) and then a new length in frames (what
    starts past the end goes; spans end there). length None: as long in time as before."""
    touches = ("fps", "length", "keyposes", "object_keys", *SPANS)

    def __init__(self, document, fps: float, length: int | None = None):
        super().__init__(document, "Change frame rate" if length is None else "Change length")
        self._fps, self._length = fps, length

    def apply(self, sb):
        timed = sb.retimed(self._fps)
        if self._length is not None:
            timed = timed.cut_to(self._length)
        for name in self.touches:
            setattr(sb, name, getattr(timed, name))


class SetText(StoryboardCommand):
    """What happens, in words (the storyboard's optional text; the model reads it with the sketch)."""
    touches = ("text",)

    def __init__(self, document, text: str):
        super().__init__(document, "Change text")
        self._text = text

    def apply(self, sb):
        sb.text = self._text


# ---- contacts ------------------------------------------------------------------------------------
class AddContact(StoryboardCommand):
    """Add a contact, the object holds' grips chosen again where it shares or crosses them
    (engine.grips: a 2D click on an object's side does not say which of its grips)."""
    touches = ("contacts",)

    def __init__(self, document, contact: Contact):
        super().__init__(document, "Add contact")
        self._contact = contact

    def apply(self, sb):
        sb.contacts.append(copy.deepcopy(self._contact))
        sb.contacts = with_grips_fitted(sb).contacts


class DeleteContact(StoryboardCommand):
    touches = ("contacts",)

    def __init__(self, document, index: int):
        super().__init__(document, "Delete contact")
        self._index = index

    def apply(self, sb):
        del sb.contacts[self._index]


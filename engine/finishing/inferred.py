"""Contacts the sketch leaves open, taken from the generated motion.

An artist may draw no contact at all: a thumbnail with a sentence under it ("the first person
hands the box to the second") leaves to the model who holds the object when. Finishing moves an
object only in the hands the storyboard says hold it, so it would leave that object where it was
sketched. For an object the storyboard gives no contact, a hand holds it wherever the generated
hand stays within `reach` of one of its anchors (the object where it was generated) while the
phase planner is in contact or carry, for at least `min_frames` frames.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..clip import MotionClip
from ..geometry.rotations import norm
from ..skeleton import HANDS
from ..storyboard import HANDS as HAND_NAMES
from ..storyboard import Contact, Storyboard
from .contacts import object_anchors
from .held import true_spans


@dataclass
class InferConfig:
    reach: float = 0.12          # m from a wrist to the anchor it holds
    min_frames: int = 6          # shorter touches are passing, not holding
    bridge: int = 3              # gaps of at most this many frames inside a hold are closed
    DURATIONS = ("min_frames", "bridge")


def with_generated_contacts(clip: MotionClip, storyboard: Storyboard, config: InferConfig = InferConfig()) -> Storyboard:
    """The storyboard with the holds of the generated clip added for every object it gives no
    contact (the clip's people in the storyboard's agent order, at its frame rate)."""
    if clip.obj_pose is None or not storyboard.objects:
        return storyboard
    open_objects = [o for o, obj in enumerate(storyboard.objects)
                    if not any(c.object == obj.id for c in storyboard.contacts)]
    if not open_objects:
        return storyboard
    n = clip.num_frames
    anchors = object_anchors(np.asarray(clip.obj_pose, float), storyboard)           # (N, O, K, 3)
    wrists = np.asarray(clip.joints, float)[:, :, list(HANDS)]                        # (N, H, 2, 3)
    engaged = np.ones(n, bool) if clip.phase is None else np.asarray(clip.phase)[:, 1:].sum(-1) > 0.5
    added = []
    for o in open_objects:
        dist = norm(wrists[:, :, :, None] - anchors[:, None, None, o])   # (N, H, 2, K)
        for h, agent in enumerate(storyboard.agents):
            for s, hand in enumerate(HAND_NAMES):
                near = (dist[:, h, s].min(-1) < config.reach) & engaged
                for start, end in _spans(near, config.bridge, config.min_frames):
                    anchor = int(np.bincount(dist[start:end + 1, h, s].argmin(-1)).argmax())
                    added.append(Contact(agent.id, hand, start, end, object=storyboard.objects[o].id, anchor=anchor))
    return replace(storyboard, contacts=[*storyboard.contacts, *added]) if added else storyboard


def _spans(mask: np.ndarray, bridge: int, min_frames: int) -> list[tuple[int, int]]:
    """Runs of True (first, last frame) after closing gaps of at most `bridge` frames, at least
    `min_frames` long."""
    merged: list[list[int]] = []
    for start, end in true_spans(mask):
        if merged and start - merged[-1][1] - 1 <= bridge:
            merged[-1][1] = end
        else:
            merged.append([start, end])
    return [(int(a), int(b)) for a, b in merged if b - a + 1 >= min_frames]

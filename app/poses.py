"""Starting points for new keyposes: the standing template (engine.poses), a copy of the
previous keyframe, a pose of the library or a copied pose placed where the figure stands; which
way a keypose faces."""
from __future__ import annotations

import numpy as np

from engine.facing import depth_of, facing, lift
from engine.poses import REACHES_FOR, library_pose, library_pose_2d, reach_of, standing_pose_2d
from engine.skeleton import FEET, JOINT_INDEX, NUM_JOINTS
from engine.storyboard import Keypose, Storyboard
from engine.synth.reach import heading_of


def previous_keypose(sb: Storyboard, agent: str, frame: int) -> Keypose | None:
    """The agent's latest keypose strictly before `frame`."""
    earlier = [k for k in sb.keyposes if k.agent == agent and k.frame < frame]
    return max(earlier, key=lambda k: k.frame) if earlier else None


def key_at_or_before(sb: Storyboard, agent: str, frame: int) -> Keypose | None:
    """The agent's keypose at `frame`, else its latest one before it."""
    return next((k for k in sb.keyposes if k.agent == agent and k.frame == frame), None) or previous_keypose(sb, agent, frame)


def new_keypose(sb: Storyboard, agent: str, frame: int) -> tuple[np.ndarray, np.ndarray]:
    """(points (22, 2), mask (22,)) for a keypose added at `frame`: the previous keyframe's pose,
    or a standing figure placed apart from the other agents."""
    previous = previous_keypose(sb, agent, frame)
    if previous is not None:
        return previous.points.copy(), previous.mask.copy()
    offset = 0.8 * (sb.agent_index(agent) - (len(sb.agents) - 1) / 2)
    points = standing_pose_2d(sb.camera) + (offset, 0.0)
    return points, np.ones(len(points), bool)


def stamped_pose(sb: Storyboard, agent: str, frame: int, name: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(points (22, 2), mask (22,), depth (22,)) of library pose `name` for the agent at `frame`,
    standing where the agent stands (see `placed_pose`), facing the way the agent's keypose before
    it faces (the library's poses all face +Z: a giver on the left held the box out away from the
    taker, a carrier turned back on the box at every key). A pose that reaches for a person or an
    object (engine.poses.REACHES_FOR) reaches towards the nearest one drawn then instead, to its
    left or right on the sketch."""
    mask = np.ones(NUM_JOINTS, bool)
    points, _ = placed_pose(sb, agent, frame, library_pose_2d(name, sb.camera), mask)
    yaw = _reach_yaw(sb, agent, frame, name, points[0])
    if yaw is None:
        yaw = _previous_facing(sb, agent, frame)
    points, mask = placed_pose(sb, agent, frame, library_pose_2d(name, sb.camera, yaw), mask)
    return points, mask, depth_of(library_pose(name, yaw), sb.camera)


def _reach_yaw(sb: Storyboard, agent: str, frame: int, name: str, pelvis: np.ndarray) -> float | None:
    """The yaw that turns library pose `name`'s reach to point along the sketch towards the
    nearest of what it reaches for, seen from `pelvis` (2,): another person (their keypose at
    `frame`, or the one before) or an object key at `frame`; None where there is none."""
    if REACHES_FOR.get(name) == "person":
        keys = [key_at_or_before(sb, a.id, frame) for a in sb.agents if a.id != agent]
        places = [k.points[0] for k in keys if k is not None and k.mask[0]]
    elif REACHES_FOR.get(name) == "object":
        places = [key.outline.mean(0) for key in sb.object_keys if key.frame == frame]
    else:
        places = []
    if not places:
        return None
    nearest = min(places, key=lambda p: float(np.linalg.norm(p - pelvis)))
    towards = np.sign(nearest[0] - pelvis[0]) or 1.0
    return float(heading_of(towards * sb.camera.basis()[0]) - heading_of(reach_of(name)))


def _previous_facing(sb: Storyboard, agent: str, frame: int) -> float:
    """The yaw of the agent's keypose before `frame` where its depths say it (a stamped or turned
    pose), else 0."""
    key = previous_keypose(sb, agent, frame)
    if key is None or key.depth is None or not key.mask[TURNABLE].all():
        return 0.0
    return facing(lift(key.points, sb.camera, key.depth))


def placed_pose(sb: Storyboard, agent: str, frame: int, points: np.ndarray, mask: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
    """A pose (points (22, 2), mask (22,)) moved to where the agent stands at `frame`: its feet on
    the feet of the agent's keypose there (or the one before), else its pelvis on that pelvis,
    else where a new keypose would go. A pose with neither feet nor pelvis is left where it is."""
    here = key_at_or_before(sb, agent, frame)
    feet = list(FEET)
    if here is not None and here.mask[feet].all() and mask[feet].all():
        shift = here.points[feet].mean(0) - points[feet].mean(0)
    elif mask[0]:
        target = here.points[0] if here is not None and here.mask[0] else new_keypose(sb, agent, frame)[0][0]
        shift = target - points[0]
    else:
        shift = np.zeros(2)
    return points + shift, mask.copy()


TURNABLE = list(FEET) + [JOINT_INDEX["l_hip"], JOINT_INDEX["r_hip"]]   # joints a facing is read from


def known_depth(doc, key: Keypose) -> np.ndarray | None:
    """The key's depths (engine.facing): its own, else the shown motion's at its frame, else None."""
    if key.depth is not None or not doc.clips:
        return key.depth
    joints = doc.clips[min(doc.variation, len(doc.clips) - 1)].joints
    h = doc.storyboard.agent_index(key.agent)
    if h >= joints.shape[1]:
        return None
    return depth_of(np.asarray(joints[min(key.frame, len(joints) - 1), h], float), doc.storyboard.camera)


def key_facing(doc, key: Keypose, points: np.ndarray | None = None) -> tuple[float, np.ndarray, bool] | None:
    """(yaw, world (3,) point under the feet, whether its depth is a guess) of a keypose (its
    points, or `points` (22, 2) while dragged); None when its feet or hips are not placed."""
    if not key.mask[TURNABLE].all():
        return None
    depth = known_depth(doc, key)
    joints = lift(key.points if points is None else points, doc.storyboard.camera, depth)
    return facing(joints), joints[list(FEET)].mean(0) * (1.0, 0.0, 1.0), depth is None

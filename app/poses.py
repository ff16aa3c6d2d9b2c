"""Starting points for new keyposes: the standing template (engine.poses), a copy of the
previous keyframe, a pose of the library or a copied pose placed where the figure stands; which
way a keypose faces."""
from __future__ import annotations

import numpy as np

from engine.facing import depth_of, facing, lift
from engine.poses import library_pose_2d, standing_pose_2d
from engine.skeleton import FEET, JOINT_INDEX
from engine.storyboard import Keypose, Storyboard


def previous_keypose(sb: Storyboard, agent: str, frame: int) -> Keypose | None:
    """The agent's latest keypose strictly before `frame`."""
    earlier = [k for k in sb.keyposes if k.agent == agent and k.frame < frame]
    return max(earlier, key=lambda k: k.frame) if earlier else None


def new_keypose(sb: Storyboard, agent: str, frame: int) -> tuple[np.ndarray, np.ndarray]:
    """(points (22, 2), mask (22,)) for a keypose added at `frame`: the previous keyframe's pose,
    or a standing figure placed apart from the other agents."""
    previous = previous_keypose(sb, agent, frame)
    if previous is not None:
        return previous.points.copy(), previous.mask.copy()
    offset = 0.8 * (sb.agent_index(agent) - (len(sb.agents) - 1) / 2)
    points = standing_pose_2d(sb.camera) + (offset, 0.0)
    return points, np.ones(len(points), bool)


def stamped_pose(sb: Storyboard, agent: str, frame: int, name: str) -> tuple[np.ndarray, np.ndarray]:
    """(points (22, 2), mask (22,)) of library pose `name` for the agent at `frame`, standing where
    the agent stands (see `placed_pose`)."""
    pose = library_pose_2d(name, sb.camera)
    return placed_pose(sb, agent, frame, pose, np.ones(len(pose), bool))


def placed_pose(sb: Storyboard, agent: str, frame: int, points: np.ndarray, mask: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
    """A pose (points (22, 2), mask (22,)) moved to where the agent stands at `frame`: its feet on
    the feet of the agent's keypose there (or the one before), else its pelvis on that pelvis,
    else where a new keypose would go. A pose with neither feet nor pelvis is left where it is."""
    here = next((k for k in sb.keyposes if k.agent == agent and k.frame == frame), None) or previous_keypose(sb, agent, frame)
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

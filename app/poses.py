"""Starting points for new keyposes: the standing template (engine.poses), a copy of the
previous keyframe, or a pose of the library stamped where the figure stands."""
from __future__ import annotations

import numpy as np

from engine.poses import library_pose_2d, standing_pose_2d
from engine.skeleton import FEET
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
    """(points (22, 2), mask (22,)) of library pose `name` for the agent at `frame`: standing where
    the agent's keypose there (or the one before) has its feet, else where a new keypose goes."""
    pose = library_pose_2d(name, sb.camera)
    standing = standing_pose_2d(sb.camera)
    here = next((k for k in sb.keyposes if k.agent == agent and k.frame == frame), None) or previous_keypose(sb, agent, frame)
    if here is not None and here.mask[list(FEET)].all():
        place = here.points[list(FEET)].mean(0) - standing[list(FEET)].mean(0)
    elif here is not None and here.mask[0]:
        place = here.points[0]
    else:                                        # no keypose yet: where a new one would stand
        place = new_keypose(sb, agent, frame)[0][0]
    return pose + place, np.ones(len(pose), bool)

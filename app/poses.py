"""Starting points for new keyposes: a standing figure, or a copy of the previous keyframe."""
from __future__ import annotations

import numpy as np

from engine.camera import StoryboardCamera
from engine.skeleton import JOINT_INDEX, rest_pose
from engine.storyboard import Keypose, Storyboard


def standing_pose_2d(camera: StoryboardCamera) -> np.ndarray:
    """A relaxed standing figure (arms down) seen through the storyboard camera, pelvis at the
    sketch origin: (22, 2) metres."""
    joints = rest_pose().copy()
    for side, sign in (("l_", 1.0), ("r_", -1.0)):
        shoulder = joints[JOINT_INDEX[side + "shoulder"]]
        elbow = shoulder + (0.04 * sign, -0.26, 0.0)
        joints[JOINT_INDEX[side + "elbow"]] = elbow
        joints[JOINT_INDEX[side + "wrist"]] = elbow + (0.02 * sign, -0.24, 0.05)
    uv = camera.project(joints)
    return uv - uv[0]


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

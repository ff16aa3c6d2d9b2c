"""Starting points for new keyposes: the standing template (engine.poses), or a copy of the
previous keyframe."""
from __future__ import annotations

import numpy as np

from engine.poses import standing_pose_2d
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

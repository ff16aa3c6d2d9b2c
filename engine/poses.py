"""The figure an artist starts a keypose from: the canvas's standing template."""
from __future__ import annotations

import numpy as np

from .camera import StoryboardCamera
from .skeleton import JOINT_INDEX, rest_pose


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

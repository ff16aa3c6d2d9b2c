"""People as capsules (engine.body's model): tapered cylinders along the bones, spheres at the
joints, a skull and hands.

Instance rows are what the shaders read (see shaders/capsule.vert and shaders/sphere.vert):
  bones   (B, 12) float32: start xyz, end xyz, start radius, end radius, linear rgba
  spheres (S, 8)  float32: centre xyz, radius, linear rgba
"""
from __future__ import annotations

import numpy as np

from ..body import BONE_RADII, BONES, HAND_RADIUS, HEAD_RADIUS, JOINT_RADII, hand_centres, head_centre


def body_instances(joints: np.ndarray, rgba: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """One person's capsules. joints (22, 3), rgba (4,) linear colour.

    Returns bones (B, 12) and spheres (S, 8) instance rows.
    """
    joints = np.asarray(joints, np.float32)
    rgba = np.asarray(rgba, np.float32)
    bones = np.empty((len(BONES), 12), np.float32)
    bones[:, 0:3] = joints[BONES[:, 0]]
    bones[:, 3:6] = joints[BONES[:, 1]]
    bones[:, 6:8] = BONE_RADII
    bones[:, 8:12] = rgba
    centres = np.concatenate([joints, hand_centres(joints), head_centre(joints)[None]])
    radii = np.concatenate([JOINT_RADII, [HAND_RADIUS, HAND_RADIUS, HEAD_RADIUS]])
    spheres = np.empty((len(centres), 8), np.float32)
    spheres[:, 0:3] = centres
    spheres[:, 3] = radii
    spheres[:, 4:8] = rgba
    return bones, spheres

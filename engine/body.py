"""The one body model: a radius per joint, capsules along the bones, and what drawing adds.

Everything that needs a body's volume reads it here: the penetration metric and the guidance
energy (so that what guidance minimises is what Pen measures), finishing's reach and collision
checks, the exported meshes and the viewport's capsules. Collision uses a sphere at every joint
and at every bone's midpoint (the midpoint's radius the mean of its ends'), approximating the
capsules; drawing shows the capsules themselves, plus a skull above the head joint and hands a
little past the wrists.
"""
from __future__ import annotations

import numpy as np

from .geometry.rotations import norm
from .skeleton import JOINT_INDEX, PARENTS

J = JOINT_INDEX
BONES = np.array([(p, c) for c, p in enumerate(PARENTS) if p >= 0])   # (21, 2) parent, child
_RADIUS = {"pelvis": 0.10, "l_hip": 0.07, "spine1": 0.10, "l_knee": 0.05, "spine2": 0.10,
           "l_ankle": 0.04, "spine3": 0.10, "l_foot": 0.03, "neck": 0.05, "l_collar": 0.06,
           "head": 0.09, "l_shoulder": 0.05, "l_elbow": 0.04, "l_wrist": 0.02}
JOINT_RADII = np.array([_RADIUS[n.replace("r_", "l_")] for n in JOINT_INDEX])      # (22,) metres
BONE_RADII = JOINT_RADII[BONES]                                    # (21, 2) at the parent, the child
SPHERE_RADII = np.concatenate([JOINT_RADII, BONE_RADII.mean(1)])     # (43,) joints, then bone midpoints

HEAD_RADIUS = 0.105   # the drawn skull, above the head joint along the neck
HAND_RADIUS = 0.042   # the drawn hand, past the wrist along the forearm
HAND_REACH = 0.07


def body_points(joints: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Collision spheres of a body: joints (..., 22, 3) -> centres (..., 43, 3), radii (43,)."""
    mids = 0.5 * (joints[..., BONES[:, 0], :] + joints[..., BONES[:, 1], :])
    return np.concatenate([joints, mids], axis=-2), SPHERE_RADII


def hand_centres(joints: np.ndarray) -> np.ndarray:
    """(..., 22, 3) -> (..., 2, 3) left and right hand centres, a little past the wrists."""
    wrists = joints[..., [J["l_wrist"], J["r_wrist"]], :]
    forearm = wrists - joints[..., [J["l_elbow"], J["r_elbow"]], :]
    length = np.maximum(norm(forearm, keepdims=True), 1e-6)
    return wrists + HAND_REACH * forearm / length


def head_centre(joints: np.ndarray) -> np.ndarray:
    """(..., 22, 3) -> (..., 3): the skull sits above the head joint, along the neck."""
    neck = joints[..., J["head"], :] - joints[..., J["neck"], :]
    length = np.maximum(norm(neck, keepdims=True), 1e-6)
    return joints[..., J["head"], :] + 0.06 * neck / length

"""People as capsules: tapered cylinders along the bones, spheres at the joints, a head.

Instance rows are what the shaders read (see shaders/capsule.vert and shaders/sphere.vert):
  bones   (B, 12) float32: start xyz, end xyz, start radius, end radius, linear rgba
  spheres (S, 8)  float32: centre xyz, radius, linear rgba
"""
from __future__ import annotations

import numpy as np

from ..skeleton import JOINT_INDEX, NUM_JOINTS

J = JOINT_INDEX
# (from joint, to joint, radius at from, radius at to), metres: a slim neutral adult.
BONES = (
    ("pelvis", "spine1", 0.105, 0.10), ("spine1", "spine2", 0.10, 0.10),
    ("spine2", "spine3", 0.10, 0.095), ("spine3", "neck", 0.07, 0.05), ("neck", "head", 0.05, 0.05),
    ("pelvis", "l_hip", 0.09, 0.08), ("pelvis", "r_hip", 0.09, 0.08),
    ("l_hip", "l_knee", 0.075, 0.056), ("r_hip", "r_knee", 0.075, 0.056),
    ("l_knee", "l_ankle", 0.054, 0.04), ("r_knee", "r_ankle", 0.054, 0.04),
    ("l_ankle", "l_foot", 0.04, 0.035), ("r_ankle", "r_foot", 0.04, 0.035),
    ("spine3", "l_collar", 0.075, 0.06), ("spine3", "r_collar", 0.075, 0.06),
    ("l_collar", "l_shoulder", 0.06, 0.052), ("r_collar", "r_shoulder", 0.06, 0.052),
    ("l_shoulder", "l_elbow", 0.05, 0.04), ("r_shoulder", "r_elbow", 0.05, 0.04),
    ("l_elbow", "l_wrist", 0.039, 0.031), ("r_elbow", "r_wrist", 0.039, 0.031),
)
BONE_INDEX = np.array([(J[a], J[b]) for a, b, _, _ in BONES])        # (B, 2)
BONE_RADII = np.array([(ra, rb) for _, _, ra, rb in BONES], np.float32)  # (B, 2)
HEAD_RADIUS = 0.105
HAND_RADIUS = 0.042
HAND_REACH = 0.07  # hand centre beyond the wrist, along the forearm


def _joint_radii() -> np.ndarray:
    """Each joint's sphere closes the capsules that meet there: the largest bone end radius."""
    r = np.zeros(NUM_JOINTS, np.float32)
    for (a, b), (ra, rb) in zip(BONE_INDEX, BONE_RADII):
        r[a], r[b] = max(r[a], ra), max(r[b], rb)
    return r


JOINT_RADII = _joint_radii()


def hand_centres(joints: np.ndarray) -> np.ndarray:
    """(..., 22, 3) -> (..., 2, 3) left and right hand centres, a little past the wrists."""
    wrists = joints[..., [J["l_wrist"], J["r_wrist"]], :]
    forearm = wrists - joints[..., [J["l_elbow"], J["r_elbow"]], :]
    length = np.maximum(np.linalg.norm(forearm, axis=-1, keepdims=True), 1e-6)
    return wrists + HAND_REACH * forearm / length


def head_centre(joints: np.ndarray) -> np.ndarray:
    """(..., 22, 3) -> (..., 3): the skull sits above the head joint, along the neck."""
    neck = joints[..., J["head"], :] - joints[..., J["neck"], :]
    length = np.maximum(np.linalg.norm(neck, axis=-1, keepdims=True), 1e-6)
    return joints[..., J["head"], :] + 0.06 * neck / length


def body_instances(joints: np.ndarray, rgba: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """One person's capsules. joints (22, 3), rgba (4,) linear colour.

    Returns bones (B, 12) and spheres (S, 8) instance rows.
    """
    joints = np.asarray(joints, np.float32)
    rgba = np.asarray(rgba, np.float32)
    bones = np.empty((len(BONES), 12), np.float32)
    bones[:, 0:3] = joints[BONE_INDEX[:, 0]]
    bones[:, 3:6] = joints[BONE_INDEX[:, 1]]
    bones[:, 6:8] = BONE_RADII
    bones[:, 8:12] = rgba
    centres = np.concatenate([joints, hand_centres(joints), head_centre(joints)[None]])
    radii = np.concatenate([JOINT_RADII, [HAND_RADIUS, HAND_RADIUS, HEAD_RADIUS]])
    spheres = np.empty((len(centres), 8), np.float32)
    spheres[:, 0:3] = centres
    spheres[:, 3] = radii
    spheres[:, 4:8] = rgba
    return bones, spheres

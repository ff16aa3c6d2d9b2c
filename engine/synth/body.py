"""Posing one person from a plan: ground track, heading, footwork and hand goals -> joints.

The torso is posed with rotations (a one-parameter crouch: hips drop and move back while the
trunk bends forward), the legs and arms with exact-length two-bone IK onto the feet and hand
goals, and the local rotations come from `skeleton.inverse_kinematics` with the person's own
offsets; the returned joints are the forward kinematics of those rotations, so bone lengths
are exact. The crouch at each frame is the least one that brings both shoulders within reach
of the hands' targets, eased in time so that people bend down before their hands arrive.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..skeleton import (ANKLES, ELBOWS, FEET, HANDS, HIPS, JOINT_INDEX, JOINT_NAMES, KNEES, NUM_JOINTS,
                        REST_OFFSETS, SHOULDERS, forward_kinematics, inverse_kinematics)
from .gait import FOOT_HEIGHT, Footwork
from .reach import pitch_matrix, to_local, two_bone_ik, yaw_matrix
from .trajectory import smoothstep

J = JOINT_INDEX
SIDES = (1.0, -1.0)  # left is +X in the heading frame
_GROUPS = {"legs": ("knee", "ankle", "foot"), "arms": ("elbow", "wrist"),
           "spine": ("spine1", "spine2", "spine3", "neck", "head")}


@dataclass
class BodyConfig:
    max_bend: float = np.deg2rad(95)   # total forward bend (hips + spine) at full crouch
    hip_share: float = 0.4             # part of the bend taken at the hips
    crouch_drop: float = 0.47          # m the pelvis drops at full crouch (scale 1)
    hips_back: float = 0.22            # m the pelvis moves back at full crouch (scale 1)
    squat_onset: float = 1.6           # exponent: how late in the crouch the pelvis drops
    reach: float = 0.92                # share of arm length a comfortable reach uses
    crouch_lead: float = 0.6           # s over which people bend before/after a hold
    knee_slack: float = 0.975          # legs never straighter than this share of their length
    arm_swing: float = 0.5             # hand swing per metre of the same foot's stride offset
    head_level: float = 0.5            # share of the bend the neck and head undo
    crouch_steps: int = 41


@dataclass
class Body:
    offsets: np.ndarray   # (22, 3) this person's bone offsets
    scale: float

    def length(self, joint: str) -> float:
        return float(np.linalg.norm(self.offsets[J[joint]]))

    @property
    def thigh(self) -> float:
        return self.length("l_knee")

    @property
    def shin(self) -> float:
        return self.length("l_ankle")

    @property
    def upper_arm(self) -> float:
        return self.length("l_elbow")

    @property
    def forearm(self) -> float:
        return self.length("l_wrist")

    @property
    def arm(self) -> float:
        return self.upper_arm + self.forearm

    def standing_height(self, config: BodyConfig = BodyConfig()) -> float:
        """Pelvis height when standing with slightly soft knees."""
        return (FOOT_HEIGHT - self.offsets[J["l_foot"], 1] - self.offsets[J["l_hip"], 1]
                + config.knee_slack * (self.thigh + self.shin))

    def rest_joints(self, config: BodyConfig = BodyConfig()) -> np.ndarray:
        """(22, 3) rest pose with the pelvis at standing height above the origin."""
        return forward_kinematics(np.array([0.0, self.standing_height(config), 0.0]),
                                  np.broadcast_to(np.eye(3), (NUM_JOINTS, 3, 3)), self.offsets)

    def stance(self, config: BodyConfig = BodyConfig()) -> np.ndarray:
        """(2, 3) standing foot-joint positions in the heading frame."""
        feet = self.rest_joints(config)[list(FEET)]
        feet[:, 1] = FOOT_HEIGHT
        return feet

    def shoulder_height(self, config: BodyConfig = BodyConfig()) -> float:
        return float(self.rest_joints(config)[SHOULDERS[0], 1])


def make_body(rng: np.random.Generator, scale_range: tuple[float, float] = (0.9, 1.1),
              proportion_jitter: float = 0.04) -> Body:
    """A person: the template scaled, with legs, arms and spine varied a little on their own."""
    scale = float(rng.uniform(*scale_range))
    offsets = REST_OFFSETS * scale
    for parts in _GROUPS.values():
        factor = rng.uniform(1 - proportion_jitter, 1 + proportion_jitter)
        for j, name in enumerate(JOINT_NAMES):
            if name.split("_")[-1] in parts:
                offsets[j] *= factor
    return Body(offsets=offsets, scale=scale)


def _torso_rotations(yaw: np.ndarray, bend: np.ndarray, config: BodyConfig) -> np.ndarray:
    """Local rotations (N, 22, 3, 3) for heading + crouch bend; limbs are left at identity."""
    n = len(yaw)
    rot = np.broadcast_to(np.eye(3), (n, NUM_JOINTS, 3, 3)).copy()
    rot[:, 0] = yaw_matrix(yaw) @ pitch_matrix(config.hip_share * bend)
    spine = pitch_matrix((1 - config.hip_share) * bend / 3)
    for name in ("spine1", "spine2", "spine3"):
        rot[:, J[name]] = spine
    level = pitch_matrix(-config.head_level * bend / 2)
    rot[:, J["neck"]] = level
    rot[:, J["head"]] = level
    return rot


def _torso_placement(body: Body, crouch: np.ndarray, config: BodyConfig) -> tuple[np.ndarray, np.ndarray]:
    """Pelvis height (N,) and backward shift (N,) for crouch amounts in [0, 1]. A slight crouch is
    mostly a lean; the knees bend in earnest only for low reaches."""
    squat = crouch ** config.squat_onset
    height = body.standing_height(config) - config.crouch_drop * body.scale * squat
    return height, -config.hips_back * body.scale * squat


def crouch_needed(body: Body, ground: np.ndarray, yaw: np.ndarray, target: np.ndarray,
                  active: np.ndarray, config: BodyConfig = BodyConfig()) -> np.ndarray:
    """Least crouch (N,) in [0, 1] that puts each active hand's target within comfortable reach.

    target: (N, 2, 3) world hand targets; active: (N, 2) bool.
    """
    grid = np.linspace(0.0, 1.0, config.crouch_steps)
    height, back = _torso_placement(body, grid, config)
    rot = _torso_rotations(np.zeros_like(grid), grid * config.max_bend, config)
    root = np.stack([np.zeros_like(grid), height, back], axis=-1)
    shoulders = forward_kinematics(root, rot, body.offsets)[:, list(SHOULDERS)]     # (C, 2, 3)
    local = to_local(target, ground, yaw)                                            # (N, 2, 3)
    dist = np.linalg.norm(local[:, None] - shoulders[None], axis=-1)                 # (N, C, 2)
    excess = np.where(active[:, None], dist - config.reach * body.arm, -1.0).max(axis=-1)
    ok = excess <= 0
    first = np.argmax(ok, axis=1)
    crouch = np.where(ok.any(axis=1), grid[first], grid[np.argmin(excess, axis=1)])
    # Interpolate between the last failing and the first passing grid step for smooth motion.
    prev = np.maximum(first - 1, 0)
    rows = np.arange(len(first))
    e0, e1 = excess[rows, prev], excess[rows, first]
    frac = np.where((first > 0) & ok.any(axis=1), e0 / np.maximum(e0 - e1, 1e-9), 1.0)
    crouch = np.where(first > 0, grid[prev] + frac * (grid[first] - grid[prev]), crouch)
    return np.where(active.any(axis=1), crouch, 0.0)


def ease_crouch(crouch: np.ndarray, fps: float, lead: float) -> np.ndarray:
    """Each frame takes the most any frame within `lead` seconds asks for, faded by distance in
    time, so the crouch never falls short of what a hold needs. (N,) -> (N,)."""
    t = np.arange(len(crouch)) / fps
    fade = 1.0 - smoothstep(np.abs(t[:, None] - t[None, :]) / lead)
    return np.max(crouch[None, :] * fade, axis=1)


def pose_person(body: Body, ground: np.ndarray, yaw: np.ndarray, footwork: Footwork,
                hand_target: np.ndarray, hand_weight: np.ndarray, fps: float,
                config: BodyConfig = BodyConfig()) -> tuple[np.ndarray, np.ndarray]:
    """Joints (N, 22, 3) and local rotations (N, 22, 3, 3) of one person.

    ground: (N, 3) ground point; yaw: (N,) heading; hand_target: (N, 2, 3) where each wrist
    goes when its weight (N, 2) is 1 (weights in between blend from the free-swinging hand).
    """
    n = len(ground)
    heading = yaw_matrix(yaw)
    crouch = ease_crouch(crouch_needed(body, ground, yaw, hand_target, hand_weight > 0.5, config),
                         fps, config.crouch_lead)
    height, back = _torso_placement(body, crouch, config)
    rot = _torso_rotations(yaw, crouch * config.max_bend, config)
    pelvis = ground + heading[:, :, 2] * back[:, None]

    # Ankle targets under flat feet, and the highest pelvis the legs can reach them from.
    foot_vec = np.einsum("nfij,fj->nfi", yaw_matrix(footwork.foot_yaw), body.offsets[list(FEET)])
    ankle_goal = footwork.feet - foot_vec
    hip_rel = np.einsum("nij,hj->nhi", rot[:, 0], body.offsets[list(HIPS)])              # (N, 2, 3)
    horiz = np.linalg.norm((pelvis[:, None] + hip_rel - ankle_goal)[..., [0, 2]], axis=-1)
    longest = config.knee_slack * (body.thigh + body.shin)
    top = ankle_goal[..., 1] + np.sqrt(np.maximum(longest ** 2 - horiz ** 2, 0.0)) - hip_rel[..., 1]
    pelvis[:, 1] = np.minimum(height + footwork.bob, top.min(axis=1))

    joints = forward_kinematics(pelvis, rot, body.offsets)
    forward = heading[:, :, 2]
    for leg in range(2):
        knee, ankle = two_bone_ik(joints[:, HIPS[leg]], ankle_goal[:, leg], body.thigh, body.shin,
                                  forward + 0.1 * SIDES[leg] * heading[:, :, 0])
        joints[:, KNEES[leg]] = knee
        joints[:, ANKLES[leg]] = ankle
        joints[:, FEET[leg]] = ankle + foot_vec[:, leg]

    # Free hands hang and swing opposite to the same-side foot.
    feet_local = to_local(footwork.feet, ground, yaw)
    stance = body.stance(config)
    for arm in range(2):
        side = SIDES[arm]
        swing = -config.arm_swing * (feet_local[:, arm, 2] - stance[arm, 2])
        hang = np.stack([np.full(n, 0.12 * side), -np.ones(n), np.clip(swing, -0.5, 0.5)], -1)
        hang *= 0.96 * body.arm / np.linalg.norm(hang, axis=-1, keepdims=True)
        shoulder = joints[:, SHOULDERS[arm]]
        free = shoulder + np.einsum("nij,nj->ni", heading, hang)
        w = hand_weight[:, arm, None]
        goal = free + (hand_target[:, arm] - free) * w
        pole = np.einsum("nij,j->ni", heading, np.array([0.8 * side, -1.0, -0.6]))
        elbow, wrist = two_bone_ik(shoulder, goal, body.upper_arm, body.forearm, pole)
        joints[:, ELBOWS[arm]] = elbow
        joints[:, HANDS[arm]] = wrist

    local_rot = inverse_kinematics(joints, body.offsets)
    return forward_kinematics(joints[:, 0], local_rot, body.offsets), local_rot

"""Holders crouch and lean to grips below their reach: a box picked up from the floor, or put down.

The generated motion often reaches a box on the floor with its feet sunk into the floor; stood
on the ground, the same body's hands are 10-20 cm above the grips, so a pick-up took the box late
(an artist-style storyboard's hands 4 cm off their grips). Here each holder lowers (the whole
body, upright) by what its held grips lie below the reach of its shoulders, the legs bending
back to the feet where they stand, as far as a squat goes; what is still out of reach it leans
forward for, the upper body pitching about the pelvis. Joint arrays are (N, H, 22, 3) in metres.
"""
from __future__ import annotations

import numpy as np
from scipy.ndimage import gaussian_filter1d, maximum_filter1d

from ..body import body_points
from ..geometry.rotations import axis_angle_to_matrix, cross, norm, normalize
from ..objects import world_to_local
from ..rig import SUBTREE
from ..skeleton import ANKLES, FEET, HIPS, JOINT_INDEX, KNEES, SHOULDERS
from ..storyboard import HANDS as HAND_NAMES
from ..storyboard import Storyboard
from ..synth.reach import UP
from .contacts import ContactConfig, arm_lengths, forward_of, object_anchors, span_weight
from .feet import reach_with_legs
from .held import BODY_SPHERES
from .keys import room_from_keys
from .limbs import DEEPER


UPPER_BODY = SUBTREE[JOINT_INDEX["spine1"]]   # the spine and all it carries: what a lean pitches forward


def _cone(values: np.ndarray, rate: float, up: bool) -> np.ndarray:
    """values (N, H) >= 0 with slopes of at most `rate` a frame: raised to the largest of each and
    every other one less `rate` per frame apart (up), or lowered to the least of each and every
    other one plus that (not up)."""
    out, pick, sign = values.copy(), (np.maximum if up else np.minimum), (-1.0 if up else 1.0)
    for shift in range(1, int(np.ceil(values.max() / rate)) + 1):
        out[shift:] = pick(out[shift:], values[:-shift] + sign * rate * shift)
        out[:-shift] = pick(out[:-shift], values[shift:] + sign * rate * shift)
    return out


def _crouched(poses: np.ndarray, drop: np.ndarray) -> np.ndarray:
    """One person's poses (M, 22, 3) lowered by drop (M,), the legs re-solved to the same feet."""
    return reach_with_legs(poses - drop[:, None, None] * UP, poses[:, list(FEET)])


def _depth(poses: np.ndarray, objects: tuple[np.ndarray, list], partners: np.ndarray | None = None) -> np.ndarray:
    """How deep (M,) the deepest body sphere but the arms' of poses (M, 22, 3) is in any object
    (objects: poses (M, O, 7), specs) or in the body of another person (partners (M, P, 22, 3),
    their spheres but the arms' likewise)."""
    points, radii = body_points(poses)
    points, radii = points[:, BODY_SPHERES], radii[BODY_SPHERES]
    pose, specs = objects
    depth = [spec.penetration_local(world_to_local(points, pose[:, o]), radii).max(-1) for o, spec in enumerate(specs)]
    if partners is not None and partners.shape[1]:
        others = body_points(partners)[0][:, :, BODY_SPHERES]                         # (M, P, S, 3)
        apart = norm(points[:, None, :, None] - others[:, :, None])                  # (M, P, S, S)
        depth.append((radii[:, None] + radii[None] - apart).max(axis=(1, 2, 3)))
    return np.max(depth, axis=0) if depth else np.zeros(len(poses))


def _leaned(poses: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """One person's poses (M, 22, 3) with the upper body pitched forward about the pelvis by
    angle (M,) radians, the hips and legs where they were."""
    axis = normalize(cross(UP, forward_of(poses)))                                  # (M, 3)
    turn = axis_angle_to_matrix(axis * angle[:, None])                                  # (M, 3, 3)
    out = poses.copy()
    pivot = poses[:, :1]
    out[:, UPPER_BODY] = pivot + np.einsum("mij,mkj->mki", turn, poses[:, UPPER_BODY] - pivot)
    return out


def _shortfall(joints: np.ndarray, anchors: np.ndarray, storyboard: Storyboard, config: ContactConfig) -> np.ndarray:
    """How far (N, H) each holder's shoulders must come down for every grip it holds (anchors
    (N, O, K, 3) world; over each contact span, easing in and out over blend_frames) to lie within
    `reach` of the arm; none where the grip is beyond reach across (step_within_reach steps
    towards it)."""
    n, h = joints.shape[:2]
    need, arms, frames = np.zeros((n, h)), arm_lengths(joints), np.arange(n)
    for c in storyboard.contacts:
        if c.object is None:
            continue
        a, side, o = storyboard.agent_index(c.agent), HAND_NAMES.index(c.hand), storyboard.object_index(c.object)
        grip = anchors[np.clip(frames, c.start, c.end), o, c.anchor]                    # (N, 3)
        shoulder = joints[:, a, SHOULDERS[side]]
        reach = config.reach * arms[:, a, side]
        across = norm((grip - shoulder)[:, [0, 2]])
        below = np.sqrt(np.maximum(reach ** 2 - across ** 2, 0.0))                    # the lowest it reaches
        short = np.where(across < reach, shoulder[:, 1] - grip[:, 1] - below, 0.0)
        need[:, a] = np.maximum(need[:, a], span_weight(n, c.start, c.end, config.blend_frames) * short)
    return np.maximum(need, 0.0)


def _squat(joints: np.ndarray, short: np.ndarray, config: ContactConfig) -> np.ndarray:
    """How far (N, H) each holder lowers for a shortfall (N, H): all of it, the pelvis no lower than
    `lowest_squat` of the legs' length."""
    legs = (norm(joints[:, :, list(KNEES)] - joints[:, :, list(HIPS)])
            + norm(joints[:, :, list(ANKLES)] - joints[:, :, list(KNEES)])).mean(-1)   # (N, H)
    return np.clip(short, 0.0, np.maximum(joints[:, :, 0, 1] - config.lowest_squat * legs, 0.0))


def _lean(joints: np.ndarray, short: np.ndarray, config: ContactConfig) -> np.ndarray:
    """The forward pitch (N, H) radians that brings each holder's shoulders down by what a
    shortfall (N, H) asks, the trunk leaning at most `most_lean` degrees from upright."""
    trunk = joints[:, :, list(SHOULDERS)].mean(2) - joints[:, :, 0]                    # pelvis -> shoulders
    length = np.maximum(norm(trunk), 1e-9)
    tilt = np.arccos(np.clip(trunk[..., 1] / length, -1.0, 1.0))
    lowest = np.cos(np.radians(config.most_lean))
    return np.maximum(np.arccos(np.clip(np.cos(tilt) - short / length, lowest, 1.0)) - tilt, 0.0)


def _paced(amount: np.ndarray, rate: float, storyboard: Storyboard, config: ContactConfig) -> np.ndarray:
    """amount (N, H) >= 0 reached by the time it is wanted and let go of after, at most `rate` a
    frame (smoothed over crouch_sigma frames), easing to none at each person's key frames (the
    warp placed those poses)."""
    amount = gaussian_filter1d(_cone(amount, rate, up=True), config.crouch_sigma, axis=0, mode="nearest")
    return np.minimum(amount, room_from_keys(storyboard, len(amount), rate, config.key_ease_frames))


def _no_deeper(poses: np.ndarray, amount: np.ndarray, move, objects: tuple[np.ndarray, list],
               partners: np.ndarray, rate: float) -> np.ndarray:
    """One person's poses (N, 22, 3) moved by move(poses, amount) (amount (N,) >= 0), where that
    takes a body sphere but the arms' deeper into an object (objects: poses (N, O, 7), specs) or
    into the partners' bodies (partners (N, P, 22, 3)) by half or a quarter of it, else not at
    all, the cut paced at `rate` a frame either side."""
    out, at = poses.copy(), np.flatnonzero(amount > 1e-4)
    if not len(at):
        return out
    # Clear of them, it may come up to them.
    still = np.maximum(_depth(poses[at], (objects[0][at], objects[1]), partners[at]), 0.0)
    allowed, left = amount[at].copy(), np.arange(len(at))       # left: the frames it takes deeper
    for share in (1.0, 0.5, 0.25):
        f = at[left]
        moved = move(poses[f], share * amount[f])
        if share == 1.0:
            out[at] = moved
        allowed[left] = share * amount[f]
        left = left[_depth(moved, (objects[0][f], objects[1]), partners[f]) > still[left] + DEEPER]
        if not len(left):
            break
    allowed[left] = 0.0
    if (allowed < amount[at]).any():   # as slowly back as there
        limit = amount.copy()
        limit[at] = allowed
        amount = np.minimum(amount, _cone(limit[:, None], rate, up=False)[:, 0])
        out[at] = move(poses[at], amount[at])
    return out


def _each_no_deeper(joints: np.ndarray, amount: np.ndarray, move, objects: tuple[np.ndarray, list],
                    rate: float) -> np.ndarray:
    """joints (N, H, 22, 3) with each person in turn moved by move(poses, amount[:, h]) (_no_deeper),
    no deeper into anyone else either, as moved so far (two people leaning over a box from either
    side put their heads 14 cm into each other)."""
    out = joints.copy()
    for a in range(joints.shape[1]):
        out[:, a] = _no_deeper(joints[:, a], amount[:, a], move, objects, np.delete(out, a, axis=1), rate)
    return out


def crouch_to_grips(joints: np.ndarray, obj_pose: np.ndarray, storyboard: Storyboard,
                    config: ContactConfig = ContactConfig()) -> np.ndarray:
    """joints (N, H, 22, 3), obj_pose (N, O, 7) -> joints with each holder lowered where its held
    grips lie below its reach (_shortfall), going down and up at crouch_frames_per_metre (smoothed
    over crouch_sigma), then leaning forward for what is still out of reach (people putting a box
    down lean 55-67 degrees), easing in and out over lean_sigma; upright at its key frames (the
    warp placed those poses), and never taking a body sphere but the arms' deeper into an object
    (a knee went 2 cm further into a box put down): there, only as deep as that allows."""
    joints = np.asarray(joints, float)
    anchors = object_anchors(obj_pose, storyboard)
    short = _shortfall(joints, anchors, storyboard, config)
    if not short.any():
        return joints
    objects = (np.asarray(obj_pose, float), [o.spec for o in storyboard.objects])
    # Down by the span's start, up after its end (to a grip one frame after another, a squat
    # of 40 cm took three frames).
    rate = 1.0 / config.crouch_frames_per_metre
    drop = _paced(_squat(joints, short, config), rate, storyboard, config)
    out = _each_no_deeper(joints, drop, _crouched, objects, rate)
    # A lean eases in and out, the way a body bends (paced like the squat, at a fixed rate, it bent
    # over for two seconds: 20 artist-style storyboards' pops within 5 cm 16 -> 13)
    lean = _lean(out, _shortfall(out, anchors, storyboard, config), config)
    wide = 2 * round(2 * config.lean_sigma) + 1   # bent over by the time the grip needs it
    lean = gaussian_filter1d(maximum_filter1d(lean, wide, axis=0), config.lean_sigma, axis=0, mode="nearest")
    rate = 1.0 / config.lean_frames_per_radian
    lean = _paced(lean, rate, storyboard, config)
    return _each_no_deeper(out, lean, _leaned, objects, rate)

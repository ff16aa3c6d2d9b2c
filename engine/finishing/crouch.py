"""Holders crouch to grips below their reach: a box picked up from the floor.

The generated motion often reaches a box on the floor with its feet sunk into the floor; stood
on the ground, the same body's hands are 10-20 cm above the grips, so a pick-up took the box late
(an artist-style storyboard's hands 4 cm off their grips). Here each holder lowers (the whole
body, upright) by what its held grips lie below the reach of its shoulders, the legs bending
back to the feet where they stand. Joint arrays are (N, H, 22, 3) in metres.
"""
from __future__ import annotations

import numpy as np
from scipy.ndimage import gaussian_filter1d

from ..body import body_points
from ..geometry.rotations import norm
from ..objects import world_to_local
from ..skeleton import ANKLES, FEET, HIPS, KNEES, SHOULDERS
from ..storyboard import HANDS as HAND_NAMES
from ..storyboard import Storyboard
from ..synth.reach import UP
from .contacts import ContactConfig, arm_lengths, object_anchors, span_weight
from .feet import reach_with_leg
from .held import BODY_SPHERES
from .keys import key_frames
from .limbs import DEEPER


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
    out = poses - drop[:, None, None] * UP
    for side, foot in enumerate(FEET):
        out = reach_with_leg(out, side, poses[:, foot])
    return out


def _depth(poses: np.ndarray, objects: tuple[np.ndarray, list]) -> np.ndarray:
    """How deep (M,) the deepest body sphere but the arms' of poses (M, 22, 3) is in any object
    (objects: poses (M, O, 7), specs)."""
    points, radii = body_points(poses)
    points = points[:, BODY_SPHERES]
    pose, specs = objects
    depth = [spec.penetration_local(world_to_local(points, pose[:, o]), radii[BODY_SPHERES]).max(-1)
             for o, spec in enumerate(specs)]
    return np.max(depth, axis=0)


def _need(joints: np.ndarray, anchors: np.ndarray, storyboard: Storyboard, config: ContactConfig) -> np.ndarray:
    """How far (N, H) each holder must lower for every grip it holds (anchors (N, O, K, 3) world;
    over each contact span, easing in and out over blend_frames) to lie within `reach` of the
    arm from its shoulder; none where the grip is beyond reach across (step_within_reach steps
    towards it), and the pelvis no lower than `lowest_squat` of the legs' length."""
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
    legs = (norm(joints[:, :, list(KNEES)] - joints[:, :, list(HIPS)])
            + norm(joints[:, :, list(ANKLES)] - joints[:, :, list(KNEES)])).mean(-1)   # (N, H)
    return np.clip(need, 0.0, np.maximum(joints[:, :, 0, 1] - config.lowest_squat * legs, 0.0))


def crouch_to_grips(joints: np.ndarray, obj_pose: np.ndarray, storyboard: Storyboard,
                    config: ContactConfig = ContactConfig()) -> np.ndarray:
    """joints (N, H, 22, 3), obj_pose (N, O, 7) -> joints with each holder lowered where its held
    grips lie below its reach (_need), going down and up at crouch_frames_per_metre (smoothed
    over crouch_sigma), up at its key frames (the warp placed those poses), and never taking a
    body sphere but the arms' deeper into an object (a knee went 2 cm further into a box put
    down): there, only as deep as that allows."""
    joints = np.asarray(joints, float)
    n, h = joints.shape[:2]
    need = _need(joints, object_anchors(obj_pose, storyboard), storyboard, config)
    if not need.any():
        return joints
    # Down by the span's start, up after its end (to a grip one frame after another, a squat
    # of 40 cm took three frames).
    rate = 1.0 / config.crouch_frames_per_metre
    need = gaussian_filter1d(_cone(need, rate, up=True), config.crouch_sigma, axis=0, mode="nearest")
    bend = max(config.crouch_sigma, 1.0)   # frames over which the way up to a key eases out
    frames = np.arange(n)
    for a, keys in enumerate(key_frames(storyboard)):
        if keys:
            d = np.min(np.abs(frames[:, None] - np.asarray(keys)[None]), axis=1)
            need[:, a] = np.minimum(need[:, a], rate * np.where(d < bend, d ** 2 / (2 * bend), d - bend / 2))
    objects = (np.asarray(obj_pose, float), [o.spec for o in storyboard.objects])
    out = joints.copy()
    for a in range(h):
        drop = need[:, a]
        at = np.flatnonzero(drop > 1e-4)
        if not len(at):
            continue
        still = _depth(joints[at, a], (objects[0][at], objects[1]))
        allowed, left = drop[at].copy(), np.arange(len(at))      # left: the frames it takes deeper
        for share in (1.0, 0.5, 0.25):
            f = at[left]
            crouched = _crouched(joints[f, a], share * drop[f])
            if share == 1.0:
                out[at, a] = crouched
            allowed[left] = share * drop[f]
            left = left[_depth(crouched, (objects[0][f], objects[1])) > still[left] + DEEPER]
            if not len(left):
                break
        allowed[left] = 0.0
        if (allowed < drop[at]).any():   # as slowly up as down
            limit = drop.copy()
            limit[at] = allowed
            drop = np.minimum(drop, _cone(limit[:, None], rate, up=False)[:, 0])
            out[at, a] = _crouched(joints[at, a], drop[at])
    return out

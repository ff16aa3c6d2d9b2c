"""Hands and feet that never go through the objects.

The decoder does not know where finishing puts the object, and a hand blending onto its grip
before a hold, or off it after, travels from where the generated hand was: often inside the box
(a wrist 15 cm deep at the start of a hand-off, 8 cm after a set-down). Here a wrist that sinks
into an object further than its own radius is pushed out along the surface normal by as much as
it sinks; the push eases in and out over the frames around (none while the hand holds: it is on
its grip), and the elbow goes to the place nearest its own that keeps both arm bones' lengths.
The push eases as an envelope of what each frame asks, never less (blend.eased_push): made exact
at each sunk frame and smoothed between, it left the final steadying a pop to smooth, which put
the hand back into the box (60 artist-style storyboards: something more than 2 cm inside an object
in 65% of them; as an envelope, 55%, with no more jumps).

A foot that steps into an object (beside a box on the floor: 10 cm into it) is moved out
sideways, ankle and foot together, the knee kept on both leg bones' lengths; the push is the
same through each stance (a planted foot that follows a push slides) and eases in and out
around it.
"""
from __future__ import annotations

import numpy as np

from ..body import BONES, JOINT_RADII, SPHERE_RADII
from ..geometry.rotations import norm, quat_to_matrix
from ..objects import ObjectSpec, world_to_local
from ..storyboard import Storyboard
from ..skeleton import FEET
from .blend import HELD_WEIGHT, eased_push, smooth_path
from .held import true_spans
from .limbs import LIMBS, on_circle

ARMS, LEGS = LIMBS[2:], LIMBS[:2]   # (shoulder, elbow, wrist), (hip, knee, ankle) left, right
STEP = 1e-3          # m; the finite difference of the surface normal
STANCE_STEP = 2e-3   # m a frame; a foot moving less to or from a frame stands there
TRACE = 1e-5         # m; a smoothed push this short is the smoothing's trace far from any push


def _outward(points: np.ndarray, obj_pose: np.ndarray, spec: ObjectSpec) -> tuple[np.ndarray, np.ndarray]:
    """Signed distance (N, P) of points (N, P, 3) to an object at obj_pose (N, 7), and the world
    direction (N, P, 3) in which it grows fastest (the outward surface normal)."""
    local = world_to_local(points, obj_pose)
    sdf = spec.sdf_local(local)
    grad = np.stack([spec.sdf_local(local + STEP * axis) - sdf for axis in np.eye(3)], -1) / STEP
    grad /= np.maximum(norm(grad, keepdims=True), 1e-9)
    return sdf, grad @ np.swapaxes(quat_to_matrix(obj_pose[:, 3:]), -1, -2)


def clear_hands(joints: np.ndarray, obj_pose: np.ndarray, storyboard: Storyboard,
                smooth_frames: float = 1.5) -> np.ndarray:
    """joints (N, H, 22, 3), obj_pose (N, O, 7) -> joints with no wrist deeper in an object than
    its radius allows; only wrists and elbows move, bone lengths kept. The push eases in and out
    over about `smooth_frames` frames around where a wrist sinks (blend.eased_push)."""
    out = np.array(joints, float)
    specs = [o.spec for o in storyboard.objects]
    on_grip = storyboard.holding()                                              # (N, H, 2)
    for side, (shoulder, elbow, wrist) in enumerate(ARMS):
        holding = on_grip[..., side]
        radius = JOINT_RADII[wrist]
        push = np.zeros(out.shape[:2] + (3,))                                   # (N, H, 3)
        for o, spec in enumerate(specs):
            sdf, normal = _outward(out[:, :, wrist] + push, obj_pose[:, o], spec)     # (N, H), (N, H, 3)
            push += np.maximum(radius - sdf, 0.0)[..., None] * normal
        push[holding] = 0.0
        for h in np.flatnonzero(np.any(push != 0.0, axis=(0, 2))):
            push[:, h] = eased_push(push[:, h], smooth_frames)
        push[holding] = 0.0
        moved = np.any(push != 0.0, axis=-1)
        if not moved.any():
            continue
        _pushed_limb(out, (shoulder, elbow, wrist), push, moved)
    return out


def clear_feet(joints: np.ndarray, obj_pose: np.ndarray, storyboard: Storyboard,
               smooth_frames: float = 1.5) -> np.ndarray:
    """joints (N, H, 22, 3), obj_pose (N, O, 7) -> joints with no ankle or foot sunk into an
    object: moved out sideways (in the object's horizontal plane, to the nearest side of its
    footprint), by one push through each stance, eased over about `smooth_frames` frames; only
    knees, ankles and feet move, leg bone lengths kept."""
    out = np.array(joints, float)
    specs = [o.spec for o in storyboard.objects]
    for (hip, knee, ankle), foot in zip(LEGS, FEET):
        bone = 22 + int(np.flatnonzero((BONES[:, 0] == ankle) & (BONES[:, 1] == foot))[0])
        radii = SPHERE_RADII[[ankle, foot, bone]]
        points = np.stack([out[:, :, ankle], out[:, :, foot], 0.5 * (out[:, :, ankle] + out[:, :, foot])], 2)
        push = np.zeros(out.shape[:2] + (3,))                                   # (N, H, 3)
        for o, spec in enumerate(specs):
            push += _sideways(points + push[:, :, None], obj_pose[:, o], spec, radii)
        for h in np.flatnonzero(np.any(push != 0.0, axis=(0, 2))):
            held, stance = _held_through_stances(push[:, h], out[:, h, foot])
            values = np.where(stance[:, None], held, eased_push(held, smooth_frames))
            weight = np.where(stance, HELD_WEIGHT, 1.0)
            eased = smooth_path(values, weight, smooth_frames ** 4)         # held where it stands
            push[:, h] = np.where(norm(eased, keepdims=True) > TRACE, eased, 0.0)
        moved = np.any(push != 0.0, axis=-1)
        if moved.any():
            before = out[:, :, ankle][moved]
            _pushed_limb(out, (hip, knee, ankle), push, moved)
            out[:, :, foot][moved] += out[:, :, ankle][moved] - before   # the foot goes with its ankle
    return out


def _sideways(points: np.ndarray, obj_pose: np.ndarray, spec: ObjectSpec, radii: np.ndarray) -> np.ndarray:
    """The horizontal push (N, H, 3) that takes the deepest of each frame's sunk spheres (points
    (N, H, P, 3), radii (P,)) out of an object at obj_pose (N, 7): out of its footprint, found
    at the object's mid-height, along the footprint's outward normal. 0 where none sinks."""
    n, h, p = points.shape[:3]
    local = world_to_local(points.reshape(n, h * p, 3), obj_pose).reshape(n, h, p, 3)
    sunk = spec.penetration_local(local, radii) > 0                               # (N, H, P)
    push = np.zeros(local.shape)
    if sunk.any():
        level = local[sunk]                                                       # (M, 3)
        level[:, 1] = spec.size[1] / 2
        sdf = spec.sdf_local(level)
        grad = np.stack([spec.sdf_local(level + STEP * axis) - sdf for axis in np.eye(3)[[0, 2]]], -1) / STEP
        normal = np.zeros(level.shape)
        normal[:, [0, 2]] = grad / np.maximum(norm(grad, keepdims=True), 1e-9)
        rotation = np.broadcast_to(quat_to_matrix(obj_pose[:, 3:])[:, None, None], (n, h, p, 3, 3))[sunk]
        depth = np.maximum(np.broadcast_to(radii, sunk.shape)[sunk] - sdf, 0.0)
        push[sunk] = np.einsum("mij,mj->mi", rotation, depth[:, None] * normal)
    push[..., 1] = 0.0
    deepest = np.argmax(norm(push), axis=-1)                                    # (N, H)
    return np.take_along_axis(push, deepest[..., None, None], 2)[:, :, 0]


def _held_through_stances(push: np.ndarray, foot: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """push (N, 3) of one foot (N, 3) with every frame of a stance (the foot still to or from its
    neighbour) given the stance's longest push -> (N, 3), and where it stands (N,) bool."""
    out = push.copy()
    step = norm(np.diff(foot, axis=0))
    slow = step < STANCE_STEP
    still = np.concatenate([[False], slow]) | np.concatenate([slow, [False]])   # its landing frame too
    for first, last in true_spans(still):
        stance = slice(first, last + 1)
        if np.any(push[stance] != 0.0):
            out[stance] = push[stance][np.argmax(norm(push[stance]))]
    return out, still


def _pushed_limb(out: np.ndarray, limb: tuple[int, int, int], push: np.ndarray, moved: np.ndarray) -> None:
    """Moves a limb's end (root, middle, end joints) of out (N, H, 22, 3) by push (N, H, 3) where
    moved (N, H), as far as the limb reaches, its middle joint the nearest place that keeps both
    bone lengths; in place."""
    root_joint, mid_joint, end_joint = limb
    root, mid, end = out[:, :, root_joint][moved], out[:, :, mid_joint][moved], out[:, :, end_joint][moved]
    upper, lower = norm(mid - root), norm(end - mid)
    reach = end + push[moved] - root
    dist = np.maximum(norm(reach), 1e-9)
    goal = root + reach * (np.minimum(dist, upper + lower) / dist)[:, None]
    out[:, :, mid_joint][moved] = on_circle(root, goal, upper, lower, mid)
    out[:, :, end_joint][moved] = goal

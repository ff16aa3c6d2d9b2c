"""Knees and elbows that never pop: the last pass of finishing.

The stages before it place the ends of the limbs (feet on their plants, wrists on keys and grips)
and each re-solves the knee or elbow between them by two-bone IK in its own way. Where a stage
hands over to the next, where a limb is nearly straight (the knee's place is then very sensitive
to the foot's) or folded (the hip-to-ankle or shoulder-to-wrist line turns fast), the middle joint
can jump 20-40 cm in one frame while its ends move a few centimetres. This pass keeps every other
joint where it is and moves only the middle ones: where a middle joint's path pops, each frame's
knee or elbow goes to the point of its circle (every place that keeps both bone lengths with the
ends fixed) nearest to its path smoothed over time. Motion that does not pop is left exactly.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from scipy.ndimage import label, maximum_filter1d

from ..geometry.rotations import matrix_to_6d, norm, normalize, sixd_to_matrix
from ..objects import ObjectSpec
from ..skeleton import ELBOWS, JOINT_INDEX, forward_kinematics
from .blend import smooth_path, spike
from .swivel import ARM_RADII, LEG_RADII, limb_penetration

DEEPER = 0.002   # m; an elbow or knee the smoothing takes further into an object than this stays
LIMBS = tuple(tuple(JOINT_INDEX[f"{side}_{joint}"] for joint in chain)
              for chain in (("hip", "knee", "ankle"), ("shoulder", "elbow", "wrist")) for side in "lr")


@dataclass
class LimbConfig:
    """Durations in frames at TUNED_FPS."""
    DURATIONS: ClassVar[tuple[str, ...]] = ("smooth_frames", "spread")
    tolerance: float = 0.02      # m; a joint off the middle of its neighbours by less is smooth
    smooth_frames: float = 1.0   # time scale of the smoothing where a limb pops (blend.smooth_path)
    popping_weight: float = 0.3  # how much a popping frame's own place counts against smoothness
    spread: int = 2              # frames either side of a pop that are smoothed with it
    passes: int = 3


def on_circle(root: np.ndarray, end: np.ndarray, upper: np.ndarray, lower: np.ndarray,
              goal: np.ndarray) -> np.ndarray:
    """The middle joint of a two-bone chain with its ends fixed, nearest to goal: root, end, goal
    (..., 3), bone lengths upper, lower (...,) -> (..., 3). The place keeps both bone lengths
    exactly wherever the ends are within reach of each other (finishing keeps them so)."""
    to_end = end - root
    dist = np.maximum(norm(to_end), 1e-9)
    axis = to_end / dist[..., None]
    along = np.clip((upper ** 2 - lower ** 2 + dist ** 2) / (2 * dist), -upper, upper)
    radius = np.sqrt(np.maximum(upper ** 2 - along ** 2, 0.0))
    centre = root + along[..., None] * axis
    off = goal - centre
    off -= np.sum(off * axis, axis=-1, keepdims=True) * axis
    return centre + radius[..., None] * normalize(off)


def steady_limbs(joints: np.ndarray, config: LimbConfig = LimbConfig(),
                 objects: tuple[np.ndarray, list[ObjectSpec]] | None = None) -> np.ndarray:
    """joints (N, H, 22, 3) -> (N, H, 22, 3) with knees and elbows that do not pop; every other
    joint and every bone length unchanged. With `objects` (their poses (N, O, 7), their specs),
    an elbow or knee is not smoothed into them: a frame whose limb the smoothed joint would take
    deeper into an object keeps its joint (smoothing pushed forearms beside side grips 2-3 cm into
    boxes that the elbows' swivel had cleared, and knees back into the box they crouch by)."""
    out = np.array(joints, float)
    if len(out) < 3:
        return out
    stiffness = config.smooth_frames ** 4
    for root, mid, end in LIMBS:
        upper = norm(out[:, :, mid] - out[:, :, root])          # (N, H)
        lower = norm(out[:, :, end] - out[:, :, mid])
        for _ in range(config.passes):
            path = out[:, :, mid]                                                  # (N, H, 3)
            # A middle joint that only follows a spike of its ends is not popping.
            excess = spike(path) - np.maximum(spike(out[:, :, root]), spike(out[:, :, end]))
            popping = maximum_filter1d(excess > config.tolerance, 2 * config.spread + 1, axis=0)
            if not popping.any():
                break
            goal = path.copy()
            for h in np.flatnonzero(popping.any(axis=0)):
                goal[:, h] = smooth_path(path[:, h], np.where(popping[:, h], config.popping_weight, 1.0), stiffness)
            moved = on_circle(out[:, :, root], out[:, :, end], upper, lower, goal)
            if objects is not None:
                leg = mid not in ELBOWS   # a knee kneels on the floor
                moved = _not_deeper(out[:, :, root], out[:, :, mid], moved, out[:, :, end], *objects,
                                    LEG_RADII if leg else ARM_RADII, ground=not leg)
            out[:, :, mid] = moved
    return out


def _not_deeper(shoulder: np.ndarray, elbow: np.ndarray, moved: np.ndarray, wrist: np.ndarray,
                obj_pose: np.ndarray, specs: list[ObjectSpec], radii: np.ndarray = ARM_RADII,
                ground: bool = True) -> np.ndarray:
    """The moved elbows (N, H, 3), but the old ones (N, H, 3) where moving them takes the arm
    (shoulder, wrist (N, H, 3)) deeper into the objects (obj_pose (N, O, 7)); or a leg's knees
    (hip, ankle; its radii and `ground`: swivel.limb_penetration's)."""
    out = moved.copy()
    for h in range(elbow.shape[1]):
        changed = np.flatnonzero(np.any(moved[:, h] != elbow[:, h], axis=-1))   # only the smoothed frames
        if not len(changed):
            continue
        ends = shoulder[changed, h, None], wrist[changed, h, None]
        both = np.stack([elbow[changed, h], moved[changed, h]], 1)
        depth = limb_penetration(ends[0], both, ends[1], obj_pose[changed], specs, radii, ground)   # (M, 2)
        deeper = changed[depth[:, 1] > depth[:, 0] + DEEPER]
        out[deeper, h] = elbow[deeper, h]
    return out


def steady_rotations(generated: np.ndarray, root: np.ndarray, rotations: np.ndarray, offsets: np.ndarray,
                     config: LimbConfig = LimbConfig()) -> tuple[np.ndarray, np.ndarray]:
    """Local rotations (N, H, 22, 3, 3) whose FK pops where the generated joints (N, H, 22, 3) do
    not, smoothed over time there; root (N, H, 3), offsets (H, 22, 3) -> (those rotations, their
    FK (N, H, 22, 3)).

    Fitting one rigid skeleton to joints whose bones change length from frame to frame (the
    decoder's) can jolt the chain: the spine's branch fits turned the shoulders 8 cm in a frame
    while the generated ones moved smoothly. Frames whose joints spike more than the generated
    ones by config.tolerance (and `spread` frames around) get rotations smoothed like steady_limbs'
    knees; the rest are left exactly. A stretch that spikes more smoothed than it did is given back
    its own rotations: averaging the rotations of a fast turn (the fit of a real dancer's pelvis
    turned 230 degrees in three frames) gives no rotation at all, and a foot jumped a metre."""
    posed = forward_kinematics(root, rotations, offsets)                         # all people at once
    if len(rotations) < 3:
        return rotations, posed
    wanted = spike(generated)                                                   # (N, H, 22)
    before = (spike(posed) - wanted).max(axis=-1)                               # (N, H)
    rotations, posed = rotations.copy(), posed.copy()
    for h in np.flatnonzero((before > config.tolerance).any(axis=0)):
        rotations[:, h], posed[:, h] = _steadied(wanted[:, h], before[:, h], posed[:, h], root[:, h],
                                                 rotations[:, h], offsets[h], config)
    return rotations, posed


def _steadied(wanted: np.ndarray, before: np.ndarray, posed: np.ndarray, root: np.ndarray, rotations: np.ndarray,
              offsets: np.ndarray, config: LimbConfig) -> tuple[np.ndarray, np.ndarray]:
    """steady_rotations for one person who pops: the generated joints' spikes wanted (N, 22),
    the fit's excess over them before (N,), its FK posed (N, 22, 3) -> (rotations, FK)."""
    n = len(rotations)

    def refit(r: np.ndarray) -> np.ndarray:   # FK (N, 22, 3), recomputed only where r changed
        changed = np.flatnonzero(np.any(r != rotations, axis=(1, 2, 3)))
        moved = posed.copy()
        moved[changed] = forward_kinematics(root[changed], r[changed], offsets)
        return moved

    def excess(r: np.ndarray) -> np.ndarray:   # (N,) how much more each frame spikes than generated
        return (spike(refit(r)) - wanted).max(axis=-1)

    smoothed, after = rotations, before
    for _ in range(config.passes):
        popping = after > config.tolerance
        if not popping.any():
            break
        popping = maximum_filter1d(popping, 2 * config.spread + 1)
        six = smooth_path(matrix_to_6d(smoothed).reshape(n, -1), np.where(popping, config.popping_weight, 1.0),
                          config.smooth_frames ** 4)
        smoothed = np.where(popping[:, None, None, None], sixd_to_matrix(six.reshape(n, -1, 6)), smoothed)
        after = excess(smoothed)
    stretches, count = label(np.any(smoothed != rotations, axis=(1, 2, 3)))
    for s in range(1, count + 1):
        near = maximum_filter1d(stretches == s, 3)       # smoothing a stretch changes its neighbours' spikes
        if after[near].max() > before[near].max() + config.tolerance:
            smoothed = np.where((stretches == s)[:, None, None, None], rotations, smoothed)
    return smoothed, refit(smoothed)

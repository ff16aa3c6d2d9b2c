"""A whole body that never pops: the last pass of finishing.

Every stage before this one leaves some one-frame pops (the decoder's gait, a warp's or a reach's
edit meeting the next stage's), and the limb pass only smooths knees and elbows that pop more than
their ends. Here, where any joint of a person pops (lies off the middle of its neighbouring frames
by more than `tolerance`, or jumps further in a frame than in both neighbouring ones), every joint
that is not held is pulled towards its path smoothed over time; the bones are given back their
lengths (held joints fixed), the pose put back on the person's skeleton by IK, and held hands and
feet back where they were. Held is what the storyboard and the stages before made exact: the
placed joints at their keys, the wrists in their holds, joints standing still, feet near the floor
(smoothed, a foot would travel before it lifts, and slide). A stretch that would pop more is
smoothed less, in turn, and left as it was where even that would; so is a frame whose held hand
the smoothed body could no longer reach. What one smoothing leaves popping the next ones take
(`SteadyConfig.passes`), the last with the hands free in the first and last frames of their holds
and the feet in those of their plants (sliding little), where those pop; no foot in the air comes
out lower than it came.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from scipy.ndimage import label, maximum_filter1d

from ..body import BONES as BODY_BONES
from ..geometry.rotations import norm
from ..skeleton import (ANKLES, CHILDREN, FEET, HANDS, NUM_JOINTS, bone_lengths, forward_kinematics,
                        inverse_kinematics)
from ..storyboard import Storyboard
from .blend import HELD_WEIGHT, at_most, smooth_path, spike
from .feet import reach_with_leg
from .limbs import LIMBS, on_circle

BONE_PARENTS, BONES = BODY_BONES.T                  # (21,) each bone's parent and child joint
TO_CHILD = np.eye(NUM_JOINTS)[:, BONES]             # (22, 21): bone b's child end
TO_PARENT = np.eye(NUM_JOINTS)[:, BONE_PARENTS]     # (22, 21): bone b's parent end
JOINT_BONES = TO_CHILD.sum(1) + TO_PARENT.sum(1)    # (22,) bones meeting at each joint
TO_ENDS = np.concatenate([TO_PARENT, TO_CHILD], 1)  # (22, 42): the bones' parent ends, then child ends

LEGS_END = [*FEET, *ANKLES]   # feet, then ankles


@dataclass
class SteadyConfig:
    """Durations in frames at TUNED_FPS."""
    DURATIONS: ClassVar[tuple[str, ...]] = ("smooth_frames", "spread")
    tolerance: float = 0.035     # m; a frame whose joints pop less is left exactly as it is
    smooth_frames: float = 1.5   # time scale of the smoothing where the body pops (blend.smooth_path)
    # How much a popping frame's own place counts against smoothness: a stretch the first would
    # make pop more (its bones given back their lengths, a collar swung 13 cm) is smoothed less,
    # in turn (40 artist-style storyboards with their largest pop within 5 cm 27 -> 31).
    popping_weights: tuple[float, ...] = (0.2, 1.0, 5.0)
    retry_above: float = 0.045   # m; a stretch popping less is not smoothed less in turn
    # Smoothings in a row: one leaves some stretches as they were (smoothed, they popped more where
    # held frames met the smoothed ones) and moves others' pops to their edges, which the next one
    # takes (later ones only where the last changed something and it still pops over retry_above).
    # artist_check's 100 storyboards, pops within 5 cm 67 -> 79 (seed 0), 66 -> 79 (seed 1); 5
    # passes 80, at 1.5x the steadying's time.
    passes: int = 3
    pass_gain: float = 0.002     # m; after the first, a smoothing that lowers a stretch's pop less is not taken
    spread: int = 2              # frames either side of a pop that are smoothed with it
    still: float = 0.004         # m a frame; a joint moving less to and from a frame is held there
    floor: float = 0.05          # m; a foot lower than this is held (planting or lifting: the height under
                                 # which FootSkate counts a foot planted). At 0.06 a foot's lift off the floor
                                 # was held and jolted the next frame by 5-7 cm: artist_check's 3 x 100
                                 # storyboards (drawings 0-2) within 5 cm of pops 264 -> 273, skating within 3%
                                 # 294 -> 293 (mean 0.44 -> 0.51% of frames); at 0.045, 279 but 0.72% skating
    plant_slide: float = 0.015   # m a foot on the floor may slide, or a hand leave its grip, in the first or
                                 # last frame of its plant or hold (the last pass; a foot 3 cm: pops within
                                 # 5 cm 88 -> 90 of 100, but skating in over 3% of their frames 1 -> 3)
    swing_floor: float = 0.08    # m; a foot in the air is lowered no further than this (a step's lift)
    bone_iterations: int = 15   # of the bone-length restoring, before the exact IK


def step_jumps(path: np.ndarray) -> np.ndarray:
    """How far each step k + 1 (frames k + 1 -> k + 2) of joint paths (N, J, 3) is longer than both
    of its neighbouring steps, over the joints -> (N - 3,) (empty for fewer than 4 frames)."""
    step = norm(np.diff(path, axis=0))                     # (N-1, J)
    return (step[1:-1] - np.maximum(step[:-2], step[2:])).max(axis=-1)


def frame_pops(path: np.ndarray) -> np.ndarray:
    """How much each frame of joint paths (N, J, 3) pops, over its joints -> (N,): the larger of its
    spike and the jump of the steps into or out of it beyond both of their neighbouring steps."""
    out = spike(path).max(axis=-1)
    if len(path) >= 4:
        jump = step_jumps(path)
        out[1:-2] = np.maximum(out[1:-2], jump)
        out[2:-1] = np.maximum(out[2:-1], jump)
    return out


def _ends(runs: np.ndarray) -> np.ndarray:
    """(N, ...) bool -> the first and last frame of each run of True (not the clip's own ends)."""
    inner = runs.copy()
    inner[1:] &= runs[:-1]
    inner[:-1] &= runs[1:]
    return runs & ~inner


def held_joints(joints: np.ndarray, storyboard: Storyboard, still: float, floor: float,
                loose_ends: bool = False) -> np.ndarray:
    """joints (N, H, 22, 3) -> (N, H, 22) bool: what the steadying must not move. With
    `loose_ends`, not the hands in the first and last frames of their holds, nor the feet and
    ankles in those of their stretches on the floor (but where a key places them)."""
    held = np.zeros(joints.shape[:3], bool)
    for k in storyboard.keyposes:
        held[k.frame, storyboard.agent_index(k.agent)] |= k.mask
    holding = storyboard.holding()                                              # (N, H, 2)
    low = joints[:, :, list(FEET), 1] < floor                                   # (N, H, 2)
    if loose_ends:
        holding, low = holding & ~_ends(holding), low & ~_ends(low)
    held[:, :, list(HANDS)] |= holding
    step = norm(np.diff(joints, axis=0))                    # (N-1, H, 22)
    held[1:-1] |= (step[:-1] < still) & (step[1:] < still)
    held[:, :, LEGS_END] |= np.concatenate([low, low], axis=-1)
    return held


def _restore_bones(joints: np.ndarray, lengths: np.ndarray, free: np.ndarray, iterations: int) -> np.ndarray:
    """joints (M, 22, 3), bone lengths (21,), free (M, 22) bool -> joints whose bones have their
    lengths again (to a millimetre or so), moving only free joints: each bone's error is shared
    between its free ends, every joint averaging what its bones ask (Jacobi iterations)."""
    out = joints.copy()
    child, parent = free[:, BONES].astype(float), free[:, BONE_PARENTS].astype(float)   # (M, 21)
    ends = np.maximum(child + parent, 1.0)
    pull_child, pull_parent = (child / ends)[..., None], (parent / ends)[..., None]
    spread = np.where(free, 1.0 / JOINT_BONES, 0.0)[..., None]                           # (M, 22, 1)
    m = len(joints)
    for _ in range(iterations):
        bone = out[:, BONES] - out[:, BONE_PARENTS]                                     # (M, 21, 3)
        length = np.maximum(norm(bone, keepdims=True), 1e-9)
        error = (1.0 - lengths[:, None] / length) * bone                                # too long by
        # Each joint's share of its bones' errors, in one product over all frames (a (22, 21)
        # product per frame took half the steadying's time).
        pulls = np.concatenate([pull_parent * error, -pull_child * error], 1)           # (M, 42, 3)
        out += spread * (TO_ENDS @ pulls.transpose(1, 0, 2).reshape(42, -1)).reshape(22, m, 3).transpose(1, 0, 2)
    return out


def _repin_limbs(pose: np.ndarray, wanted: np.ndarray, held: np.ndarray) -> np.ndarray:
    """pose (M, 22, 3) on the rigid skeleton; wanted (M, 22, 3) where held (M, 22) ends of limbs
    must be: each held ankle or wrist goes back, the knee or elbow to the nearest place that keeps
    both bone lengths, a foot with its ankle. A frame where a held end is out of its limb's reach
    now is `wanted` whole (its hand stays on its grip)."""
    out = pose.copy()
    missed = np.zeros(len(pose), bool)
    for root, mid, end in LIMBS:
        at = held[:, end]
        if not at.any():
            continue
        upper = norm(pose[at, mid] - pose[at, root])
        lower = norm(pose[at, end] - pose[at, mid])
        target = wanted[at, end]
        missed[at] |= norm(target - pose[at, root]) > upper + lower
        out[at, mid] = on_circle(pose[at, root], target, upper, lower, pose[at, mid])
        for child in CHILDREN[end]:   # a held foot keeps its place about the ankle, a free one its own
            about = np.where(held[at, child, None], wanted[at, child] - target, pose[at, child] - pose[at, end])
            out[at, child] = target + about
        out[at, end] = target
    return np.where(missed[:, None, None], wanted, out)


def _feet_placed(poses: np.ndarray, path: np.ndarray, free: np.ndarray, lowest: np.ndarray,
                 floor: float, slide: float) -> np.ndarray:
    """poses (N, 22, 3) smoothed from path (N, 22, 3), their free feet (free (N, 22) bool) put
    back: one the rigid skeleton put lower than `lowest` (N, 2) raised back to it (smoothed again and
    again, the bones' directions lowered a swinging foot by a centimetre each time), and one on
    the floor in `path` (lower than `floor`: planting or lifting) back to within `slide` (m) of
    where it stood, so that it does not skate. Those legs re-solved from the hip."""
    out = poses.copy()
    for side, (foot, ankle) in enumerate(zip(FEET, ANKLES)):
        moving = free[:, foot] & free[:, ankle]
        planted = moving & (path[:, foot, 1] < floor)
        fix = planted | (moving & (out[:, foot, 1] < lowest[:, side] - 1e-3))
        if fix.any():
            goal = out[fix, foot].copy()
            stay = path[fix][:, foot, [0, 2]]
            slid = stay + at_most(goal[:, [0, 2]] - stay, slide)
            goal[:, [0, 2]] = np.where(planted[fix, None], slid, goal[:, [0, 2]])
            goal[:, 1] = np.maximum(goal[:, 1], lowest[fix, side])
            out[fix] = reach_with_leg(out[fix], side, goal)
    return out


def _steady_person(path: np.ndarray, held: np.ndarray, offsets: np.ndarray, config: SteadyConfig,
                   lowest: np.ndarray, gain: float = 0.0, changed: np.ndarray | None = None,
                   ends: np.ndarray | None = None) -> np.ndarray:
    """One smoothing of a person's popping stretches: path (N, 22, 3), held (N, 22), the person's
    bone offsets (22, 3), `lowest` (N, 4) the heights its feet and ankles (LEGS_END) stay above
    where they are free -> path. A stretch is smoothed where that lowers its largest pop by `gain`
    (m) or more; with `changed` (N,) bool, only the stretches that meet it. Hands in `ends` (N, 22)
    bool (the ends of their holds, not held) stay within config.plant_slide of where they were."""
    before = frame_pops(path)
    popping = maximum_filter1d(before > config.tolerance, 2 * config.spread + 1)
    if not popping.any():
        return path
    out = path.copy()
    stretches, count = label(popping)
    left = list(range(1, count + 1))          # stretches not smoothed yet
    if changed is not None:   # a later pass: only where the last one changed something and it still pops much
        left = [s for s in np.unique(stretches[changed]) if s and before[stretches == s].max() > config.retry_above]
    for weight in config.popping_weights:
        goal = _smoothed(path, held, np.isin(stretches, left), offsets, config, weight, lowest, ends)
        after = frame_pops(goal)
        for s in list(left):
            near = maximum_filter1d(stretches == s, 3)
            if after[near].max() <= before[near].max() - gain + 1e-6:
                out[stretches == s] = goal[stretches == s]
                left.remove(s)
        # Smoothed less only where it pops more than retry_above: lower pops are not worth the
        # time (30 ms of 0.44 s on the bundled box hand-off, every retry for a pop of 3.6-4.1 cm).
        left = [s for s in left if before[stretches == s].max() > config.retry_above]
        if not left:
            break
    return out


def _smoothed(path: np.ndarray, held: np.ndarray, popping: np.ndarray, offsets: np.ndarray, config: SteadyConfig,
              weight: float, lowest: np.ndarray, ends: np.ndarray | None = None) -> np.ndarray:
    """path (N, 22, 3) smoothed where popping (N,), held (N, 22) joints kept, each popping frame's
    place counting `weight` against smoothness, back on the skeleton (offsets (22, 3)), free feet
    and ankles no lower than `lowest` (N, 4)."""
    goal = path.copy()
    kept = held | ~popping[:, None]                                                     # (N, 22)
    alike: dict[bytes, list[int]] = {}                    # joints held at the same frames: one solve
    for j in range(kept.shape[1]):
        alike.setdefault(kept[:, j].tobytes(), []).append(j)
    for joints in alike.values():
        goal[:, joints] = smooth_path(path[:, joints].reshape(len(path), -1),
                                      np.where(kept[:, joints[0]], HELD_WEIGHT, weight),
                                      config.smooth_frames ** 4).reshape(len(path), len(joints), 3)
    # Nor does it lower a foot in the air below swing_floor: it would brush the floor as it travels.
    goal[:, LEGS_END, 1] = np.maximum(goal[:, LEGS_END, 1], lowest)
    # Back on the person's skeleton (IK keeps the smoothed bone directions), held hands and feet
    # put back where they were.
    lengths = bone_lengths(path[0])[BONES]
    goal[popping] = _restore_bones(goal[popping], lengths, ~held[popping], config.bone_iterations)
    rigid = forward_kinematics(goal[popping, 0], inverse_kinematics(goal[popping], offsets), offsets)
    goal[popping] = _repin_limbs(rigid, path[popping], held[popping])
    if ends is not None:   # a hand at its hold's end leaves its grip by little
        near = ends & popping[:, None] & np.isin(np.arange(NUM_JOINTS), HANDS)
        wanted = np.where(near[..., None], path + at_most(goal - path, config.plant_slide), goal)
        goal[popping] = _repin_limbs(goal[popping], wanted[popping], near[popping])
    return _feet_placed(goal, path, popping[:, None] & ~held, lowest[:, :len(FEET)], config.floor,
                        config.plant_slide)


def steady_body(joints: np.ndarray, offsets: np.ndarray, storyboard: Storyboard,
                config: SteadyConfig = SteadyConfig(), people: Sequence[int] | None = None,
                held: np.ndarray | None = None) -> np.ndarray:
    """joints (N, H, 22, 3) on each person's skeleton, offsets (H, 22, 3) -> the same where nothing
    pops; where something does, smoothed with the held joints (held_joints, and `held` (N, H, 22)
    bool where given) kept, the last pass with the ends of holds and plants let move a little. Only
    `people` (indices; None: everyone) are steadied."""
    out = np.array(joints, float)
    if len(out) < 4:
        return out
    extra = np.zeros(out.shape[:3], bool) if held is None else held
    held = held_joints(out, storyboard, config.still, config.floor) | extra
    loose = held_joints(out, storyboard, config.still, config.floor, loose_ends=True) | extra
    ends = np.any(held != loose, axis=2)                                        # (N, H)
    for h in range(out.shape[1]) if people is None else people:
        lowest = np.minimum(out[:, h, LEGS_END, 1], config.swing_floor)     # as the feet came, not as a pass left them
        changed = None
        for k in range(config.passes):
            steadied = _steady_person(out[:, h], held[:, h], offsets[h], config, lowest,
                                      config.pass_gain if k else 0.0, changed)
            changed = maximum_filter1d(np.any(steadied != out[:, h], axis=(1, 2)), 2 * config.spread + 3)
            if not changed.any():
                break
            out[:, h] = steadied
        # Last, where a grasp, a release, a foot's landing or its lift-off still pops, the hand or
        # the foot is let move in its first and last frames (by plant_slide; a foot up as far as it
        # will): the body that rose or turned while the hand held on, and a foot held still to its last
        # frame on the floor, then swung, had put the jolt there. artist_check's 100 storyboards,
        # pops within 5 cm 79 -> 88 (seeds 0 and 1), jumps beyond both neighbours 97 -> 99; grips,
        # skate and penetration the same (unbounded, hands left their grips by up to 7 cm).
        near_ends = maximum_filter1d(ends[:, h], 2 * config.spread + 1)
        if near_ends.any():
            out[:, h] = _steady_person(out[:, h], loose[:, h], offsets[h], config, lowest, config.pass_gain, near_ends,
                                       held[:, h] & ~loose[:, h])
    return out

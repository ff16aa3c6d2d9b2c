"""Motion warping onto the storyboard's keyposes (Witkin and Popovic, 1995).

A generated motion follows its sketch only roughly. At every keyframe the warp solves the pose
that lands exactly on the sketched keypose in the sketch plane; the differences (each joint's
displacement from the pelvis in the body's own frame, an offset of the root) are spread over the
neighbouring frames (the root's from key to key, the pose's fading within pose_falloff of its
key), so the motion keeps its own dynamics while passing through the sketch. Pelvis strokes are
walked afterwards (paths.py).

A 2D sketch does not give depth; the ground does. Every sketched joint slides along its camera
ray to a depth that keeps the generated pose's depth differences along its bones (a stamped or
turned keypose's own, which the app knows) while the feet it stands on touch the ground (a
least-squares fit); a slide of the whole figure along the viewing direction keeps the sketch
exact.

Joint arrays are (N, H, 22, 3) in metres with consistent bone lengths: `offsets` (H, 22, 3) are
each person's bones, FK(joints[:, h, 0], IK(joints[:, h], offsets[h]), offsets[h]) == joints.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from scipy.ndimage import gaussian_filter1d

from ..camera import StoryboardCamera
from ..facing import towards_camera
from ..geometry.rotations import cross, norm
from ..skeleton import ANKLES, ELBOWS, FEET, HANDS, JOINT_INDEX, NUM_JOINTS, PARENTS, forward_kinematics, inverse_kinematics
from ..storyboard import Storyboard
from ..synth.reach import UP, heading_of, yaw_matrix
from .contacts import reach_with_arms
from .feet import reach_with_leg
from .keys import closeness_to_keys, spread

PELVIS, L_HIP, R_HIP = JOINT_INDEX["pelvis"], JOINT_INDEX["l_hip"], JOINT_INDEX["r_hip"]
LEVEL = 0.05  # |vertical part of the viewing direction| below which the camera is too level to
              # place points by their height


@dataclass
class WarpConfig:
    DURATIONS: ClassVar[tuple[str, ...]] = ("falloff", "pose_falloff", "heading_smoothing")
    # (frames at TUNED_FPS)
    falloff: int = 12             # frames over which an offset fades in before the first key / out after the last
    pose_falloff: int = 60        # frames over which a key's pose change (not its place) fades out between
                                  # keys: spread whole over a 66-frame walk, a posed figure's straight template
                                  # knee turned with the body and swung the knee 40 cm in a frame (20 frames
                                  # did as well for pops but moved the pelvis paths 1.3 cm further off)
    heading_smoothing: float = 1.5  # frames; Gaussian sigma of the heading that a key's pose change turns
                                  # with (a real dancer's spin read off the hips turned 135 degrees in one
                                  # frame, and a spread pose change swung a wrist 40 cm with it)
    foot_height: float = 0.02     # m; height of the foot joint standing on the ground (as FeetConfig's)
    # Keypose depth fit (solve_keypose); weights of its residuals (m), 1 for a bone's depth change.
    stance_tolerance: float = 0.08  # m; a generated foot this close to the lower one's height stands
    ground_weight: float = 10.0   # a standing foot's height above foot_height
    bone_weight: float = 1.0      # a bone's length error
    bone_iterations: int = 3      # Gauss-Newton steps for the (non-linear) bone lengths
    depth_anchor: float = 1e-3    # a joint's depth change: places a figure no standing foot places
    ankle_floor: float = 0.03     # m; the lowest a sketched ankle's depth may put it (a flat foot's is 0.08;
                                  # at 0.06 artist_check's pops within 5 cm 67 -> 64 of 100, a grip 3.3 cm off)


# Body parts a sketch scales apart (the salsa dancers' arms are 20-60% longer than the decoder
# draws them, their legs 2-10%: one scale for all grew legs by the arms' measure and lifted the
# pelvis 4 cm, 11 cm deeper along a camera ray): the bones ending at each part's joints, and the
# long bones that measure it.
BODY_PARTS = {
    "legs": (("l_hip", "r_hip", "l_knee", "r_knee", "l_ankle", "r_ankle", "l_foot", "r_foot"),
             ("l_knee", "r_knee", "l_ankle", "r_ankle")),
    "arms": (("l_collar", "r_collar", "l_shoulder", "r_shoulder", "l_elbow", "r_elbow", "l_wrist", "r_wrist"),
             ("l_elbow", "r_elbow", "l_wrist", "r_wrist")),
    "trunk": (("spine1", "spine2", "spine3", "neck", "head"), ("spine1", "spine2", "spine3", "neck")),
}


MEASURING = 0.5   # a bone shown at less than this share of its length (pointing at the camera) measures nothing


def sketched_scales(offsets: np.ndarray, joints: np.ndarray, storyboard: Storyboard, agent: int,
                    quantile: float = 0.5, most: float = 1.1) -> dict[str, float]:
    """How much larger than `offsets` (22, 3) the agent's sketched keyposes say each body part
    is (BODY_PARTS), each in [1, most]; `joints` (N, 22, 3) the agent's generated motion.

    A bone's sketched length is its true length foreshortened as the bone points out of the
    sketch plane; the generated pose at the key says how far it does (a standing leg seen from
    20 degrees above shows 94% of its length: read as its length, the legs came out shorter
    than the arms and a held key's planted feet beyond their reach), so each sketched bone over
    its own length and its generated foreshortening measures the part; the median over the keys'
    bones of the part is its scale. Bones the generated pose points nearly at the camera measure
    nothing. A part only grows by this: a sketch cannot say a body is smaller, since every bone
    may point at the camera. Nor much larger: people built unlike the training bodies would be
    lifted off their feet between keyposes; 1.1 measured best on held-out synthesized and real
    storyboards alike."""
    mine = [k for k in storyboard.keyposes if k.agent == storyboard.agents[agent].id and k.frame < len(joints)]
    if not mine:
        return dict.fromkeys(BODY_PARTS, 1.0)
    parents = np.asarray(PARENTS[1:])
    drawn = np.stack([k.points for k in mine])                                    # (K, 22, 2)
    placed = np.stack([k.mask[1:] & k.mask[parents] for k in mine])              # (K, 21) bones drawn
    pose = joints[[k.frame for k in mine]]                                        # (K, 22, 3)
    bone = pose[:, 1:] - pose[:, parents]
    seen = storyboard.camera.project(pose)
    shown = (norm(seen[:, 1:] - seen[:, parents])
             / np.maximum(norm(bone), 1e-9))                   # generated foreshortening
    own = norm(offsets[1:])
    ratio = norm(drawn[:, 1:] - drawn[:, parents]) / np.maximum(own * shown, 1e-9)
    measures = placed & (shown >= MEASURING) & (own > 1e-6)
    scales = {}
    for part, (_, measured) in BODY_PARTS.items():
        bones = [JOINT_INDEX[name] - 1 for name in measured]
        ratios = ratio[:, bones][measures[:, bones]]
        scales[part] = float(np.clip(np.quantile(ratios, quantile), 1.0, most)) if len(ratios) else 1.0
    return scales


def scale_per_bone(scales: dict[str, float]) -> np.ndarray:
    """(22,) factor of each bone (the one ending at each joint; the root's is 1) from part scales."""
    out = np.ones(NUM_JOINTS)
    for part, (members, _) in BODY_PARTS.items():
        out[[JOINT_INDEX[name] for name in members]] = scales[part]
    return out


def grounding_height(joints: np.ndarray, foot_height: float) -> np.ndarray:
    """How far (...) poses (..., 22, 3) must move up for their lower foot to stand on the ground."""
    return foot_height - joints[..., list(FEET), 1].min(-1)


def solve_keypose(joints: np.ndarray, uv: np.ndarray, mask: np.ndarray, camera: StoryboardCamera,
                  lengths: np.ndarray, config: WarpConfig = WarpConfig(), known: np.ndarray | None = None) -> np.ndarray:
    """One person's pose (22, 3) moved onto a sketched keypose: uv (22, 2) where mask (22,) is
    True; `lengths` (22,) the bone lengths to keep; `known` (22,) the keypose's own depths where
    the storyboard has them (Keypose.depth). Unsketched joints ride rigidly on their parent.

    Each sketched joint goes to its sketch point; what is left is its depth along the camera
    ray (the viewing direction: the sketch camera is orthographic). Least squares chooses the
    depths: every sketched joint keeps the depth difference the generated pose gives it from its
    nearest sketched ancestor (the keypose's own, where known: a stamped pose's, which the
    generated pose, a standing one, knew nothing of), every foot the generated pose stands on
    (within `stance_tolerance` of its lower foot) stands on the ground, and, weakly, every bone
    keeps its length. Bone lengths alone decide little: a bone near the sketch plane 1 cm
    shorter than drawn is sqrt(2 L dL) deep, 10 cm for a thigh, and the decoder's bones are ~3%
    off. With a level camera the ground fixes no depth; the generated depths stay."""
    right, up, back = camera.basis()
    origin = np.asarray(camera.target) + uv[:, :1] * right + uv[:, 1:2] * up          # (22, 3) on the rays
    depth = (joints - origin) @ back                                                 # (22,) generated
    sketched = np.flatnonzero(mask)
    at = np.full(NUM_JOINTS, -1)
    at[sketched] = np.arange(len(sketched))
    # A sketched joint keeps its generated depth difference to its nearest sketched ancestor (a
    # shoulder whose collar and spine the artist left out still rides on the pelvis: linked only to
    # its parent, the arms kept their depth as the grounded legs and pelvis slid 20 cm along the
    # rays); only a joint whose parent is sketched has a bone length to keep.
    linked = np.array([j for j in sketched if _sketched_ancestor(j, mask) >= 0], int)
    child, parent = at[linked], at[[_sketched_ancestor(j, mask) for j in linked]]
    bones = np.array([j for j in linked if mask[PARENTS[j]]], int)
    bone_child, bone_parent, bone_lengths = at[bones], at[np.asarray(PARENTS)[bones]], lengths[bones]
    feet = joints[list(FEET), 1]
    standing = [at[f] for f, y in zip(FEET, feet) if mask[f] and y - feet.min() < config.stance_tolerance]
    if abs(back[1]) <= LEVEL:
        standing = []
    # Unknowns: each sketched joint's change of depth, x (S,). Linear rows A x = b: the anchor,
    # the depth differences, the standing feet's heights.
    eye = np.eye(len(sketched))
    a = np.concatenate([config.depth_anchor * eye, eye[child] - eye[parent],
                        config.ground_weight * back[1] * eye[standing]])
    kept = np.zeros(len(child))
    if known is not None:   # the key's depth differences along the ray, instead of the generated ones
        along = (known - (origin - origin[list(FEET)].mean(0)) @ towards_camera(camera)) / np.hypot(back[0], back[2])
        kept = (along - depth)[sketched][child] - (along - depth)[sketched][parent]
    b = np.concatenate([np.zeros(len(sketched)), kept,
                        config.ground_weight * (config.foot_height - origin[sketched[standing], 1]
                                                - depth[sketched[standing]] * back[1])])
    x = _least_squares(a, b)
    for _ in range(config.bone_iterations):   # Gauss-Newton on the bone lengths
        points = origin[sketched] + (depth[sketched] + x)[:, None] * back
        bone = points[bone_child] - points[bone_parent]
        length = np.maximum(norm(bone), 1e-9)
        slope = config.bone_weight * (bone @ back) / length                     # d length / d x_child
        jac = np.concatenate([a, slope[:, None] * (eye[bone_child] - eye[bone_parent])])
        res = np.concatenate([a @ x - b, config.bone_weight * (length - bone_lengths)])
        x = x - _least_squares(jac, res)
    if abs(back[1]) > LEVEL:
        # An ankle the depths put under the floor (seen from above, a heel drawn below its toes, 11
        # of 100 artist-style storyboards, one 8 cm deep) slides along its ray up to ankle_floor.
        ankles = np.array([at[j] for j in ANKLES if mask[j]], int)
        height = origin[sketched[ankles], 1] + (depth[sketched[ankles]] + x[ankles]) * back[1]
        x[ankles] += np.maximum(config.ankle_floor - height, 0.0) / back[1]
    out = joints.copy()
    for j in range(NUM_JOINTS):
        if mask[j]:
            out[j] = origin[j] + (depth[j] + x[at[j]]) * back
        elif PARENTS[j] >= 0:
            out[j] = out[PARENTS[j]] + joints[j] - joints[PARENTS[j]]
    if abs(back[1]) > LEVEL:   # the lower foot exactly on the ground: a slide along the ray keeps the sketch
        out += grounding_height(out, config.foot_height) / back[1] * back
    return out


def _least_squares(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """argmin |a x - b| for a (R, S) of full column rank (the depth anchor rows make it so), by
    the normal equations: np.linalg.lstsq's SVD cost 0.13 ms a call, half of the warp's time."""
    return np.linalg.solve(a.T @ a, a.T @ b)


def _sketched_ancestor(joint: int, mask: np.ndarray) -> int:
    """The nearest of `joint`'s ancestors that mask (22,) places, or -1."""
    parent = PARENTS[joint]
    while parent >= 0 and not mask[parent]:
        parent = PARENTS[parent]
    return parent


def warp_to_keyposes(joints: np.ndarray, offsets: np.ndarray, storyboard: Storyboard,
                     config: WarpConfig = WarpConfig()) -> np.ndarray:
    """Every person passes through their sketched keyposes (exactly in the sketch plane, where
    bone lengths allow). joints (N, H, 22, 3), offsets (H, 22, 3) -> (N, H, 22, 3).

    The offsets spread between keys are joint displacements relative to the pelvis, in the
    body's own (heading) frame, so they turn with the body; the skeleton is then refitted, and
    around the keys the legs reach for the displaced feet (the solved keypose's bones are not
    quite the skeleton's, and a refit from the hips put feet 5 cm under or over the ground), and the
    arms for the wrists that the keys place (a figure drawn out of proportion, as an artist's
    stretched by up to 12%, has bones the skeleton cannot match: the refit left its wrists 4-5 cm
    off their drawn points). Local rotation offsets would be the textbook choice, but a solved
    keypose often tilts the IK's pelvis frame by 60 degrees or more and the hips back by as much;
    half of each, between keys, folds the legs up off the ground (a carrier crawled through the
    let_go example)."""
    out = joints.copy()
    n = len(joints)
    warped = {}                                      # person -> (root (N, 3), target (N, 22, 3), keyposes)
    for h, agent in enumerate(storyboard.agents):
        keys = sorted((k for k in storyboard.keyposes if k.agent == agent.id and k.mask.any()),
                      key=lambda k: k.frame)
        if not keys:
            continue
        frames = [k.frame for k in keys]
        lengths = norm(offsets[h])
        posed = np.stack([solve_keypose(joints[k.frame, h], k.points, k.mask, storyboard.camera, lengths, config, k.depth)
                          for k in keys])                                        # (K, 22, 3)
        body = joints[:, h] - joints[:, h, PELVIS:PELVIS + 1]                     # (N, 22, 3) from the pelvis
        hips = joints[:, h, L_HIP] - joints[:, h, R_HIP]
        heading = gaussian_filter1d(np.unwrap(heading_of(cross(hips, UP))), config.heading_smoothing, mode="nearest")
        turn = yaw_matrix(heading)                                                # (N, 3, 3) body -> world
        moved = posed - posed[:, PELVIS:PELVIS + 1] - body[frames]
        local = moved @ turn[frames]                                             # world -> body frame
        root = joints[:, h, PELVIS] + spread(n, frames, posed[:, PELVIS] - joints[frames, h, PELVIS], config.falloff)
        pose = spread(n, frames, local, config.falloff) * closeness_to_keys(n, frames, config.pose_falloff)[:, None, None]
        warped[h] = (root, root[:, None] + body + pose @ np.swapaxes(turn, -1, -2), keys)
    if not warped:
        return out
    people = list(warped)                            # the refit, all people at once
    root, target = (np.stack([warped[h][i] for h in people], 1) for i in (0, 1))
    out[:, people] = forward_kinematics(root, inverse_kinematics(target, offsets[people]), offsets[people])
    for h in people:
        # The refit moved the feet (a keypose's solved bones are not quite the skeleton's): around
        # the keys the legs reach for the warped feet. Further out the refit's own legs stay
        # (reaching all along made the steps between keys less natural: FID 0.27 -> 0.40).
        target, keys = warped[h][1], warped[h][2]
        near = closeness_to_keys(n, [k.frame for k in keys], config.falloff)[:, None]
        for side, foot in enumerate(FEET):
            out[:, h] = reach_with_leg(out[:, h], side, out[:, h, foot] + near * (target[:, foot] - out[:, h, foot]))
    # So did the wrists: around the keys that place them, the arms reach for the warped wrists,
    # the elbows bending towards the warped ones.
    goal, weight = np.zeros(out.shape[:2] + (2, 3)), np.zeros(out.shape[:2] + (2,))
    elbows = out[:, :, list(ELBOWS)].copy()
    for h in people:
        target, keys = warped[h][1], warped[h][2]
        for side, wrist in enumerate(HANDS):
            placing = [k.frame for k in keys if k.mask[wrist]]
            if placing:
                goal[:, h, side], weight[:, h, side] = target[:, wrist], closeness_to_keys(n, placing, config.falloff)
                elbows[:, h, side] = target[:, ELBOWS[side]]
    return reach_with_arms(out, goal, weight, elbows=elbows)

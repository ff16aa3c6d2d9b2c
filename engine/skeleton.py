"""The 22-joint SMPL body: names, hierarchy, neutral rest skeleton, forward and inverse kinematics.

World conventions for the whole project (stated once, here): units are metres, Y is up, the
ground is the plane y = 0, a person in rest pose faces +Z and their left is +X. Time is counted
in frames at the clip's fps.

A pose is a root translation (3,) plus one local rotation per joint (22, 3, 3); the root's local
rotation is its global orientation. Bone offsets (22, 3) are each joint's position relative to
its parent in the parent's rest frame; the template below is a neutral adult, and imported
people get their own offsets (same directions, their bone lengths) from `fit_offsets`.
"""
from __future__ import annotations

import numpy as np

from .geometry.rotations import kabsch, norm, normalize, rotation_between

JOINT_NAMES = (
    "pelvis", "l_hip", "r_hip", "spine1", "l_knee", "r_knee", "spine2", "l_ankle", "r_ankle",
    "spine3", "l_foot", "r_foot", "neck", "l_collar", "r_collar", "head", "l_shoulder",
    "r_shoulder", "l_elbow", "r_elbow", "l_wrist", "r_wrist",
)
PARENTS = (-1, 0, 0, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 9, 9, 12, 13, 14, 16, 17, 18, 19)
NUM_JOINTS = 22
JOINT_INDEX = {name: i for i, name in enumerate(JOINT_NAMES)}
CHILDREN = tuple(tuple(c for c, p in enumerate(PARENTS) if p == j) for j in range(NUM_JOINTS))
# Left/right swap used for mirroring poses.
MIRROR = tuple(JOINT_INDEX[n.replace("l_", "#").replace("r_", "l_").replace("#", "r_")]
               for n in JOINT_NAMES)
HANDS = (JOINT_INDEX["l_wrist"], JOINT_INDEX["r_wrist"])
FEET = (JOINT_INDEX["l_foot"], JOINT_INDEX["r_foot"])
ANKLES = (JOINT_INDEX["l_ankle"], JOINT_INDEX["r_ankle"])
KNEES = (JOINT_INDEX["l_knee"], JOINT_INDEX["r_knee"])
HIPS = (JOINT_INDEX["l_hip"], JOINT_INDEX["r_hip"])
SHOULDERS = (JOINT_INDEX["l_shoulder"], JOINT_INDEX["r_shoulder"])
ELBOWS = (JOINT_INDEX["l_elbow"], JOINT_INDEX["r_elbow"])

# Neutral rest skeleton (T-pose) as parent-relative offsets in metres.
_HALF = {  # left side; the right side mirrors x
    "l_hip": (0.070, -0.090, 0.000), "l_knee": (0.035, -0.380, 0.000),
    "l_ankle": (-0.010, -0.400, -0.040), "l_foot": (0.030, -0.060, 0.130),
    "l_collar": (0.075, 0.120, -0.030), "l_shoulder": (0.110, 0.045, -0.010),
    "l_elbow": (0.260, -0.015, -0.020), "l_wrist": (0.250, 0.005, 0.000),
}
_SPINE = {
    "pelvis": (0.0, 0.0, 0.0), "spine1": (0.0, 0.110, -0.020), "spine2": (0.0, 0.135, 0.010),
    "spine3": (0.0, 0.055, 0.025), "neck": (0.0, 0.215, -0.040), "head": (0.0, 0.065, 0.050),
}


def _template_offsets() -> np.ndarray:
    out = np.zeros((NUM_JOINTS, 3))
    for name, off in _SPINE.items():
        out[JOINT_INDEX[name]] = off
    for name, off in _HALF.items():
        out[JOINT_INDEX[name]] = off
        out[JOINT_INDEX["r_" + name[2:]]] = (-off[0], off[1], off[2])
    return out


REST_OFFSETS = _template_offsets()
# Pelvis height at which the rest pose's feet touch the ground (foot joint 2 cm up).
REST_PELVIS_HEIGHT = 0.95


def rest_pose(offsets: np.ndarray = REST_OFFSETS) -> np.ndarray:
    """Joint positions (22, 3) of the rest pose standing on the ground at the origin."""
    return forward_kinematics(np.array([0.0, REST_PELVIS_HEIGHT, 0.0]),
                              np.broadcast_to(np.eye(3), (NUM_JOINTS, 3, 3)), offsets)


def bone_lengths(joints: np.ndarray) -> np.ndarray:
    """(..., 22, 3) -> (..., 22); the root's entry is 0."""
    par = np.array([max(p, 0) for p in PARENTS])
    return norm(joints - joints[..., par, :])


def forward_kinematics(root: np.ndarray, local_rot: np.ndarray,
                       offsets: np.ndarray = REST_OFFSETS) -> np.ndarray:
    """Joint positions from a pose.

    root: (..., 3) pelvis position; local_rot: (..., 22, 3, 3); offsets: (22, 3) or (..., 22, 3).
    Returns (..., 22, 3). Walked joint-major, the offsets unbroadcast (as _walk_ik).
    """
    rot = np.ascontiguousarray(np.moveaxis(local_rot, -3, 0))                     # (22, ..., 3, 3)
    bones = _joint_major(offsets, local_rot.ndim - 3)[..., None]                   # (22, ..., 3, 1)
    glob, pos = [None] * NUM_JOINTS, [None] * NUM_JOINTS
    for j, p in enumerate(PARENTS):
        if p < 0:
            glob[j], pos[j] = rot[j], np.asarray(root)
        else:
            glob[j], pos[j] = glob[p] @ rot[j], pos[p] + (glob[p] @ bones[j])[..., 0]
    return np.stack(pos, axis=-2)


def _joint_major(offsets: np.ndarray, lead: int) -> np.ndarray:
    """Offsets (..., 22, 3) -> (22, 1, ..., 3), with ones in front of their own leading axes up to
    `lead` of them: they broadcast against a joint-major batch (22, lead axes, 3) unbroadcast."""
    bones = np.moveaxis(np.asarray(offsets, float), -2, 0)
    return bones.reshape((NUM_JOINTS,) + (1,) * (lead + 2 - bones.ndim) + bones.shape[1:])


def _depth(j: int) -> int:
    return 0 if PARENTS[j] < 0 else 1 + _depth(PARENTS[j])


def _ik_levels(needed: range | tuple = range(NUM_JOINTS)) -> tuple:
    """The tree a level at a time: per depth, its joints with one child (their parents, their
    children), and its joints with several (pelvis, spine3); only the `needed` joints and their
    ancestors. IK walks it so, 8 batched steps instead of 17 joint by joint: the finishing runs IK
    about ten times per generation on small batches, where numpy's cost per call rules."""
    def ancestors(j: int) -> set[int]:
        return {j} | (ancestors(PARENTS[j]) if PARENTS[j] >= 0 else set())

    kept = set().union(*(ancestors(j) for j in needed))
    levels = []
    for depth in range(1 + max(_depth(j) for j in kept)):
        at = [j for j in sorted(kept) if _depth(j) == depth and CHILDREN[j]]
        chain = [j for j in at if len(CHILDREN[j]) == 1]
        levels.append((np.array(chain, int), np.array([PARENTS[j] for j in chain], int),
                       np.array([CHILDREN[j][0] for j in chain], int), [j for j in at if len(CHILDREN[j]) > 1]))
    return tuple(levels)


_IK_LEVELS = _ik_levels()
_BRANCHING = tuple(j for j in range(NUM_JOINTS) if len(CHILDREN[j]) > 1)   # pelvis, spine3
_BRANCH_LEVELS = _ik_levels(_BRANCHING)   # what fit_offsets needs: the branching joints' frames


def inverse_kinematics(joints: np.ndarray, offsets: np.ndarray = REST_OFFSETS,
                       root: np.ndarray | None = None) -> np.ndarray:
    """Local rotations that make FK(joints[pelvis], R, offsets) reproduce `joints`.

    joints: (..., 22, 3); root: the pelvis' rotations (..., 3, 3) to keep, or None to fit them.
    Returns local rotations (..., 22, 3, 3).
    Joints with one child get the smallest rotation (no twist) that points the bone at the
    child; joints with several children (pelvis, spine3) get the Kabsch fit of all child
    bones; leaf joints get the identity. Exact when bone geometry matches `offsets`.
    """
    return _walk_ik(joints, offsets, root, _IK_LEVELS)[0]


def _walk_ik(joints: np.ndarray, offsets: np.ndarray, root: np.ndarray | None,
             levels: tuple) -> tuple[np.ndarray, np.ndarray]:
    """inverse_kinematics over `levels` (_ik_levels) -> (local (..., 22, 3, 3), global rotations
    (..., 23, 3, 3), the last the root's parent's); joints outside the levels are left identity
    (local) or undefined (global). Walked joint-major (joints on the first axis): a level's
    gathers and stores are then block copies, and the offsets stay unbroadcast."""
    lead = joints.shape[:-2]
    at = np.ascontiguousarray(np.moveaxis(joints, -2, 0))          # (22, ..., 3)
    bones = _joint_major(offsets, len(lead))                         # (22, ..., 3)
    local = np.empty((NUM_JOINTS,) + lead + (3, 3))
    local[...] = np.eye(3)
    glob = np.empty((NUM_JOINTS + 1,) + lead + (3, 3))   # the extra last entry is the root's parent, index -1
    glob[NUM_JOINTS] = np.eye(3)
    for chain, parents, kids, branching in levels:
        if len(chain):
            parent_glob = glob[parents]
            # Child bone directions expressed in the parent's frame (undo the parent's rotation).
            target = ((at[kids] - at[chain])[..., None, :] @ parent_glob)[..., 0, :]
            R_local = rotation_between(bones[kids], target)
            local[chain] = R_local
            glob[chain] = parent_glob @ R_local
        for j in branching:
            parent_glob = glob[PARENTS[j]]
            kids_j = list(CHILDREN[j])
            target = np.moveaxis(at[kids_j] - at[j], 0, -2) @ parent_glob        # (..., children, 3)
            R_local = root if j == 0 and root is not None else kabsch(
                np.broadcast_to(np.moveaxis(bones[kids_j], 0, -2), target.shape), target)
            local[j] = R_local
            glob[j] = parent_glob @ R_local
    return np.ascontiguousarray(np.moveaxis(local, 0, -3)), np.moveaxis(glob, 0, -3)


def fit_offsets(joints: np.ndarray, iterations: int = 3) -> np.ndarray:
    """Bone offsets (..., 22, 3) for a clip of joint positions (N, ..., 22, 3): one body per
    person of (N, H, 22, 3), or (22, 3) for one person's (N, 22, 3).

    Bone lengths are the clip's medians; single-child bones keep the template direction;
    the children of branching joints (pelvis, spine3) are re-estimated in their parent's
    local frame so that FK(IK(joints)) reproduces the clip's rigid branch geometry.
    """
    lengths = np.median(bone_lengths(joints), axis=0)
    offsets = normalize(REST_OFFSETS) * lengths[..., None]
    offsets[..., 0, :] = 0.0
    for _ in range(iterations):
        glob = _walk_ik(joints, offsets, None, _BRANCH_LEVELS)[1]
        for j in _BRANCHING:
            for c in CHILDREN[j]:
                local = np.einsum("...ji,...j->...i", glob[..., j, :, :], joints[..., c, :] - joints[..., j, :])
                offsets[..., c, :] = np.mean(local, axis=0)
    return offsets

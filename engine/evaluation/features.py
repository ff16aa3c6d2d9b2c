"""What the motion evaluator reads: per-frame feature sequences of a scene and of a storyboard.

Motion features are made translation- and yaw-invariant by canonicalisation: the pelvises' mean
ground position at the first frame goes to the origin and person 0's facing at the first frame
(from hips and shoulders) is turned to +Z. Storyboard features need no canonicalisation: the
sketch-plane strokes do not change when scene and camera turn and move together, so of the
camera only what survives a global yaw and shift is read (its elevation and target height).

Shapes (B batch, N frames; H = 2 people, O = 1 object slot):
  motion_features(joints (B,N,2,22,3), obj_pose (B,N,1,7), obj_present (B,), valid (B,N), fps)
      -> (B, N, MOTION_FEATURES)
  story_features(controls dict of (B,...) tensors, valid (B,N)) -> (B, N, STORY_FEATURES)
"""
from __future__ import annotations

import torch

from ..geometry.rotations_torch import quat_to_matrix
from ..skeleton import JOINT_INDEX, NUM_JOINTS

NUM_HUMANS = 2
PELVIS = JOINT_INDEX["pelvis"]
ACROSS_PAIRS = ((JOINT_INDEX["l_hip"], JOINT_INDEX["r_hip"]),
                (JOINT_INDEX["l_shoulder"], JOINT_INDEX["r_shoulder"]))

# Per frame: joints and their velocities; object position, 6D rotation, velocity, presence; valid.
MOTION_FEATURES = 2 * NUM_HUMANS * NUM_JOINTS * 3 + 3 + 6 + 3 + 1 + 1
# Per frame: keypose and trajectory points with their masks, object box / path with masks,
# contact and anchor flags, camera elevation and target height, valid.
STORY_FEATURES = 2 * NUM_HUMANS * NUM_JOINTS * 3 + 4 + 1 + 2 + 1 + 2 * NUM_HUMANS * 2 + 2 + 1


def first_frame_frame(joints: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """The canonical frame of each scene: origin (B, 3) on the ground under the pelvises' mean
    at frame 0, and the yaw rotation (B, 3, 3) that turns person 0's facing at frame 0 to +Z."""
    origin = joints[:, 0, :, PELVIS].mean(dim=1) * joints.new_tensor([1.0, 0.0, 1.0])
    first = joints[:, 0, 0]                                               # (B, 22, 3)
    across = sum(first[:, left] - first[:, right] for left, right in ACROSS_PAIRS)
    # Facing = across x up; with Y up that is (-across_z, 0, across_x) (left is +X facing +Z).
    facing_x, facing_z = -across[:, 2], across[:, 0]
    yaw = torch.atan2(facing_x, facing_z)
    c, s = torch.cos(-yaw), torch.sin(-yaw)
    zero, one = torch.zeros_like(c), torch.ones_like(c)
    turn = torch.stack([torch.stack([c, zero, s], -1),
                        torch.stack([zero, one, zero], -1),
                        torch.stack([-s, zero, c], -1)], -2)
    return origin, turn


def _velocity(x: torch.Tensor, fps: float) -> torch.Tensor:
    """Backward differences along time (dim 1), in units per second; zero at the first frame."""
    return torch.cat([torch.zeros_like(x[:, :1]), x[:, 1:] - x[:, :-1]], dim=1) * fps


def motion_features(joints: torch.Tensor, obj_pose: torch.Tensor, obj_present: torch.Tensor,
                    valid: torch.Tensor, fps: float) -> torch.Tensor:
    """(B,N,2,22,3), (B,N,1,7), (B,), (B,N) -> canonical per-frame features (B, N, MOTION_FEATURES)."""
    b, n = joints.shape[:2]
    origin, turn = first_frame_frame(joints)
    canon = torch.einsum("bij,bnhkj->bnhki", turn, joints - origin[:, None, None, None])
    present = obj_present.reshape(b, 1, 1).to(joints.dtype)
    obj_pos = torch.einsum("bij,bnj->bni", turn, obj_pose[:, :, 0, :3] - origin[:, None]) * present
    obj_rot = turn[:, None] @ quat_to_matrix(obj_pose[:, :, 0, 3:])          # (B, N, 3, 3)
    obj_rot6d = obj_rot[..., :2].transpose(-1, -2).reshape(b, n, 6) * present
    flat = canon.reshape(b, n, -1)
    return torch.cat([flat, _velocity(flat, fps), obj_pos, obj_rot6d, _velocity(obj_pos, fps),
                      present.expand(b, n, 1), valid.reshape(b, n, 1).to(joints.dtype)], dim=-1)


def story_features(controls: dict[str, torch.Tensor], valid: torch.Tensor) -> torch.Tensor:
    """Controls (fields of engine.controls.Controls batched, object axis one slot, masks bool or
    0/1) and valid (B, N) -> per-frame features (B, N, STORY_FEATURES)."""
    kp_mask = controls["kp_mask"].float()
    b, n = kp_mask.shape[:2]
    tr_mask = controls["tr_mask"].float()
    obj_mask = controls["obj_mask"].float()
    path_mask = controls["objpath_mask"].float()
    camera = controls["camera"].float().reshape(b, 1, 3, 3)
    per_frame_camera = torch.stack([camera[:, :, 2, 1],                     # sin(elevation)
                                    controls["cam_target"].float()[:, None, 1]], -1).expand(b, n, 2)
    parts = [
        (controls["kp2d"].float() * kp_mask[..., None]).reshape(b, n, -1), kp_mask.reshape(b, n, -1),
        (controls["tr2d"].float() * tr_mask[..., None]).reshape(b, n, -1), tr_mask.reshape(b, n, -1),
        (controls["obj2d"].float() * obj_mask[..., None]).reshape(b, n, -1), obj_mask.reshape(b, n, -1),
        (controls["objpath2d"].float() * path_mask[..., None]).reshape(b, n, -1), path_mask.reshape(b, n, -1),
        controls["contact"].float().reshape(b, n, -1),
        (controls["contact_anchor"] >= 0).float().reshape(b, n, -1),
        per_frame_camera, valid.reshape(b, n, 1).float(),
    ]
    return torch.cat(parts, dim=-1)

"""Changing the frame rate of motion: linear for positions, slerp for rotations.

Frame k of the output is at time k / dst_fps; the output stops at the last input frame's time.
No low-pass filter: smoothing joint positions one by one bends the rigid skeleton during fast
turns (on the CMU salsa takes the fitted skeleton then missed the smoothed joints by up to 35 mm).
"""
from __future__ import annotations

import numpy as np

from ..clip import MotionClip
from ..geometry.rotations import matrix_to_6d, matrix_to_quat, normalize, quat_to_matrix, sixd_to_matrix
from ..skeleton import forward_kinematics


def source_positions(num_frames: int, src_fps: float, dst_fps: float) -> np.ndarray:
    """(M,) fractional input-frame index of each output frame."""
    if num_frames < 1 or src_fps <= 0 or dst_fps <= 0:
        raise ValueError(f"cannot resample {num_frames} frames from {src_fps} to {dst_fps} fps")
    last = (num_frames - 1) * dst_fps / src_fps
    count = int(np.floor(last + 1e-6)) + 1
    return np.minimum(np.arange(count) * (src_fps / dst_fps), num_frames - 1)


def _bracket(pos: np.ndarray, num_frames: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    i0 = np.floor(pos).astype(int)
    i1 = np.minimum(i0 + 1, num_frames - 1)
    return i0, i1, pos - i0


def resample_linear(x: np.ndarray, src_fps: float, dst_fps: float) -> np.ndarray:
    """x: (F, ...) -> (M, ...) sampled at dst_fps by linear interpolation."""
    x = np.asarray(x, dtype=np.float64)
    i0, i1, w = _bracket(source_positions(x.shape[0], src_fps, dst_fps), x.shape[0])
    w = w.reshape((-1,) + (1,) * (x.ndim - 1))
    return (1.0 - w) * x[i0] + w * x[i1]


def resample_quaternions(q: np.ndarray, src_fps: float, dst_fps: float) -> np.ndarray:
    """Unit quaternions q: (F, ..., 4) wxyz -> (M, ..., 4) by spherical linear interpolation."""
    q = normalize(np.asarray(q, dtype=np.float64))
    i0, i1, w = _bracket(source_positions(q.shape[0], src_fps, dst_fps), q.shape[0])
    a, b = q[i0], q[i1]
    w = w.reshape((-1,) + (1,) * (q.ndim - 1))
    dot = np.sum(a * b, axis=-1, keepdims=True)
    b = np.where(dot < 0, -b, b)  # take the short way round
    dot = np.abs(dot)
    theta = np.arccos(np.clip(dot, -1.0, 1.0))
    sin = np.sin(theta)
    near = sin < 1e-6  # almost equal: lerp is exact enough and avoids 0/0
    safe = np.where(near, 1.0, sin)
    wa = np.where(near, 1.0 - w, np.sin((1.0 - w) * theta) / safe)
    wb = np.where(near, w, np.sin(w * theta) / safe)
    return normalize(wa * a + wb * b)


def resample_clip(clip: MotionClip, fps: float) -> MotionClip:
    """The clip at another frame rate, on its skeleton: pelvis positions linear, local rotations
    and object orientations by slerp, joints recomputed by FK (bones stay rigid); anchors and
    phase linear, contact flags by the nearer frame's value (linear, then rounded). A clip with
    no bone offsets (generated motion, whose rotations need not match its joints exactly) has
    its joints interpolated linearly instead. The same clip when the rate already matches."""
    if abs(clip.fps - fps) < 1e-6:
        return clip

    def lin(x):
        return None if x is None else resample_linear(x, clip.fps, fps)

    quat = matrix_to_quat(sixd_to_matrix(clip.rot6d.astype(np.float64)))           # (N, H, 22, 4)
    rot = quat_to_matrix(resample_quaternions(quat, clip.fps, fps))
    if clip.bone_offsets is None:
        joints = lin(clip.joints)
    else:
        root = lin(clip.joints[:, :, 0])
        joints = np.stack([forward_kinematics(root[:, h], rot[:, h], clip.bone_offsets[h])
                           for h in range(clip.num_humans)], 1)
    obj_pose = None
    if clip.obj_pose is not None:
        obj_pose = np.concatenate([lin(clip.obj_pose[..., :3]),
                                   resample_quaternions(clip.obj_pose[..., 3:], clip.fps, fps)], axis=-1)
    contact = None if clip.contact is None else np.round(lin(clip.contact))
    return MotionClip(fps=fps, joints=joints, rot6d=matrix_to_6d(rot), obj_pose=obj_pose,
                      obj_anchors=lin(clip.obj_anchors), obj_type=clip.obj_type, obj_size=clip.obj_size,
                      bone_offsets=clip.bone_offsets, phase=lin(clip.phase), contact=contact,
                      scenario=clip.scenario)

"""The motion clip: what the synthesizer, importers, sampler and exporters exchange.

Stored as an NPZ (docs/clip_format.md). Shapes: N frames, H humans, O objects, K anchors.
"""
from __future__ import annotations

from dataclasses import dataclass, fields
from pathlib import Path

import numpy as np

from .atomic import atomic_write
from .geometry.rotations import matrix_to_6d
from .skeleton import NUM_JOINTS, REST_OFFSETS, fit_offsets, inverse_kinematics

PHASES = ("approach", "contact", "carry")
FORMAT_VERSION = 1


class ClipError(ValueError):
    """A clip file that cannot be read or is inconsistent."""


@dataclass
class MotionClip:
    fps: float
    joints: np.ndarray                      # (N, H, 22, 3) float32, metres, Y up
    rot6d: np.ndarray                       # (N, H, 22, 6) float32, local rotations
    obj_pose: np.ndarray | None = None      # (N, O, 7) xyz + quaternion wxyz
    obj_anchors: np.ndarray | None = None   # (N, O, K, 3) world anchor positions
    obj_type: np.ndarray | None = None      # (O,) str: box / table / canister
    obj_size: np.ndarray | None = None      # (O, 3) bounding box in metres
    bone_offsets: np.ndarray | None = None  # (H, 22, 3) per-person skeleton for FK
    phase: np.ndarray | None = None         # (N, 3) occupancy of approach / contact / carry
    contact: np.ndarray | None = None       # (N, H, 2) left / right hand in contact (0/1)
    scenario: str = ""

    def __post_init__(self):
        _check(isinstance(self.fps, (int, float, np.floating, np.integer)) and 0 < float(self.fps) <= 1000,
               f"fps must be a number in (0, 1000], got {self.fps}")
        self.joints = np.asarray(self.joints, np.float32)
        self.rot6d = np.asarray(self.rot6d, np.float32)
        n, h = self.joints.shape[:2]
        _check(self.joints.shape == (n, h, NUM_JOINTS, 3), f"joints must be (N,H,22,3), got {self.joints.shape}")
        _check(self.rot6d.shape == (n, h, NUM_JOINTS, 6), f"rot6d must be (N,H,22,6), got {self.rot6d.shape}")
        if self.obj_pose is not None:
            self.obj_pose = np.asarray(self.obj_pose, np.float32)
            o = self.obj_pose.shape[1]
            _check(self.obj_pose.shape == (n, o, 7), f"obj_pose must be (N,O,7), got {self.obj_pose.shape}")
            if self.obj_anchors is not None:
                self.obj_anchors = np.asarray(self.obj_anchors, np.float32)
                _check(self.obj_anchors.shape[:2] == (n, o) and self.obj_anchors.shape[3] == 3,
                       f"obj_anchors must be (N,O,K,3), got {self.obj_anchors.shape}")
        for name, shape in (("phase", (n, 3)), ("contact", (n, h, 2))):
            v = getattr(self, name)
            if v is not None:
                v = np.asarray(v, np.float32)
                _check(v.shape == shape, f"{name} must be {shape}, got {v.shape}")
                setattr(self, name, v)
        for name in ("joints", "rot6d", "obj_pose", "obj_anchors", "phase", "contact"):
            v = getattr(self, name)
            _check(v is None or np.all(np.isfinite(v)), f"{name} contains NaN or infinite values")

    @property
    def num_frames(self) -> int:
        return self.joints.shape[0]

    @property
    def num_humans(self) -> int:
        return self.joints.shape[1]

    @property
    def num_objects(self) -> int:
        return 0 if self.obj_pose is None else self.obj_pose.shape[1]

    @property
    def duration(self) -> float:
        return self.num_frames / self.fps

    @classmethod
    def from_joints(cls, joints: np.ndarray, fps: float, **kw) -> "MotionClip":
        """Build a clip from joint positions (N, H, 22, 3), solving IK for the rotations."""
        offsets = np.stack([fit_offsets(joints[:, h]) for h in range(joints.shape[1])])
        rot = np.stack([inverse_kinematics(joints[:, h], offsets[h]) for h in range(joints.shape[1])], 1)
        return cls(fps=fps, joints=joints, rot6d=matrix_to_6d(rot), bone_offsets=offsets, **kw)

    def offsets(self) -> np.ndarray:
        """(H, 22, 3) bone offsets, the template where the clip has none."""
        if self.bone_offsets is not None:
            return np.asarray(self.bone_offsets)
        return np.broadcast_to(REST_OFFSETS, (self.num_humans, NUM_JOINTS, 3))

    def slice(self, start: int, stop: int) -> "MotionClip":
        kw = {f.name: getattr(self, f.name) for f in fields(self)}
        for name in ("joints", "rot6d", "obj_pose", "obj_anchors", "phase", "contact"):
            if kw[name] is not None:
                kw[name] = kw[name][start:stop]
        return MotionClip(**kw)

    def to_arrays(self) -> dict[str, np.ndarray]:
        """The clip as named arrays (what its NPZ file holds)."""
        arrays = {"format_version": np.int32(FORMAT_VERSION), "fps": np.float32(self.fps),
                  "scenario": np.str_(self.scenario)}
        for f in fields(self):
            v = getattr(self, f.name)
            if f.name not in arrays and v is not None:
                arrays[f.name] = np.asarray(v)
        return arrays

    @classmethod
    def from_arrays(cls, data: dict[str, np.ndarray], where: str) -> "MotionClip":
        """A clip from to_arrays' arrays; ClipError naming `where` for anything wrong."""
        data = dict(data)
        for key in ("fps", "joints", "rot6d"):
            _check(key in data, f"{where}: missing required array '{key}'")
        try:
            version = int(data.pop("format_version", FORMAT_VERSION))
            _check(version <= FORMAT_VERSION, f"clip format version {version} is newer than this program")
            known = {f.name for f in fields(cls)}
            kw = {k: v for k, v in data.items() if k in known}
            kw["fps"] = float(kw["fps"])
            kw["scenario"] = str(kw.get("scenario", ""))
            return cls(**kw)
        except (ClipError, TypeError, ValueError) as e:   # a wrong shape, type or value in a readable file
            raise ClipError(f"{where}: {str(e).splitlines()[0] if str(e) else type(e).__name__}") from None

    def save(self, path: str | Path) -> None:
        with atomic_write(path) as f:
            np.savez_compressed(f, **self.to_arrays())

    @classmethod
    def load(cls, path: str | Path) -> "MotionClip":
        try:
            with np.load(path, allow_pickle=False) as z:
                data = {k: z[k] for k in z.files}
        except Exception as e:  # zipfile, OSError, ValueError: all mean "not a clip"
            raise ClipError(f"{path}: not a readable motion clip NPZ ({e})") from None
        return cls.from_arrays(data, str(path))


def _check(ok: bool, message: str) -> None:
    if not ok:
        raise ClipError(message)

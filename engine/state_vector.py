"""Scene state of H humans and O objects, and its flattening to the paper's D_full vector.

Per frame: each human has joint positions (22, 3) and local 6D rotations (22, 6); each object a
pose (7: translation + unit quaternion wxyz) and K_o world anchors (K_o, 3). Flattened, a frame
is D_full = H*22*(3+6) + O*(3+4) + sum_o K_o*3 numbers, laid out as
[human 0: joints, rot6d | human 1 ... | object 0 pose | ... | object 0 anchors | ...].
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .skeleton import NUM_JOINTS

HUMAN_DIM = NUM_JOINTS * 9


@dataclass(frozen=True)
class SceneLayout:
    num_humans: int
    anchors_per_object: tuple[int, ...] = ()

    @property
    def num_objects(self) -> int:
        return len(self.anchors_per_object)

    @property
    def dim(self) -> int:
        """D_full."""
        return self.num_humans * HUMAN_DIM + 7 * self.num_objects + 3 * sum(self.anchors_per_object)

    def flatten(self, joints: np.ndarray, rot6d: np.ndarray, obj_pose: np.ndarray | None = None,
                obj_anchors: list[np.ndarray] | None = None) -> np.ndarray:
        """joints (N, H, 22, 3), rot6d (N, H, 22, 6), obj_pose (N, O, 7),
        obj_anchors: per object (N, K_o, 3). Returns (N, D_full)."""
        n = joints.shape[0]
        parts = [np.concatenate([joints, rot6d], axis=-1).reshape(n, -1)]
        if self.num_objects:
            parts.append(obj_pose.reshape(n, -1))
            parts += [a.reshape(n, -1) for a in obj_anchors]
        out = np.concatenate(parts, axis=-1)
        if out.shape[1] != self.dim:
            raise ValueError(f"scene has {out.shape[1]} numbers per frame, layout expects {self.dim}")
        return out

    def unflatten(self, flat: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[np.ndarray]]:
        """(N, D_full) -> joints, rot6d, obj_pose (N, O, 7), [anchors (N, K_o, 3)]."""
        if flat.shape[-1] != self.dim:
            raise ValueError(f"expected {self.dim} numbers per frame, got {flat.shape[-1]}")
        n, h = flat.shape[0], self.num_humans
        hum = flat[:, :h * HUMAN_DIM].reshape(n, h, NUM_JOINTS, 9)
        off = h * HUMAN_DIM
        pose = flat[:, off:off + 7 * self.num_objects].reshape(n, self.num_objects, 7)
        off += 7 * self.num_objects
        anchors = []
        for k in self.anchors_per_object:
            anchors.append(flat[:, off:off + 3 * k].reshape(n, k, 3))
            off += 3 * k
        return hum[..., :3], hum[..., 3:], pose, anchors

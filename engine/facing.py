"""Which way a sketched figure faces, and the figure turned about the vertical.

A keypose is 2D; turning it needs depth: each joint's horizontal distance in front of or behind
its feet along the view (Keypose.depth, known for a stamped or turned pose; else that of a 3D
pose of the same person, such as the generated motion at that frame; else 0: upright and flat).
The figure is lifted onto the camera rays with its feet on the ground at those depths, turned
about the vertical through its feet and seen through the camera again: it keeps its place.
"""
from __future__ import annotations

import numpy as np

from .camera import StoryboardCamera
from .skeleton import FEET, JOINT_INDEX, PARENTS
from .synth.reach import heading_of

L_HIP, R_HIP = JOINT_INDEX["l_hip"], JOINT_INDEX["r_hip"]


def towards_camera(camera: StoryboardCamera) -> np.ndarray:
    """The horizontal unit direction (3,) towards the camera."""
    back = camera.basis()[2]
    return np.array([back[0], 0.0, back[2]]) / max(np.hypot(back[0], back[2]), 1e-9)


def depth_of(pose_3d: np.ndarray, camera: StoryboardCamera) -> np.ndarray:
    """World joints (22, 3) -> (22,) depths as Keypose.depth measures them."""
    return (pose_3d - pose_3d[list(FEET)].mean(0)) @ towards_camera(camera)


def lift(points: np.ndarray, camera: StoryboardCamera, depth: np.ndarray | None = None) -> np.ndarray:
    """Sketch points (22, 2) -> world joints (22, 3), each on its camera ray, the feet on the
    ground and each joint at its depth (22,) (0 where not given: upright in the feet's plane)."""
    right, up, back = camera.basis()
    on_plane = np.asarray(camera.target) + points[:, :1] * right + points[:, 1:2] * up
    feet = list(FEET)
    ground = on_plane[feet].mean(0) - on_plane[feet].mean(0)[1] / back[1] * back   # under the feet
    towards = towards_camera(camera)
    depth = np.zeros(len(points)) if depth is None else depth - depth[feet].mean()
    along_ray = (depth + (ground - on_plane) @ towards) / (back @ towards)
    return on_plane + along_ray[:, None] * back


def facing(joints: np.ndarray) -> float:
    """Yaw (radians, 0 = facing +Z) of world joints (22, 3): square to the hips."""
    across = joints[L_HIP] - joints[R_HIP]
    return float(heading_of(np.array([-across[2], 0.0, across[0]])))


def turned(points: np.ndarray, camera: StoryboardCamera, angle: float, depth: np.ndarray | None = None
           ) -> tuple[np.ndarray, np.ndarray]:
    """(sketch points (22, 2), depths (22,)) of the figure turned about the vertical through its
    feet, its yaw (as `facing` measures it) grown by `angle` radians."""
    joints = lift(points, camera, depth)
    centre = joints[list(FEET)].mean(0)
    c, s = np.cos(angle), np.sin(angle)
    spun = (joints - centre) @ np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]]).T + centre
    return camera.project(spun), depth_of(spun, camera)


def moved_depth(before: np.ndarray, depth: np.ndarray, after: np.ndarray, camera: StoryboardCamera) -> np.ndarray:
    """Depths (22,) of a figure whose sketch points (22, 2) moved from `before` (at depths `depth`)
    to `after`: each joint that moved, or whose parent did, slides along its new camera ray to
    keep its bone's 3D length (the slide nearest its old depth; as near as the ray comes where
    it is out of reach). A dragged hand had kept its stamped depth, and the warp solves a key at
    the depths it knows."""
    old = lift(before, camera, depth)
    new = lift(after, camera, depth)
    back = camera.basis()[2]
    moved = np.linalg.norm(np.asarray(after) - before, axis=-1) > 1e-9
    for j in range(1, len(PARENTS)):   # parents first
        p = PARENTS[j]
        moved[j] |= moved[p]
        if moved[j]:
            length = np.linalg.norm(old[j] - old[p])
            o = new[j] - new[p]                                   # on the ray: o + t back, t from here
            b, c = o @ back, o @ o - length ** 2                   # |o + t back|^2 = length^2
            roots = -b + np.array([-1.0, 1.0]) * np.sqrt(max(b * b - c, 0.0))
            new[j] = new[j] + roots[np.argmin(np.abs(roots))] * back
    return depth_of(new, camera)

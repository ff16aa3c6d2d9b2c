"""Export one person of a MotionClip as BVH with the 22-joint SMPL hierarchy.

Joints keep our names (skeleton.JOINT_NAMES), offsets come from clip.offsets() in metres, the
root has channels "Xposition Yposition Zposition" + rotations and every other joint has three
rotation channels, all in EXPORT_ORDER (default "Zrotation Yrotation Xrotation": R = Rz @ Ry @ Rx,
degrees). The five leaf joints (feet, head, wrists) get an End Site that continues their bone by
END_SITE_LENGTH so that viewers draw a stub. World axes are ours: Y up, +Z forward, +X left.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..atomic import write_text
from ..clip import MotionClip
from ..geometry.rotations import matrix_to_euler, normalize, sixd_to_matrix
from ..skeleton import CHILDREN, JOINT_NAMES, PARENTS
from .bvh import END_SITE, BvhMotion, BvhNode, format_bvh

EXPORT_ORDER = "ZYX"
END_SITE_LENGTH = 0.05  # metres


def clip_to_bvh(clip: MotionClip, human_index: int, order: str = EXPORT_ORDER) -> BvhMotion:
    """BvhMotion for person `human_index`: (N, 6 + 21*3) channel data, frame time 1/fps."""
    if not 0 <= human_index < clip.num_humans:
        raise IndexError(f"human_index {human_index} out of range for {clip.num_humans} people")
    offsets = clip.offsets()[human_index].astype(np.float64)
    rot = sixd_to_matrix(clip.rot6d[:, human_index].astype(np.float64))      # (N, 22, 3, 3)
    angles = matrix_to_euler(rot, order)                                      # (N, 22, 3)
    rot_channels = tuple(f"{ax}rotation" for ax in order.upper())
    nodes: list[BvhNode] = []
    index_of = {}
    column = 0
    # Depth-first so that BVH nesting and node order agree.
    stack = [0]
    while stack:
        j = stack.pop()
        parent = -1 if PARENTS[j] < 0 else index_of[PARENTS[j]]
        channels = (("Xposition", "Yposition", "Zposition") if parent < 0 else ()) + rot_channels
        index_of[j] = len(nodes)
        nodes.append(BvhNode(JOINT_NAMES[j], parent, offsets[j], channels, column))
        column += len(channels)
        if not CHILDREN[j]:
            stub = normalize(offsets[j]) * END_SITE_LENGTH
            nodes.append(BvhNode(f"{JOINT_NAMES[j]}/{END_SITE}", index_of[j], stub, (), column))
        stack.extend(reversed(CHILDREN[j]))
    order_in_file = [JOINT_NAMES.index(n.name) for n in nodes if not n.is_end_site]
    root = clip.joints[:, human_index, 0].astype(np.float64)                  # (N, 3)
    data = np.concatenate([root] + [angles[:, j] for j in order_in_file], axis=1)
    return BvhMotion(nodes, 1.0 / clip.fps, data)


def write_bvh(clip: MotionClip, human_index: int, path: str | Path, order: str = EXPORT_ORDER) -> None:
    """Write person `human_index` of `clip` to a BVH file."""
    write_text(path, format_bvh(clip_to_bvh(clip, human_index, order)))

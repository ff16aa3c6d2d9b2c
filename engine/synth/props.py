"""The object in a synthesized scene: random shape and size, which grips a hand takes, poses.

Grips are the object's anchors (engine.objects.default_anchors): two on each x end.
"""
from __future__ import annotations

import numpy as np

from ..objects import DEFAULT_SIZES, GRIP_SIGNS, NUM_ANCHORS, OBJECT_TYPES, ObjectSpec, local_to_world
from .reach import UP

def random_object(rng: np.random.Generator, types: tuple[str, ...] = OBJECT_TYPES,
                  size_range: tuple[float, float] = (0.8, 1.25)) -> ObjectSpec:
    kind = str(rng.choice(types))
    size = np.asarray(DEFAULT_SIZES[kind]) * rng.uniform(*size_range, size=3)
    if kind == "canister":
        size[2] = size[0]  # round
    return ObjectSpec(kind, tuple(size))


def end_grips(sx: float) -> list[int]:
    """Anchor indices of the x end with sign sx."""
    return [k for k in range(NUM_ANCHORS) if GRIP_SIGNS[k, 0] == sx]


def side_grips(sz: float) -> list[int]:
    """Anchor indices on the side with z sign sz (one per x end)."""
    return [k for k in range(NUM_ANCHORS) if GRIP_SIGNS[k, 1] == sz]


def pose_array(position: np.ndarray, yaw: np.ndarray) -> np.ndarray:
    """Object poses (N, 7) xyz + wxyz from positions (N, 3) and yaw about +Y (N,)."""
    half = yaw / 2
    quat = np.stack([np.cos(half), np.zeros_like(half), np.sin(half), np.zeros_like(half)], -1)
    return np.concatenate([position, quat], axis=-1)


def world_anchors(spec: ObjectSpec, pose: np.ndarray) -> np.ndarray:
    """(N, 7) -> (N, K, 3)."""
    return local_to_world(spec.anchors, pose)


def assign_hands(grips: list[int], anchors: np.ndarray, yaw: float) -> tuple[int, int]:
    """Which of two grips (world positions anchors (K, 3)) the left and right hand take for a
    person facing yaw: the grip further to their left goes to the left hand."""
    left = np.cross(UP, np.array([np.sin(yaw), 0.0, np.cos(yaw)]))
    a, b = grips
    return (a, b) if (anchors[a] - anchors[b]) @ left > 0 else (b, a)

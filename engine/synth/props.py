"""The object in a synthesized scene: random shape and size, its four grip anchors, poses.

Every object gets K = 4 anchors at (sx * a, y, sz * b) for sx, sz in {-1, +1}, ordered
[(-,-), (-,+), (+,-), (+,+)]: two grips on each x end, so that two people holding the two ends
(sx) or one person holding the near side (sz) each have a grip for each hand.
"""
from __future__ import annotations

import numpy as np

from ..objects import DEFAULT_SIZES, OBJECT_TYPES, TABLE_TOP, ObjectSpec, local_to_world
from .reach import UP

GRIP_SIGNS = np.array([[-1, -1], [-1, 1], [1, -1], [1, 1]], dtype=float)  # (4, 2) sx, sz


def random_object(rng: np.random.Generator, types: tuple[str, ...] = OBJECT_TYPES,
                  size_range: tuple[float, float] = (0.8, 1.25)) -> ObjectSpec:
    kind = str(rng.choice(types))
    size = np.asarray(DEFAULT_SIZES[kind]) * rng.uniform(*size_range, size=3)
    if kind == "canister":
        size[2] = size[0]  # round
    return ObjectSpec(kind, tuple(size), grip_anchors(kind, tuple(size)))


PALM = 0.02  # m from the surface to the wrist joint of a hand flat on it


def grip_anchors(kind: str, size: tuple[float, float, float]) -> np.ndarray:
    """(4, 3) local grip points: where the wrist joint is when the palm is on the surface."""
    w, h, d = size
    if kind == "table":      # at the top's edge on the two short ends, palm under it
        a, y, b = w / 2 + PALM, h - TABLE_TOP - PALM, 0.3 * d
    elif kind == "canister":  # on the wall, 35 degrees either side of the x axis
        r = min(w, d) / 2 + PALM
        a, y, b = r * np.cos(np.radians(35)), 0.7 * h, r * np.sin(np.radians(35))
    else:                    # box: high on the end faces, where a lifting hand goes
        a, y, b = w / 2 + PALM, 0.75 * h, 0.28 * d
    return np.column_stack([GRIP_SIGNS[:, 0] * a, np.full(4, y), GRIP_SIGNS[:, 1] * b])


def end_grips(sx: float) -> list[int]:
    """Anchor indices of the x end with sign sx."""
    return [k for k in range(4) if GRIP_SIGNS[k, 0] == sx]


def side_grips(sz: float) -> list[int]:
    """Anchor indices on the side with z sign sz (one per x end)."""
    return [k for k in range(4) if GRIP_SIGNS[k, 1] == sz]


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

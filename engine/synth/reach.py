"""Exact-length two-bone IK and the heading frames the synthesizer poses people in.

A person's heading is a yaw about +Y; yaw 0 faces +Z (the rest pose), so the forward vector is
(sin yaw, 0, cos yaw) and the left vector (cos yaw, 0, -sin yaw).
"""
from __future__ import annotations

import math

import numpy as np
from scipy.ndimage import gaussian_filter1d

from ..geometry.rotations import EPS, norm, normalize

UP = np.array([0.0, 1.0, 0.0])


def yaw_matrix(yaw: np.ndarray) -> np.ndarray:
    """Rotation about +Y. (...) -> (..., 3, 3)."""
    c, s = np.cos(yaw), np.sin(yaw)
    zero, one = np.zeros_like(yaw), np.ones_like(yaw)
    return np.stack([c, zero, s, zero, one, zero, -s, zero, c], axis=-1).reshape(np.shape(yaw) + (3, 3))


def pitch_matrix(angle: np.ndarray) -> np.ndarray:
    """Rotation about +X; a positive angle tips +Y towards +Z (a forward bend). (...) -> (..., 3, 3)."""
    c, s = np.cos(angle), np.sin(angle)
    zero, one = np.zeros_like(angle), np.ones_like(angle)
    return np.stack([one, zero, zero, zero, c, -s, zero, s, c], axis=-1).reshape(np.shape(angle) + (3, 3))


def heading_of(direction: np.ndarray) -> np.ndarray:
    """Yaw that faces a horizontal direction. (..., 3) -> (...)."""
    return np.arctan2(direction[..., 0], direction[..., 2])


def forward_of(yaw: np.ndarray) -> np.ndarray:
    """(...) -> (..., 3) unit forward vector on the ground plane."""
    return np.stack([np.sin(yaw), np.zeros_like(yaw), np.cos(yaw)], axis=-1)


def wrap_angle(a: np.ndarray) -> np.ndarray:
    return (a + np.pi) % (2 * np.pi) - np.pi


def to_local(points: np.ndarray, origin: np.ndarray, yaw: np.ndarray) -> np.ndarray:
    """World points (N, ..., 3) into heading frames given by origin (N, 3) and yaw (N,)."""
    R = yaw_matrix(yaw)
    shape = (points.shape[0],) + (1,) * (points.ndim - 2)
    rel = points - origin.reshape(shape + (3,))
    return np.einsum("nji,n...j->n...i", R, rel)


def two_bone_ik(root: np.ndarray, target: np.ndarray, upper: float, lower: float,
                pole: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Place the middle and end joints of a two-bone chain with exact bone lengths.

    root, target, pole: (..., 3); `pole` is a direction the middle joint bends towards.
    Returns (middle, end), each (..., 3). The end equals the target when it is within reach;
    otherwise it is the closest reachable point on the line from root to target.
    """
    to_target = target - root
    dist = norm(to_target, keepdims=True)
    axis = to_target / np.maximum(dist, 1e-9)
    # Keep a hair of bend so the knee/elbow direction stays defined.
    reach = np.clip(dist, abs(upper - lower) + 1e-6, (upper + lower) * (1 - 1e-6))
    cos_root = (upper ** 2 + reach ** 2 - lower ** 2) / (2 * upper * reach)
    sin_root = np.sqrt(np.maximum(1 - cos_root ** 2, 0.0))
    side = normalize(pole - np.sum(pole * axis, axis=-1, keepdims=True) * axis)
    middle = root + upper * (cos_root * axis + sin_root * side)
    end = root + reach * axis
    return middle, end


def continuous_pole(pole: np.ndarray, axis: np.ndarray, carry_m: float = 0.03) -> np.ndarray:
    """Poles (N, ..., 3) of two-bone chains whose root-to-end directions are `axis` (N, ..., 3),
    kept on one side from frame to frame (axis 0): each frame's pole across its axis, plus
    `carry_m` of the side the previous frame bent to. Where a pole's part across the axis
    shrinks through zero (an arm reaching the way its fallback bend points), its side flipped
    and the elbow jumped 20 cm in a frame; a chain bent well over `carry_m` keeps its own side."""
    n = len(pole)
    if n == 0:
        return pole.copy()
    axis = axis.reshape(n, -1, 3)
    out = pole.reshape(n, -1, 3) - np.sum(pole.reshape(n, -1, 3) * axis, -1, keepdims=True) * axis
    # Sequential (each frame's side follows the one before it), so in plain floats: numpy's cost
    # per call (17 calls a frame) made this loop 6% of the finishing.
    previous = normalize(out[0]).tolist()
    rows, axes = out.tolist(), axis.tolist()
    sqrt = math.sqrt
    for t in range(1, n):
        for c, ((ax, ay, az), o) in enumerate(zip(axes[t], rows[t])):
            px, py, pz = previous[c]
            along = px * ax + py * ay + pz * az
            kx, ky, kz = px - along * ax, py - along * ay, pz - along * az
            size = sqrt(kx * kx + ky * ky + kz * kz)
            k = carry_m / (size if size > EPS else EPS)
            ox, oy, oz = o[0] + k * kx, o[1] + k * ky, o[2] + k * kz
            o[0], o[1], o[2] = ox, oy, oz
            length = sqrt(ox * ox + oy * oy + oz * oz)
            length = length if length > EPS else EPS
            previous[c] = (ox / length, oy / length, oz / length)
    out = np.array(rows)
    return out.reshape(pole.shape)


def steady_pole(bend: np.ndarray, fallback: np.ndarray, sigma: float = 2.0, fallback_m: float = 0.02,
                bent_m: float = 0.03) -> np.ndarray:
    """Where a two-bone chain's middle joint should bend, turning smoothly over frames (axis 0).

    bend (N, ..., 3): the middle joint's offset from the root-to-end line now (its length says
    how bent the chain is); fallback (N, ..., 3): the way to bend when it is straight. A nearly
    straight limb's bend direction swings from frame to frame, and IK towards it can flip an
    elbow or a knee in one frame. There, the pole is each frame's direction weighted by how bent
    the limb is, with `fallback_m` of the fallback, smoothed over `sigma` frames; a limb bent by
    well over `bent_m` keeps its own bend exactly (so motion that needs no change gets none)."""
    smooth = gaussian_filter1d(bend + fallback_m * normalize(fallback), sigma, axis=0, mode="nearest")
    straight = np.exp(-0.5 * (norm(bend, keepdims=True) / bent_m) ** 2)
    return bend + straight * (smooth - bend)


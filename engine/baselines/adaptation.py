"""The geometry RetrievAdapt uses to bend a retrieved clip toward a storyboard: a ground-plane
rigid fit in the sketch plane, a piecewise-linear time warp through the keyframes, sampling a
clip at fractional frames, and smooth offsets that fall off in time around constrained frames.

All positions are world metres (Y up); sketch points are sketch-plane metres seen through the
storyboard's orthographic camera (camera.py).
"""
from __future__ import annotations

from dataclasses import fields

import numpy as np
from scipy.linalg import solve_banded

from ..camera import StoryboardCamera
from ..clip import MotionClip
from ..geometry.rotations import matrix_to_quat, quat_to_matrix


def yaw_matrix(yaw: np.ndarray) -> np.ndarray:
    """Rotation about +Y. (...,) radians -> (..., 3, 3)."""
    c, s = np.cos(yaw), np.sin(yaw)
    zero, one = np.zeros_like(c), np.ones_like(c)
    return np.stack([c, zero, s, zero, one, zero, -s, zero, c], axis=-1).reshape(np.shape(yaw) + (3, 3))


def fit_ground_rigid(points: np.ndarray, weights: np.ndarray, targets: np.ndarray,
                     camera: StoryboardCamera, yaw_steps: int = 720) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Best yaw about +Y and ground translation moving world points onto sketch targets.

    points: (W, P, 3) candidates' points; weights: (W, P), each row summing to 1 (0 = ignore);
    targets: (P, 2) sketch points. Minimises sum_p w |project(R x_p + offset) - target_p|^2.
    Returns yaw (W,), offset (W, 3) with offset[:, 1] = 0 so that x' = R(yaw) x + offset, and
    the weighted mean squared residual (W,) in m^2.

    Under an orthographic camera the projection of a yawed point is c * a + s * b + e (c, s the
    yaw's cosine and sine), and a free image-plane shift is a ground translation (the camera
    looks down, elevation > 0), so every candidate reduces to six weighted sums: the yaw is then
    a 1-D search on a fine grid refined by a parabola, cheap for thousands of candidates.
    """
    B2 = camera.basis()[:2]                                                  # (2, 3) right, up
    w = weights[..., None]                                                   # (W, P, 1)
    pivot = np.sum(w * points, axis=1) * (1.0, 0.0, 1.0)                     # (W, 3)
    x0 = points - pivot[:, None]
    a = x0[..., :1] * B2[:, 0] + x0[..., 2:] * B2[:, 2]                      # (W, P, 2)
    b = x0[..., 2:] * B2[:, 0] - x0[..., :1] * B2[:, 2]
    g = targets[None] - x0[..., 1:2] * B2[:, 1]
    mean_a, mean_b, mean_g = (np.sum(w * v, axis=1) for v in (a, b, g))      # (W, 2)
    a, b, g = a - mean_a[:, None], b - mean_b[:, None], g - mean_g[:, None]

    def wdot(u, v):
        return np.sum(w * u * v, axis=(1, 2))

    G, Ga, Gb, Aa, Bb, Ab = wdot(g, g), wdot(g, a), wdot(g, b), wdot(a, a), wdot(b, b), wdot(a, b)

    def cost(theta):  # theta (W, A) -> (W, A)
        c, s = np.cos(theta), np.sin(theta)
        return (G[:, None] - 2 * c * Ga[:, None] - 2 * s * Gb[:, None] + c * c * Aa[:, None]
                + s * s * Bb[:, None] + 2 * c * s * Ab[:, None])

    step = 2 * np.pi / yaw_steps
    grid = np.arange(yaw_steps) * step - np.pi
    values = cost(np.broadcast_to(grid, (len(points), yaw_steps)))
    best = np.argmin(values, axis=1)
    rows = np.arange(len(points))
    lo, mid, hi = values[rows, best - 1], values[rows, best], values[rows, (best + 1) % yaw_steps]
    curvature = lo - 2 * mid + hi
    shift = np.where(curvature > 1e-15, 0.5 * (lo - hi) / np.maximum(curvature, 1e-15), 0.0)
    yaw = grid[best] + np.clip(shift, -1.0, 1.0) * step
    residual = np.maximum(cost(yaw[:, None])[:, 0], 0.0)

    # The image-plane shift the centring removed is B2 (pivot + T - camera target); T lies on
    # the ground, so solve the 2x2 system of its x and z.
    image_shift = mean_g - np.cos(yaw)[:, None] * mean_a - np.sin(yaw)[:, None] * mean_b
    rhs = image_shift - (pivot - np.asarray(camera.target)) @ B2.T              # (W, 2)
    ground = np.linalg.lstsq(B2[:, [0, 2]], rhs.T, rcond=None)[0].T              # (W, 2) x, z
    R = yaw_matrix(yaw)
    offset = pivot - np.einsum("wij,wj->wi", R, pivot) + np.stack(
        [ground[:, 0], np.zeros(len(ground)), ground[:, 1]], axis=1)
    return yaw, offset, residual


def transform_clip(clip: MotionClip, yaw: float, offset: np.ndarray) -> MotionClip:
    """The clip moved by x' = R(yaw) x + offset (offset (3,) on the ground)."""
    R = yaw_matrix(np.float64(yaw))
    kw = {f.name: getattr(clip, f.name) for f in fields(clip)}
    kw["joints"] = clip.joints @ R.T + offset
    rot6d = clip.rot6d.copy()
    rot6d[:, :, 0, :3] = rot6d[:, :, 0, :3] @ R.T  # only the root's rotation is global
    rot6d[:, :, 0, 3:] = rot6d[:, :, 0, 3:] @ R.T
    kw["rot6d"] = rot6d
    if clip.num_objects:
        pose = clip.obj_pose.astype(float).copy()
        pose[..., :3] = pose[..., :3] @ R.T + offset
        pose[..., 3:] = matrix_to_quat(R @ quat_to_matrix(pose[..., 3:]))
        kw["obj_pose"] = pose
        if clip.obj_anchors is not None:
            kw["obj_anchors"] = clip.obj_anchors @ R.T + offset
    return MotionClip(**kw)


def keyframe_warp(errors: np.ndarray, key_frames: np.ndarray, num_frames: int, source_frames: int,
                  max_stretch: float = 2.0, time_weight: float = 0.01) -> np.ndarray:
    """Piecewise-linear time warp: for each output frame, the (fractional) source frame to show.

    errors: (K, L) cost of showing source frame f at keyframe k (e.g. squared sketch error);
    key_frames: (K,) sorted output frames of the keyframes; num_frames: output length N;
    source_frames: L. The warp passes through (0, 0) and (N - 1, L - 1) unless a keyframe sits
    there, and through one source frame per keyframe chosen by dynamic programming to minimise
    errors + time_weight * (normalised distance from the uniform timing)^2, with every piece's
    speed within [1 / max_stretch, max_stretch] of the uniform speed (L - 1) / (N - 1).
    Returns (N,) float source frames, non-decreasing.
    """
    rate = (source_frames - 1) / max(num_frames - 1, 1)
    frames = np.arange(source_frames)
    nodes_q, costs = [], []
    if len(key_frames) == 0 or key_frames[0] > 0:
        nodes_q.append(0)
        costs.append(np.where(frames == 0, 0.0, np.inf))
    for k, q in enumerate(key_frames):
        nodes_q.append(int(q))
        costs.append(errors[k] + time_weight * ((frames - rate * q) / max(source_frames - 1, 1)) ** 2)
    if len(key_frames) == 0 or key_frames[-1] < num_frames - 1:
        nodes_q.append(num_frames - 1)
        costs.append(np.where(frames == source_frames - 1, 0.0, np.inf))
    total, back = [costs[0]], []
    step = frames[None, :] - frames[:, None]                                 # (from, to)
    for i in range(1, len(nodes_q)):
        dq = nodes_q[i] - nodes_q[i - 1]
        allowed = (step >= np.floor(dq * rate / max_stretch)) & (step <= np.ceil(dq * rate * max_stretch))
        candidates = np.where(allowed, total[-1][:, None], np.inf)
        back.append(np.argmin(candidates, axis=0))
        total.append(candidates[back[-1], frames] + costs[i])
    chosen = [int(np.argmin(total[-1]))]
    for pointers in reversed(back):
        chosen.append(int(pointers[chosen[-1]]))
    chosen = np.array(chosen[::-1], float)
    # Sub-frame keyframe times from a parabola through each chosen frame's cost and its neighbours.
    for i, f in enumerate(chosen.astype(int)):
        if 0 < f < source_frames - 1 and np.all(np.isfinite(costs[i][f - 1:f + 2])):
            lo, mid, hi = costs[i][f - 1:f + 2]
            curvature = lo - 2 * mid + hi
            if curvature > 1e-15:
                chosen[i] += np.clip(0.5 * (lo - hi) / curvature, -0.5, 0.5)
    return np.interp(np.arange(num_frames), nodes_q, np.maximum.accumulate(chosen))


def sample_frames(clip: MotionClip, times: np.ndarray, fps: float | None = None) -> MotionClip:
    """The clip shown at fractional frames `times` (M,): positions and phase linearly
    interpolated, object rotations normalised-lerped in one hemisphere, contact labels from the
    nearer frame. Rotations are interpolated in 6D and re-derived by whoever needs them exact."""
    times = np.clip(np.asarray(times, float), 0, clip.num_frames - 1)
    lo = np.floor(times).astype(int)
    hi = np.minimum(lo + 1, clip.num_frames - 1)
    w = times - lo

    def lerp(a):
        wb = w.reshape((-1,) + (1,) * (a.ndim - 1))
        return (1 - wb) * a[lo] + wb * a[hi]

    kw = {f.name: getattr(clip, f.name) for f in fields(clip)}
    kw["fps"] = clip.fps if fps is None else fps
    for name in ("joints", "rot6d", "obj_anchors", "phase"):
        if kw[name] is not None:
            kw[name] = lerp(np.asarray(kw[name], float))
    if clip.contact is not None:
        kw["contact"] = clip.contact[np.where(w < 0.5, lo, hi)]
    if clip.obj_pose is not None:
        pose = lerp(clip.obj_pose.astype(float))
        q_lo, q_hi = clip.obj_pose[lo, :, 3:], clip.obj_pose[hi, :, 3:]
        q_hi = q_hi * np.where(np.sum(q_lo * q_hi, axis=-1, keepdims=True) < 0, -1.0, 1.0)
        q = (1 - w[:, None, None]) * q_lo + w[:, None, None] * q_hi
        pose[..., 3:] = q / np.linalg.norm(q, axis=-1, keepdims=True)
        kw["obj_pose"] = pose
    return MotionClip(**kw)


def smooth_offsets(targets: np.ndarray, weights: np.ndarray, falloff: float = 10.0,
                   shrink: float = 1e-3) -> np.ndarray:
    """Offset curves that meet sparse targets and fade away from them.

    targets: (N, C, 3) wanted offset at each frame of each channel (a joint, an object);
    weights: (N, C) >= 0, 0 where a channel is unconstrained. Each channel's curve d minimises
      sum_n w_n |d_n - target_n|^2 + shrink * sum_n (|d_n|^2 + falloff^2 |d_n+1 - d_n|^2
                                                      + falloff^4 / 4 |d_n+1 - 2 d_n + d_n-1|^2),
    so it passes (nearly) through weighted targets, stays smooth through them, and decays to 0
    over about `falloff` frames where there are none. Returns (N, C, 3).
    """
    n, channels = weights.shape
    out = np.zeros_like(targets, dtype=float)
    if n < 3:
        return np.where(weights[..., None] > 0, targets, 0.0)
    # Banded normal matrix of the smoothness terms (5 diagonals), shared by every channel.
    bands = shrink * (_gram_bands((1.0,), n) + falloff ** 2 * _gram_bands((-1.0, 1.0), n)
                      + falloff ** 4 / 4 * _gram_bands((1.0, -2.0, 1.0), n))
    for ch in range(channels):
        w = weights[:, ch]
        if not np.any(w > 0):
            continue
        ab = bands.copy()
        ab[2] += w
        out[:, ch] = solve_banded((2, 2), ab, w[:, None] * targets[:, ch])
    return out


def _gram_bands(stencil: tuple[float, ...], n: int) -> np.ndarray:
    """D^T D in solve_banded's (5, n) layout (2 bands each side), D the (n - len + 1, n)
    matrix applying `stencil` at every position."""
    bands = np.zeros((5, n))
    starts = np.arange(n - len(stencil) + 1)
    for i, si in enumerate(stencil):
        for j, sj in enumerate(stencil):
            bands[2 + i - j, starts + j] += si * sj
    return bands

"""Footsteps for a person whose ground point and heading are given per frame.

The gait is driven by distance travelled rather than by a clock: gait distance grows with the
ground point's path length plus a turn term (so turning on the spot also steps), and each bout
of movement is cut into whole steps. A person who stops therefore always stands on two planted
feet, and a planted foot never moves. Steps alternate feet; each foot swings from its old plant
to a plant ahead of the body in the middle part of its step window, lifting so that it leaves
the ground before it travels (no sliding near the floor).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .reach import yaw_matrix
from .trajectory import blend_yaw, smootherstep

FOOT_HEIGHT = 0.02  # height of the foot joint above the ground on a flat, planted foot (m)


@dataclass
class GaitConfig:
    step_length: float = 0.5      # m at body scale 1, the average; bouts round it to whole steps
    turn_radius: float = 0.3      # m of gait distance per radian of turning
    min_bout: float = 0.08        # m of gait distance below which the feet stay put
    lift: float = 0.08            # m of swing clearance at body scale 1
    swing_share: float = 0.8      # part of a step window the foot is in the air
    bob: float = 0.012            # m of pelvis rise at mid-swing


@dataclass
class Footwork:
    feet: np.ndarray        # (N, 2, 3) l_foot / r_foot joint positions
    foot_yaw: np.ndarray    # (N, 2) heading of each foot
    bob: np.ndarray         # (N,) pelvis height offset


def plan_footwork(ground: np.ndarray, yaw: np.ndarray, stance: np.ndarray, scale: float,
                  config: GaitConfig = GaitConfig()) -> Footwork:
    """Feet for a ground track.

    ground: (N, 3) the body's ground point (pelvis projected to y = 0); yaw: (N,) heading;
    stance: (2, 3) each foot's standing position in the heading frame (y ignored).
    """
    n = len(ground)
    yaw = np.unwrap(yaw)
    step_dist = (np.linalg.norm(np.diff(ground[:, [0, 2]], axis=0), axis=-1)
                 + config.turn_radius * np.abs(np.diff(yaw)))
    gait = np.concatenate([[0.0], np.cumsum(step_dist)])

    def plant(at: float, a: int, b: int, foot: int) -> tuple[np.ndarray, float]:
        """Where `foot` stands when the gait distance reaches `at` within frames a..b."""
        u = gait[a:b + 1]
        g = np.array([np.interp(at, u, ground[a:b + 1, k]) for k in range(3)])
        heading = float(np.interp(at, u, yaw[a:b + 1]))
        pos = g + yaw_matrix(np.array(heading)) @ stance[foot]
        pos[1] = FOOT_HEIGHT
        return pos, heading

    first_pos = [plant(0.0, 0, 0, f) for f in range(2)]
    feet = np.repeat(np.stack([p for p, _ in first_pos])[None], n, axis=0)
    foot_yaw = np.repeat(np.array([[h for _, h in first_pos]]), n, axis=0)
    bob = np.zeros(n)

    for a, b in _bouts(step_dist > 1e-6):
        length = gait[b] - gait[a]
        if length < config.min_bout * scale:
            continue
        count = max(1, int(round(length / (config.step_length * scale))))
        step = length / count
        # Plant j lands `step * j` along the bout (the last two both at its end: a closing step)
        # during a window that ends half a step before the body passes the plant.
        lands = [min(j * step, length) for j in range(1, count + 2)]
        starts = [0.0] + [max((j - 1.5) * step, 0.0) for j in range(2, count + 2)]
        ends = [min((j - 0.5) * step, length) for j in range(1, count + 2)]
        ends[-1] = length
        u_rel = gait[a:b + 1] - gait[a]
        first = int(np.argmax([np.linalg.norm(plant(gait[a] + lands[0], a, b, f)[0] - feet[a, f])
                               for f in range(2)]))
        for j, (land, w0, w1) in enumerate(zip(lands, starts, ends)):
            foot = first if j % 2 == 0 else 1 - first
            lift_off = a + _frame_at(u_rel, w0)
            src, src_yaw = feet[lift_off, foot].copy(), foot_yaw[lift_off, foot]
            dst, dst_yaw = plant(gait[a] + land, a, b, foot)
            tau = np.clip((u_rel - w0) / max(w1 - w0, 1e-9), 0.0, 1.0)
            swing = np.clip((tau - 0.5 * (1 - config.swing_share)) / config.swing_share, 0.0, 1.0)
            frames = slice(a, b + 1)
            # Travel only while well off the floor, so no frame rate sees a low, moving foot.
            ease = smootherstep((swing - 0.15) / 0.7)[:, None]
            pos = src + (dst - src) * ease
            pos[:, 1] = FOOT_HEIGHT + config.lift * scale * np.sqrt(np.sin(np.pi * swing))
            feet[frames, foot] = np.where((u_rel >= w0)[:, None], pos, feet[frames, foot])
            foot_yaw[frames, foot] = np.where(u_rel >= w0, blend_yaw(src_yaw, dst_yaw, ease[:, 0]),
                                              foot_yaw[frames, foot])
            bob[frames] += config.bob * scale * np.sin(np.pi * swing)
        feet[b + 1:] = feet[b]
        foot_yaw[b + 1:] = foot_yaw[b]
    return Footwork(feet=feet, foot_yaw=foot_yaw, bob=bob)


def _frame_at(u: np.ndarray, value: float) -> int:
    """Index of the last frame whose gait distance is at most `value`."""
    return max(int(np.searchsorted(u, value, side="right")) - 1, 0)


def _bouts(moving: np.ndarray) -> list[tuple[int, int]]:
    """Runs of movement as (first frame, last frame): moving[i] is the motion from frame i to i+1."""
    edges = np.diff(np.concatenate([[0], moving.astype(np.int8), [0]]))
    return [(int(s), int(e)) for s, e in zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1))]

"""Timing curves and ground paths: easing, Bezier curves, and travel along them over a time span.

Times are in seconds (arrays of frame times), positions in metres on the ground plane (y = 0).
"""
from __future__ import annotations

from math import comb

import numpy as np

from .reach import heading_of, wrap_angle


def smoothstep(x: np.ndarray) -> np.ndarray:
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3 - 2 * x)


def smootherstep(x: np.ndarray) -> np.ndarray:
    x = np.clip(x, 0.0, 1.0)
    return x * x * x * (x * (6 * x - 15) + 10)


def progress(times: np.ndarray, start: float, stop: float) -> np.ndarray:
    """Linear 0..1 progress of each time through [start, stop], clamped. (N,) -> (N,)."""
    return np.clip((times - start) / max(stop - start, 1e-9), 0.0, 1.0)


def window_weight(times: np.ndarray, on: float, off: float, ramp_in: float, ramp_out: float) -> np.ndarray:
    """1 on [on, off], easing from 0 over `ramp_in` before and back to 0 over `ramp_out` after. (N,)."""
    rise = smoothstep((times - (on - ramp_in)) / max(ramp_in, 1e-9))
    fall = 1.0 - smoothstep((times - off) / max(ramp_out, 1e-9))
    w = np.minimum(rise, fall)
    w[(times >= on) & (times <= off)] = 1.0
    return w


def bezier(control: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Points and tangents of a Bezier curve. control: (C, 3), u: (N,) in [0, 1] -> (N, 3), (N, 3)."""
    deg = len(control) - 1
    u = u[:, None]
    pts = np.zeros((len(u), 3))
    tan = np.zeros((len(u), 3))
    for i, c in enumerate(control):
        pts += comb(deg, i) * u ** i * (1 - u) ** (deg - i) * c
    for i in range(deg):
        tan += deg * comb(deg - 1, i) * u ** i * (1 - u) ** (deg - 1 - i) * (control[i + 1] - control[i])
    return pts, tan


def arc_length_table(control: np.ndarray, samples: int = 64) -> tuple[np.ndarray, np.ndarray]:
    """Curve parameter u (S,) and cumulative arc length (S,) for uniform-speed travel."""
    u = np.linspace(0.0, 1.0, samples)
    pts, _ = bezier(control, u)
    return u, np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=-1))])


def travel(times: np.ndarray, start: float, stop: float, control: np.ndarray
           ) -> tuple[np.ndarray, np.ndarray]:
    """Move along a Bezier path over [start, stop] with eased (smoothstep) speed.

    Before `start` the mover waits at the first control point, after `stop` at the last.
    Returns positions (N, 3) and the path heading (N,) (yaw of the tangent).
    """
    u_tab, s_tab = arc_length_table(control)
    s = smoothstep(progress(times, start, stop)) * s_tab[-1]
    pts, tan = bezier(control, np.interp(s, s_tab, u_tab))
    return pts, heading_of(tan)


def blend_yaw(a: np.ndarray, b: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Turn from yaw a towards yaw b by weight w along the shorter way. All (N,)."""
    return a + wrap_angle(b - a) * w


def arc_control(start: np.ndarray, goal: np.ndarray, arrive_dir: np.ndarray | None, bend: float
                ) -> np.ndarray:
    """Control points (3, 3) of a quadratic curve from start to goal.

    arrive_dir: unit direction to arrive along (the curve's end tangent), or None for a curve
    bowed sideways by `bend` (a fraction of the distance; the sign picks the side).
    """
    chord = goal - start
    dist = np.linalg.norm(chord)
    if arrive_dir is not None:
        mid = goal - arrive_dir * 0.5 * dist
    else:
        side = np.array([chord[2], 0.0, -chord[0]]) / max(dist, 1e-9)
        mid = start + 0.5 * chord + side * bend * dist
    return np.stack([start, mid, goal])

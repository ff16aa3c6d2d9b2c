"""Corrections blended over time: an edit that must hold exactly on some frames and fade or
change elsewhere, without a jolt.

A correction (the finished motion less the generated one) that switches on in one frame, or
swings from one plant's to the next in two, shows as a pop however smooth the generated motion
is. `smooth_correction` keeps the correction exactly on the frames that are held and makes it
as smooth as it can elsewhere (least second differences) while staying near what the stage
asked for: a Whittaker smoother with hard constraints, one banded solve (`smooth_path`). A push
out of something (`eased_push`) must never fall short instead: it eases as an envelope.
"""
from __future__ import annotations

from collections.abc import Callable
from functools import cache

import numpy as np
from scipy.linalg import solveh_banded
from scipy.ndimage import gaussian_filter1d, maximum_filter1d

from ..geometry.rotations import norm, normalize
from ..synth.trajectory import smoothstep

HELD_WEIGHT = 1e8     # a held frame's weight against the smoothness: held to far below a millimetre


def smooth_path(values: np.ndarray, weight: np.ndarray, stiffness: float) -> np.ndarray:
    """The path (N, D) nearest to `values` (N, D) under per-frame weights (N,) with least squared
    second differences times `stiffness` (about stiffness ** 0.25 frames is the time scale over
    which it changes) -> (N, D). A frame of weight HELD_WEIGHT stays where it is."""
    n = len(values)
    if n < 3:
        return np.array(values, float)
    # A = diag(weight) + stiffness * D2^T D2, D2 the (N-2, N) second difference; upper banded form.
    diagonals = np.zeros((3, n))
    d2 = (1.0, -2.0, 1.0)
    for offset in range(3):   # (D2^T D2)[i, i + offset] summed over the rows of D2 that touch both
        for k in range(3 - offset):
            diagonals[2 - offset, k + offset: n - 2 + k + offset] += stiffness * d2[k] * d2[k + offset]
    diagonals[2] += weight
    return solveh_banded(diagonals, weight[:, None] * values)


def smooth_correction(correction: np.ndarray, held: np.ndarray, stiffness: float) -> np.ndarray:
    """correction (N, D) asked for per frame; held (N,) bool: frames where it must stay exact;
    elsewhere it changes smoothly, near what was asked (stiffness as smooth_path's). -> (N, D)."""
    if held.all():
        return np.array(correction, float)
    out = smooth_path(correction, np.where(held, HELD_WEIGHT, 1.0), stiffness)
    out[held] = correction[held]              # exactly, not to the solver's 1e-7
    return out


def eased_push(push: np.ndarray, frames: float) -> np.ndarray:
    """Pushes (N, 3) out of something, eased over about `frames` frames and never shorter than
    asked: their length the larger of its own and its smoothed running maximum, along their
    smoothed direction. Exact at the frames that asked and smoothed between, a push that came and
    went over a frame or two was a pop that later smoothing halved, putting back what it pushed out."""
    length = norm(push)
    window = 2 * int(np.ceil(frames)) + 1
    envelope = np.maximum(gaussian_filter1d(maximum_filter1d(length, window), frames, mode="nearest"), length)
    direction = gaussian_filter1d(push, frames, axis=0, mode="nearest")
    return np.where(norm(direction, keepdims=True) > 1e-9, envelope[:, None] * normalize(direction), 0.0)


def at_most(moves: np.ndarray, most: float) -> np.ndarray:
    """Moves (..., D) shortened to at most `most` (m) long, their directions kept."""
    return moves * np.minimum(1.0, most / np.maximum(norm(moves, keepdims=True), 1e-9))


def spike(path: np.ndarray) -> np.ndarray:
    """How far each frame of a path (N, ..., 3) lies off the middle of its neighbours -> (N, ...);
    the first and last frames 0."""
    out = np.zeros(path.shape[:-1])
    out[1:-1] = norm(path[1:-1] - 0.5 * (path[:-2] + path[2:]))
    return out


@cache
def _smoothstep_spike(frames: int) -> float:
    """The largest spike of a unit smoothstep over `frames` in-between frames, still ends included."""
    s = np.arange(frames + 2) / (frames + 1)
    path = np.concatenate([[0.0], smoothstep(s), [1.0]])
    return float(np.abs(path[1:-1] - 0.5 * (path[:-2] + path[2:])).max())


def ease_frames(distance: float, pop: float, shortest: int, longest: int) -> int:
    """Frames (in [shortest, longest]) a smoothstep from one still place to another `distance`
    away needs so that it spikes (off its neighbours' midpoint, still ends included) at most `pop`."""
    return next((frames for frames in range(shortest, longest) if distance * _smoothstep_spike(frames) <= pop),
                max(longest, shortest))


def ease_jumps(values: np.ndarray, at: list[int], frames_for: Callable[[float], int]) -> np.ndarray:
    """values (N, D) whose jump into each frame c of `at` is eased out over the frames_for(size of
    the jump) frames after it: from c on they start where the frames before were heading (their
    last step continued) and reach their own by a smoothstep. -> (N, D)."""
    out = np.array(values, float)
    for c in at:
        if not 1 <= c < len(out):
            continue
        jump = out[c - 1] + (out[c - 1] - out[c - 2] if c >= 2 else 0.0) - out[c]
        length = frames_for(float(np.linalg.norm(jump)))
        after = np.arange(c, min(c + length + 1, len(out)))
        out[after] += smoothstep(1.0 - (after - c) / (length + 1))[:, None] * jump
    return out

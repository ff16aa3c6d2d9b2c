"""Walking where the feet's made-up steps would have a person hop.

feet.py gives a foot that glides along the floor steps of its own, each foot apart. Where the
body glides fast, or one foot hovers while the other glides, those steps overlap and the person
has both feet in the air for frames at a time (a hop, while carrying a box). Here such a
stretch, from a frame at which both feet stand before it to one after it, becomes a walk: steps
that alternate feet, timed by the distance the pelvis travels (as the synthesizer's gait,
engine.synth.gait), each foot lifting and landing while the other stands, from where the feet
stand at its start to where they stand at its end. A walk that would jolt a foot, or plant one
beyond its leg's reach, is not taken: the hop stays.
"""
from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
from scipy.ndimage import label

from ..geometry.rotations import norm
from ..skeleton import ANKLES, FEET, HIPS, KNEES
from ..synth.trajectory import smootherstep
from .blend import spike

if TYPE_CHECKING:
    from .feet import FeetConfig

STILL = 0.005   # m a frame: a foot on the floor moving less than this to and from a frame stands


def _standing(goal: np.ndarray, config: FeetConfig) -> np.ndarray:
    """Frames (N,) at which a foot goal (N, 3) stands on the floor, still."""
    step = norm(np.diff(goal, axis=0))
    moving = np.concatenate([[0.0], step]) + np.concatenate([step, [0.0]])
    return (goal[:, 1] <= config.stance_height) & (moving < 2 * STILL)


def walk_through_flights(goals: Sequence[np.ndarray], pose: np.ndarray, keys: Sequence[int],
                         config: FeetConfig) -> list[np.ndarray]:
    """Both feet's goals (two (N, 3)) for a person's pose (N, 22, 3), with every stretch in which
    both are off the floor walked instead where a walk goes smoothly (see the module's doc). The
    stretch widens, over frames at which both feet stand, by up to config.max_widen each way;
    one around a key frame stays as it is (the warp placed the key's feet)."""
    goals = [np.array(g, float) for g in goals]
    n = len(pose)
    flight = (goals[0][:, 1] > config.stance_height) & (goals[1][:, 1] > config.stance_height)
    both = np.flatnonzero(_standing(goals[0], config) & _standing(goals[1], config))
    spans, count = label(flight)
    done = -1
    for i in range(1, count + 1):
        frames = np.flatnonzero(spans == i)
        if frames[0] <= done:
            continue
        before = [*both[both < frames[0]][::-1], 0]              # nearest first
        after = [*both[both > frames[-1]], n - 1]
        for widen in range(config.max_widen + 1):
            a, b = before[min(widen, len(before) - 1)], after[min(widen, len(after) - 1)]
            if a <= done or any(a < k < b for k in keys):
                break
            walked = _walk(goals, pose[a:b + 1], a, b, config)
            if walked is not None:
                for foot in range(2):
                    goals[foot][a:b + 1] = walked[foot]
                done = b
                break
    return goals


def _walk(goals: list[np.ndarray], pose: np.ndarray, a: int, b: int, config: FeetConfig) -> list[np.ndarray] | None:
    """Both feet's goals over frames a..b ((b - a + 1, 3) each; pose (b - a + 1, 22, 3) those
    frames) stepping in turn from where each is at a to where it is at b, each step about
    config.walk_step of the pelvis' travel; None if that jolts a foot by more than config.walk_pop
    or leaves one out of its leg's reach."""
    pelvis = pose[:, 0]
    travel = np.concatenate([[0.0], np.cumsum(norm(np.diff(pelvis[:, [0, 2]], axis=0)))])
    if travel[-1] < config.min_step_m:   # the body stays: no walk (the feet's own steps stand)
        return None
    start, end = [g[a] for g in goals], [g[b] for g in goals]
    behind = [np.dot(start[f] - pelvis[0], pelvis[-1] - pelvis[0]) for f in range(2)]
    first = int(np.argmin(behind))                   # the foot further behind steps first
    steps = max(2, int(np.ceil(travel[-1] / config.walk_step)))
    feet = _stepping(pelvis, travel, start, end, first, steps, config)
    if max(spike(f).max() for f in feet) > config.walk_pop:
        return None
    for side, foot in enumerate(feet):   # the body may lower by max_crouch to reach its plants
        leg = (norm(pose[:, KNEES[side]] - pose[:, HIPS[side]])
               + norm(pose[:, ANKLES[side]] - pose[:, KNEES[side]]))
        ankle = foot - (pose[:, FEET[side]] - pose[:, ANKLES[side]])
        hip = pose[:, HIPS[side]] - [0.0, config.max_crouch, 0.0]
        if (norm(ankle - hip) > config.plant_reach * leg).any():
            return None
    return feet


def _stepping(pelvis: np.ndarray, travel: np.ndarray, start: list[np.ndarray], end: list[np.ndarray],
              first: int, steps: int, config: FeetConfig) -> list[np.ndarray]:
    """Feet paths (two (M, 3)) taking `steps` steps in turn, `first` foot first, as the pelvis
    (M, 3) travels (travel (M,), m from its first frame). Each step's window of the travel is
    its share of the distance the feet cover, so that every step moves as fast against the
    pelvis (equal windows gave a foot's one long step to the end plant a third of the time: a
    1.3 m step in 3 frames); a foot lands beside the pelvis half a window past the window's
    end, and the last step of each foot on its end plant."""
    bounds = np.linspace(0.0, travel[-1], steps + 1)
    landings = _landings(pelvis, travel, bounds, start, end, first, config)
    covered = np.array([np.linalg.norm((dst - src)[[0, 2]]) for _, src, dst in landings])
    if covered.sum() > 1e-6:
        bounds = travel[-1] * np.concatenate([[0.0], np.cumsum(covered)]) / covered.sum()
        landings = _landings(pelvis, travel, bounds, start, end, first, config)
    feet = [np.repeat(s[None], len(pelvis), axis=0) for s in start]
    for j, (foot, src, dst) in enumerate(landings):
        width = max(bounds[j + 1] - bounds[j], 1e-9)
        tau = np.clip((travel - bounds[j]) / width, 0.0, 1.0)
        # Travelling over the whole window (not its middle 80%) jolts the foot 0.64 times as much;
        # the square root of a sine lifts it off the floor fast, so that it does not slide.
        path = src + smootherstep(tau)[:, None] * (dst - src)
        path[:, 1] += (config.step_height - config.foot_height) * np.sqrt(np.sin(np.pi * tau))
        moving = travel >= bounds[j]
        feet[foot][moving] = path[moving]
    return feet


def _landings(pelvis: np.ndarray, travel: np.ndarray, bounds: np.ndarray, start: list[np.ndarray],
              end: list[np.ndarray], first: int, config: FeetConfig) -> list[tuple[int, np.ndarray, np.ndarray]]:
    """(foot, from, to) of each step whose window of the travel is bounds[j]..bounds[j + 1]."""
    total = travel[-1]
    offset_start, offset_end = [s - pelvis[0] for s in start], [e - pelvis[-1] for e in end]
    where = [s.copy() for s in start]
    out = []
    for j in range(len(bounds) - 1):
        foot = first if j % 2 == 0 else 1 - first
        if j >= len(bounds) - 3:
            dst = end[foot]
        else:
            at = 0.5 * (bounds[j + 1] + bounds[j + 2])
            w = at / total
            dst = np.array([np.interp(at, travel, pelvis[:, k]) for k in range(3)])
            dst += (1 - w) * offset_start[foot] + w * offset_end[foot]
            dst[1] = config.foot_height
        out.append((foot, where[foot], dst))
        where[foot] = dst
    return out

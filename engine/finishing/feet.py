"""Feet on the ground: settle each person onto the floor, then lock planted feet in place.

Classic motion cleanup on world joint positions (N, H, 22, 3), metres, Y up, ground y = 0.
`settle_on_ground` lifts or lowers the whole body so that the lower foot stands on the floor;
`lock_feet` finds each foot's stance intervals (low and slow), pins the foot there and solves
the leg from the fixed hip by exact two-bone IK. Every bone keeps its length: the knee and
ankle come from the IK, the foot joint rides rigidly on the ankle. Run settle first: stance
detection reads absolute heights.

A foot that glides along the floor instead of stepping (the generator's usual fault) gets
steps: its stance is cut when the foot has drifted `max_drift` from where it was planted, and
a gap between two stances that never leaves the floor becomes a lifted arc from one plant to
the next (the second foot's step waits for the first to land, so people walk, not hop; where the
steps still lift both feet at once, walk.py makes the stretch a walk, and where no walk goes
smoothly the lower foot skims the floor). Feet that already swing clear of the floor keep their
own swing, retimed where they would leave or land with a jolt.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from scipy.ndimage import distance_transform_edt, gaussian_filter1d, label, maximum_filter1d

from ..geometry.rotations import cross, norm, normalize
from ..skeleton import ANKLES, FEET, HIPS, KNEES
from ..synth.reach import UP, steady_pole, two_bone_ik
from ..synth.trajectory import smoothstep
from .blend import HELD_WEIGHT, at_most, ease_frames, eased_push, smooth_correction, smooth_path, spike
from .keys import closeness_to_keys
from .walk import walk_through_flights



@dataclass
class FeetConfig:
    """Thresholds of the feet finishing; durations in frames at TUNED_FPS."""
    DURATIONS: ClassVar[tuple[str, ...]] = ("speed_sigma", "min_stance_frames", "blend_frames", "step_frames",
                                            "max_step_frames", "swing_frames", "correction_frames", "settle_sigma",
                                            "crouch_window", "crouch_sigma", "hop_frames", "min_glide_frames",
                                            "glide_frames", "foot_turn_sigma")
    # Foot joint height when standing (the rest skeleton's; EnergyConfig.foot_height).
    foot_height: float = 0.02        # m
    # A foot may be planted while its joint is under this height (metrics' contact height).
    stance_height: float = 0.05      # m
    # Hysteresis on the foot's speed: a stance starts under stance_speed and lasts while under
    # release_speed. A swinging foot moves at 2-4 m/s; a low foot well below that is planted,
    # however much it slides (the metric's skate speed is 0.5 m/s).
    stance_speed: float = 1.0        # m/s
    release_speed: float = 2.0       # m/s
    # While the other foot is this high, a low foot slower than release_speed is planted: a
    # runner's feet glided at 1-1.6 m/s under the other's swing (skate 8.8 -> 0.8% of the frames).
    lifted_height: float = 0.04      # m
    speed_sigma: float = 3.0         # frames; smoothing of the foot path before its speed (the
                                     # decoder's feet jitter by up to 10 cm a frame)
    min_stance_frames: int = 3       # shorter stances are passing touches, left alone
    blend_frames: int = 3            # ramp in and out of a lock, so the foot never pops
    # A re-placed foot turns about its ankle towards its direction smoothed over foot_turn_sigma frames,
    # by at most most_foot_turn: the decoder's heel rose over the frames a glide left its plant, and on
    # a foot held planted, then lifted, both came in one frame (an ankle spiking 5.6 cm over the
    # foot's 3.7). artist_check's 100 storyboards with pops within 5 cm 63 -> 67 (1.5 cm: 68, but a
    # foot pivoting on its toes swung the ankle 10 cm), 15 sketch-only 11 -> 10 (mean 4.87 -> 4.79
    # cm), 3 real windows' mean pop 7.06 -> 7.20 cm, skate 1.8 -> 2.1%.
    foot_turn_sigma: float = 1.5
    most_foot_turn: float = 0.01     # m
    # A gliding foot is re-planted once it has drifted this far, after a step of step_frames.
    max_drift: float = 0.3           # m
    step_frames: int = 4
    swing_frames: float = 2.0        # time scale over which a swing's pace along its path changes ...
    swing_pop: float = 0.045         # m; ... where held still at its plants it jolts more than this
                                     # (and its plants are shortened until it need not: _with_room_to_step)
    correction_frames: float = 2.5   # time scale over which a correction of the feet changes (blend.py)
    min_step_m: float = 0.05          # plants closer than this need no room to step between them
    step_height: float = 0.08        # m; peak of a made-up step (the synthesizer's swing lift)
    max_step_frames: int = 8         # a longer gap is no step: the foot keeps its own path
    step_pop: float = 0.03           # m; a made-up step takes frames enough that the eased foot
                                     # jolts (spikes off its neighbours' midpoint) at most this much
    walk_step: float = 0.6           # m the pelvis travels per step where made-up steps would lift
                                     # both feet at once and the stretch is walked (walk.py) ...
    walk_pop: float = 0.045          # m; ... if that jolts a foot at most this much, ...
    max_widen: int = 3               # ... the stretch widened by up to this many standing frames each way
    hop_frames: float = 1.0          # time scale over which a hop's lower foot comes down (_lower_in_hops)
    # A foot off its plant gliding faster than the first speed while the other foot stands rises,
    # by the second to step_height (_lift_glides): the decoder drags a swinging foot along the floor.
    glide_speeds: tuple[float, float] = (0.4, 1.0)   # m/s
    min_glide_frames: int = 3        # frames low and that fast in a row (a swing leaves and lands in fewer)
    glide_frames: float = 1.0        # time scale over which that rise comes and goes
    settle_sigma: float = 3.0        # frames; smoothing of the vertical settle shift
    max_crouch: float = 0.1          # m; most a body lowers so its legs reach their plants
    leg_extension: float = 0.97      # share of a leg's length its planted reach may take: a knee kept
                                     # off straight, where two-bone IK swings it fast (pops). 0.98 -> 0.97:
                                     # clips whose largest pop is within 5 cm 32 -> 65% (synthesized),
                                     # 23 -> 27% (artist-style), T2D and foot float the same; 0.95 swung
                                     # a hand-drawn storyboard's knee 14 cm
    plant_reach: float = 0.98        # share of a leg's length a made-up walk may plant a foot from its hip
    crouch_window: int = 5           # frames a crouch is held around its deepest need ...
    crouch_sigma: float = 1.5        # ... and smoothed over, so it never bobs


def settle_on_ground(joints: np.ndarray, config: FeetConfig = FeetConfig()) -> np.ndarray:
    """Shift each person vertically so that their lower foot stands at config.foot_height.

    joints (N, H, 22, 3) -> (N, H, 22, 3). The shift is per person and frame, the same for all
    joints, and smoothed over time so that it never pops. Using the lower foot leaves a step
    alone (the other foot carries the weight); a jump would be pulled down.
    """
    joints = np.asarray(joints, float)
    lowest = joints[:, :, list(FEET), 1].min(axis=-1)                           # (N, H)
    shift = gaussian_filter1d(config.foot_height - lowest, config.settle_sigma, axis=0, mode="nearest")
    return joints + shift[:, :, None, None] * UP


def stance_intervals(foot: np.ndarray, fps: float, config: FeetConfig = FeetConfig(),
                     busy: np.ndarray | None = None, keys: Sequence[int] = (),
                     other: np.ndarray | None = None) -> list[tuple[int, int]]:
    """Stance intervals [start, stop) of one foot's path (N, 3), in time order. `busy` (N,) bool
    marks frames in which the other foot is off its plant: a made-up step is moved to the nearest
    frame at which the other foot stands, and a short gap while it is off is held, so that a
    gliding person walks rather than hops; `other` (N, 3), the other foot's path, marks the
    frames in which it is lifted (config.lifted_height). A stance holding one of
    the key frames `keys` has a plant of its own around the key, while the foot is within half
    of max_drift of where it is at the key (lock_feet plants it there)."""
    low = foot[:, 1] < config.stance_height
    if len(foot) > 1:
        path = gaussian_filter1d(foot, config.speed_sigma, axis=0, mode="nearest")
        speed = norm(np.gradient(path, axis=0)) * fps
    else:
        speed = np.zeros(len(foot))
    strong, weak = low & (speed < config.stance_speed), low & (speed < config.release_speed)
    if other is not None:   # the other foot up: this one bears the weight, however it glides
        strong |= weak & (other[:, 1] >= config.lifted_height)
    if busy is not None:   # a short gap while the other foot is off its plant too would be a hop
        edges = np.flatnonzero(np.diff(np.concatenate([[0], weak.astype(int), [0]])))
        for stop, start in zip(edges[1:-1:2], edges[2::2]):
            if (start - stop <= config.max_step_frames and busy[stop:start].all()
                    and foot[stop:start, 1].max() < config.step_height):
                weak[stop:start] = True
    edges = np.flatnonzero(np.diff(np.concatenate([[0], weak.astype(int), [0]])))
    out = []
    for start, stop in zip(edges[::2], edges[1::2]):
        # Hysteresis: a stance must once be slow; too short a one is a passing touch.
        if stop - start < config.min_stance_frames or not strong[start:stop].any():
            continue
        while start < stop:                      # cut a gliding stance into plants and steps
            key = next((k for k in keys if start <= k < stop), None)
            lift = None                          # where a step into a key's plant starts
            if key is not None:   # the key's plant, where the key has the foot, lasts while it is near
                near = norm(foot[start:stop, [0, 2]] - foot[key, [0, 2]]) <= config.max_drift / 2
                far = np.flatnonzero(~near) + start
                first = max(far[far < key], default=start - 1) + 1
                end = min(far[far > key], default=stop)
                if first - start >= config.step_frames + config.min_stance_frames:   # plants before it
                    # The step into the key's plant goes while the other foot stands, but not
                    # long before the foot gets near: planted early, it was out of the leg's reach.
                    preferred = first - config.step_frames
                    lo = max(start + config.min_stance_frames, preferred - config.max_step_frames)
                    hi = max(lo, min(key - config.step_frames, preferred + config.max_step_frames))
                    lift = _free_step(busy, preferred, lo, hi, config.step_frames, int(np.clip(preferred, lo, hi)))
            if key is None or lift is not None:  # a plant of the foot's own, until it drifts
                until = stop if lift is None else lift
                drift = norm(foot[start:until, [0, 2]] - foot[start, [0, 2]])
                end = start + int(np.argmax(drift > config.max_drift)) if drift.max() > config.max_drift else until
            # The step waits for the other foot to stand, but not long: a plant held on while
            # the foot glides away would leave it metres to cover in one step.
            end = _free_step(busy, end, max(start + config.min_stance_frames, end - config.max_step_frames),
                             min(stop if lift is None else lift, end + config.max_step_frames), config.step_frames, end)
            if lift is None and stop - end < config.step_frames + config.min_stance_frames:
                end = stop                       # no room for another plant: hold this one
            out.append((int(start), int(end)))
            start = end + config.step_frames
    return _with_room_to_step(out, foot, config, keys, busy)


def _plant_spot(foot: np.ndarray, start: int, stop: int, keys: Sequence[int]) -> np.ndarray:
    """Where (x, z) a stance [start, stop) plants the foot (N, 3): at its first key frame, where
    the sketch put it, else its mean."""
    held = [k for k in keys if start <= k < stop]
    return foot[held[0], [0, 2]] if held else foot[start:stop, [0, 2]].mean(0)


def _swings(foot: np.ndarray, stop: int, start: int, config: FeetConfig) -> bool:
    """Whether the foot (N, 3) lifts itself off the floor between a plant's stop and the next
    one's start (else _foot_goal makes up a step there)."""
    return start > stop and foot[stop:start, 1].max() >= config.step_height


def _with_room_to_step(intervals: list[tuple[int, int]], foot: np.ndarray, config: FeetConfig,
                       keys: Sequence[int] = (), busy: np.ndarray | None = None) -> list[tuple[int, int]]:
    """Plants shortened so that the foot has frames enough to step from one to the next without
    a jolt (blend.ease_frames for their distance): held to the ends of their stances, two plants
    0.77 m apart left a gliding foot 4 frames to cover it (a 7 cm spike of the foot, 11 cm of the
    knee). So does a swing of the foot's own, to jolt at most swing_pop: the decoder's fast
    strides leave a plant 0.8 m from the next one 5 frames before it (artist_check's 100
    storyboards, scenes 0-49, seed 0: largest pop within 5 cm 55 -> 63, skate the same). Each
    frame is taken from the plant the foot has left further behind at that frame; a plant keeps
    min_stance_frames, its key frames and the frames the other foot is off (busy), so that the
    person never has both feet in the air."""
    free = np.ones(len(foot), bool) if busy is None else ~busy
    out = list(intervals)
    for i in range(len(out) - 1):
        (s1, e1), (s2, e2) = out[i], out[i + 1]
        spot1, spot2 = _plant_spot(foot, s1, e1, keys), _plant_spot(foot, s2, e2, keys)
        apart = float(np.linalg.norm(spot1 - spot2))
        own = _swings(foot, e1, s2, config)   # a swing of the foot's own: it jolts up to swing_pop
        if apart <= config.min_step_m or s2 - e1 > config.max_step_frames:
            continue
        last_key = max((k for k in keys if s1 <= k < e1), default=-1)
        first_key = min((k for k in keys if s2 <= k < e2), default=len(foot))
        need = ease_frames(apart, config.swing_pop if own else config.step_pop, config.step_frames,
                           config.max_step_frames)
        strict = True    # first while the other foot stands; then a brief hop beats a jolt
        while s2 - e1 < need:
            can_end = e1 - 1 >= s1 + config.min_stance_frames and e1 - 1 > last_key and (free[e1 - 1] or not strict)
            can_start = s2 + 1 <= e2 - config.min_stance_frames and s2 < first_key and (free[s2] or not strict)
            if not (can_end or can_start):
                if strict:
                    strict = False
                    continue
                break
            behind_end = np.linalg.norm(foot[e1 - 1, [0, 2]] - spot1)
            behind_start = np.linalg.norm(foot[s2, [0, 2]] - spot2)
            end, start = (e1 - 1, s2) if can_end and (not can_start or behind_end >= behind_start) else (e1, s2 + 1)
            if not own and _swings(foot, end, start, config):
                break     # made up, a step lifts the foot: frames where it lifts itself keep their plant
            e1, s2 = end, start
        out[i], out[i + 1] = (s1, e1), (s2, e2)
    return out


def _free_step(busy: np.ndarray | None, preferred: int, first: int, last: int, frames: int,
               default: int | None = None) -> int | None:
    """The frame in [first, last] nearest `preferred` (the later of two) at which a step of
    `frames` frames can start while the other foot stands (busy (N,) bool: it is off its plant);
    `default` if there is none."""
    order = sorted(range(first, last + 1), key=lambda e: (abs(e - preferred), -e))
    return next((e for e in order if busy is None or not busy[e:e + frames].any()), default)


STILL_STEP = 1e-3   # m a frame; a foot moving less to and from a frame stands there


def _retimed_swings(foot: np.ndarray, intervals: list[tuple[int, int]], config: FeetConfig,
                    keys: Sequence[int] = ()) -> np.ndarray:
    """The foot's path (N, 3) retimed along itself where it keeps its own path off its plants
    (not where _foot_goal makes up a step) and, held still at the plants, would jolt (spike) more
    than config.swing_pop: its progress along the path smoothed over time (config.swing_frames),
    still at the plants, at the key frames `keys` and wherever it stands, so that it leaves and
    lands slowly. Released at swing speed, a foot jolted 6-7 cm off its plant (20 artist-style
    storyboards: largest pop within 5 cm 12 -> 13). -> (N, 3)."""
    out = foot.copy()
    n, pad = len(foot), 3
    stretches = [(0, intervals[0][0], False, True)] if intervals else []   # (first, last frame, still at them)
    stretches += [(a - 1, b, True, True) for (_, a), (b, _) in zip(intervals[:-1], intervals[1:])
                  if b - a > config.max_step_frames or _swings(foot, a, b, config)]
    stretches += [(intervals[-1][1] - 1, n - 1, True, False)] if intervals else []
    for first, last, still_first, still_last in stretches:
        span = np.arange(max(first, 0), min(last, n - 1) + 1)
        held = np.concatenate([foot[span[:1]].repeat(2 * still_first, 0), foot[span],
                               foot[span[-1:]].repeat(2 * still_last, 0)])   # still at its plants
        if len(span) < 3 or spike(held).max() <= config.swing_pop:
            continue   # it leaves and lands smoothly already
        way = np.concatenate([[0.0], np.cumsum(norm(np.diff(foot[span], axis=0)))])
        before, after = pad * still_first, pad * still_last
        values = np.concatenate([np.zeros(before), way, np.full(after, way[-1])])
        weight = np.ones(len(values))
        weight[:before + still_first] = weight[len(values) - after - still_last:] = HELD_WEIGHT
        steps = np.diff(way)
        still = np.concatenate([[False], (steps[:-1] < STILL_STEP) & (steps[1:] < STILL_STEP), [False]])
        weight[before + np.flatnonzero(still | np.isin(span, keys))] = HELD_WEIGHT   # nor where it stands
        progress = smooth_path(values[:, None], weight, config.swing_frames ** 4)[before:before + len(span), 0]
        at = np.interp(np.clip(np.maximum.accumulate(progress), 0.0, way[-1]), way, span)
        out[span] = np.stack([np.interp(at, span, foot[span, k]) for k in range(3)], -1)
    return out


def _foot_goal(foot: np.ndarray, intervals: list[tuple[int, int]], config: FeetConfig,
               keys: Sequence[int] = ()) -> np.ndarray:
    """Where one foot (N, 3) should be, given its stances -> (N, 3). A stance holding a key
    frame plants the foot where it is at its first key (there, the sketch put it)."""
    n = len(foot)
    on = np.zeros(n, bool)
    target = foot.copy()
    # Lift-off and touch-down frames (a neighbour is off the floor) keep their height.
    flat = maximum_filter1d(foot[:, 1], 3, mode="nearest") < config.stance_height
    for start, stop in intervals:
        on[start:stop] = True
        target[start:stop, [0, 2]] = _plant_spot(foot, start, stop, keys)
        target[start:stop, 1] = np.where(flat[start:stop], config.foot_height, foot[start:stop, 1])
    own = _retimed_swings(foot, intervals, config, keys)
    correction = target - own                                                  # (N, 3), 0 off stance
    # Before the first stance, after the last and across long gaps the foot keeps its own path
    # (retimed): the correction fades out over blend_frames.
    frames = np.arange(n)
    carried = np.stack([np.interp(frames, frames[on], correction[on, k]) for k in range(3)], -1)
    ramp = 1.0 - distance_transform_edt(~on) / (config.blend_frames + 1)
    goal = own + smoothstep(ramp)[:, None] * carried
    stepped = np.zeros(n, bool)                                               # made-up steps
    # A short gap is a step from one plant to the next, eased so the foot leaves and lands
    # slowly. A swing keeps its own shape, shifted from the first plant's correction to the
    # next one's; a gap that never leaves the floor was a slide and becomes an arc that rises
    # fast (square root of a sine) so that the foot is off the floor while it travels.
    for (_, a), (b, _) in zip(intervals[:-1], intervals[1:]):
        if b - a > config.max_step_frames:
            continue
        s = (frames[a:b] - a + 1) / (b - a + 1)
        ease = smoothstep(s)[:, None]
        if not _swings(foot, a, b, config):
            goal[a:b] = target[a - 1] + ease * (target[b] - target[a - 1])
            lift = config.step_height - config.foot_height
            goal[a:b, 1] = config.foot_height + lift * np.sqrt(np.sin(np.pi * s))
            stepped[a:b] = True
        else:
            goal[a:b] = own[a:b] + correction[a - 1] + ease * (correction[b] - correction[a - 1])
    # Plants and keys stay exact; everywhere else the correction changes smoothly (a foot that
    # left a plant at full speed, or went back to its own path in three frames, popped the knee).
    # Made-up steps are smooth already and stay exact: flattened, they slid along the floor, and
    # smoothing their correction (not the step) brought back the glide's jolts.
    held = on | stepped
    held[[k for k in keys if 0 <= k < n]] = True
    smooth = own + smooth_correction(goal - own, held, config.correction_frames ** 4)
    smooth[:, 1] = np.maximum(smooth[:, 1], np.minimum(goal[:, 1], config.foot_height))   # not into the floor
    return smooth


HOP_HEIGHT = 0.055   # m; the lower foot of a hop no walk replaces comes down to this: just over
                     # the height under which a travelling foot slides (metrics' contact height)


def _lower_in_hops(goals: list[np.ndarray], config: FeetConfig, keys: Sequence[int] = ()) -> list[np.ndarray]:
    """Both feet's goals (two (N, 3)) with the lower foot of every stretch in which both are up
    (a hop walk.py did not replace: a made-up step while the other foot hovers) brought down to
    HOP_HEIGHT there, eased in and out (blend.eased_push over config.hop_frames) and never under
    config.stance_height where it was over (lower, it would slide along the floor); not around a
    key frame of `keys` (the warp placed the key's feet). The hop stays, skimming the floor: 20
    artist-style storyboards' lowest foot p95 within 6 cm 12 -> 20, pops the same."""
    goals = [g.copy() for g in goals]
    up = (goals[0][:, 1] > HOP_HEIGHT) & (goals[1][:, 1] > HOP_HEIGHT)
    spans, count = label(up)
    for i in range(1, count + 1):
        frames = np.flatnonzero(spans == i)
        if any(frames[0] - 1 <= k <= frames[-1] + 1 for k in keys):
            continue
        y = goals[int(np.argmin([g[frames, 1].mean() for g in goals]))][:, 1]   # a view: edits the goal
        drop = np.zeros((len(y), 3))
        drop[frames, 1] = y[frames] - HOP_HEIGHT
        y[:] = np.maximum(y - eased_push(drop, config.hop_frames)[:, 1], np.minimum(y, config.stance_height))
    return goals

def lock_feet(joints: np.ndarray, fps: float, config: FeetConfig = FeetConfig(),
              keys: Sequence[Sequence[int]] | None = None) -> np.ndarray:
    """Pin each foot during its stance intervals and re-solve the leg from the hip.

    joints (N, H, 22, 3) -> (N, H, 22, 3); knees, ankles and feet move, and a body standing too
    tall for its planted legs lowers as a whole (at most config.max_crouch; not at the key
    frames, whose legs the warp made reach). During a stance the
    foot joint holds the interval's mean horizontal position, or where it is at a key frame of
    keys[h] (each person's keypose frames) in the stance, at config.foot_height (lift-off and
    touch-down frames keep their height); around it the foot eases in and out over
    config.blend_frames, or steps to the next plant; off its plants, a foot gliding fast while
    the other stands is lifted (_lift_glides). The knee bends the way it already bent
    (towards the person's facing when the leg was straight); a goal out of reach straightens
    the leg towards it (after the crouch, only horizontally). Call after `settle_on_ground`.
    """
    joints = np.asarray(joints, float)
    out = joints.copy()
    for h in range(joints.shape[1]):
        pose = joints[:, h]                                                    # (N, 22, 3)
        held = keys[h] if keys is not None else ()
        busy = np.ones(len(joints), bool)                                      # left foot off its plant
        goals = []
        for side in range(2):
            intervals = stance_intervals(pose[:, FEET[side]], fps, config, busy if side else None, held,
                                         pose[:, FEET[1 - side]])
            for start, stop in intervals:
                busy[start:stop] = False
            goals.append(_foot_goal(pose[:, FEET[side]], intervals, config, held) if intervals
                         else pose[:, FEET[side]])
        goals = _lower_in_hops(walk_through_flights(goals, pose, held, config), config, held)
        goals = _lift_glides(goals, fps, config, held)
        crouch = _crouch(pose, goals, config)
        if held:   # the keyposes stand as the warp placed them (their legs reach already)
            crouch *= 1.0 - closeness_to_keys(len(pose), held, config.blend_frames)
        out[:, h] -= crouch[:, None, None] * UP
        for side, goal in enumerate(goals):                # a foot the crouch moved goes back
            moved = np.any(goal != pose[:, FEET[side]], axis=-1) | (crouch > 0)   # the rest stays exact
            turned = _foot_turn_smoothed(out[:, h], side, config.foot_turn_sigma, config.most_foot_turn)
            out[moved, h] = reach_with_leg(turned[moved], side, goal[moved])
    return out


def _lift_glides(goals: list[np.ndarray], fps: float, config: FeetConfig, keys: Sequence[int] = ()) -> list[np.ndarray]:
    """Both feet's goals (two (N, 3)) with a foot that glides low off its plant for
    config.min_glide_frames or more while the other stands raised with its speed: from
    config.glide_speeds[0] up to step_height at [1], eased in over config.glide_frames, fading
    where the other foot lifts (never a hop) and around the key frames `keys` (the warp placed
    their feet). A foot left on its own path across a gap too long for a made-up step had
    skimmed the floor at 1-3 m/s: of 40 artist-style storyboards (two seeds) 3 -> 0 skated in
    over 3% of their frames (mean 0.50 -> 0.32%), the real windows' skate 1.5 -> 1.2%, pops,
    grips and feet's float the same."""
    slow, fast = config.glide_speeds
    n = len(goals[0])
    away = 1.0 - closeness_to_keys(n, list(keys), config.blend_frames) if len(keys) else np.ones(n)
    out = [g.copy() for g in goals]

    def eased_into(frames: np.ndarray) -> np.ndarray:   # (N,) bool -> 0 outside, 1 two glide_frames in
        return smoothstep(np.clip(distance_transform_edt(frames) / (2.0 * config.glide_frames), 0.0, 1.0))

    for side in range(2):
        standing = goals[1 - side][:, 1] <= config.stance_height
        speed = norm(np.gradient(goals[side][:, [0, 2]], axis=0)) * fps if n > 1 else np.zeros(n)
        runs, count = label((goals[side][:, 1] < config.stance_height) & (speed > slow))
        lengths = np.bincount(runs.ravel(), minlength=count + 1)
        gliding = (runs > 0) & (lengths[runs] >= config.min_glide_frames)   # not a swing's lift-off or landing
        rise = smoothstep(np.clip((speed - slow) / (fast - slow), 0.0, 1.0))
        lift = (config.step_height - config.foot_height) * rise * eased_into(gliding) * eased_into(standing) * away
        out[side][:, 1] = np.maximum(goals[side][:, 1], config.foot_height + lift)
    return out


def _crouch(pose: np.ndarray, goals: list[np.ndarray], config: FeetConfig) -> np.ndarray:
    """How far (N,) a person (pose (N, 22, 3)) lowers so that its legs reach their foot goals
    (each (N, 3)): a body standing taller than its planted legs would straighten them
    and lift the feet off the ground. At most config.max_crouch; smoothed, so it never bobs."""
    need = np.zeros(len(pose))
    for side, goal in enumerate(goals):
        hip, knee, ankle, toe = HIPS[side], KNEES[side], ANKLES[side], FEET[side]
        length = config.leg_extension * (norm(pose[:, knee] - pose[:, hip])
                          + norm(pose[:, ankle] - pose[:, knee]))
        reach = goal - (pose[:, toe] - pose[:, ankle]) - pose[:, hip]          # hip -> ankle goal
        across = norm(reach[:, [0, 2]])
        need = np.maximum(need, -reach[:, 1] - np.sqrt(np.maximum(length ** 2 - across ** 2, 0.0)))
    need = np.clip(need, 0.0, config.max_crouch)
    held = maximum_filter1d(need, config.crouch_window, mode="nearest")
    return gaussian_filter1d(held, config.crouch_sigma, mode="nearest")


def _foot_turn_smoothed(poses: np.ndarray, side: int, sigma: float, most: float) -> np.ndarray:
    """Poses (N, 22, 3) in time order with one foot's joint turned about its ankle towards the
    foot's direction smoothed over sigma frames, by about `most` metres at most (a foot pivoting
    on its toes swings fast, and smoothed whole, it swung the ankle 10 cm in a frame), its length
    kept -> (N, 22, 3)."""
    toe, ankle = FEET[side], ANKLES[side]
    foot = poses[:, toe] - poses[:, ankle]
    length = norm(foot, keepdims=True)
    change = normalize(gaussian_filter1d(foot, sigma, axis=0, mode="nearest")) * length - foot
    change = at_most(change, most)
    out = poses.copy()
    out[:, toe] = poses[:, ankle] + normalize(foot + change) * length
    return out


STRAIGHTEST = 0.99   # share of a leg's length that reach_with_leg extends it to at most


def reach_with_leg(poses: np.ndarray, side: int, foot_goal: np.ndarray) -> np.ndarray:
    """Poses (M, 22, 3) with one leg (side 0 left, 1 right) re-solved from its fixed hip by exact
    two-bone IK so that the foot joint, riding rigidly on the ankle, reaches foot_goal (M, 3);
    a goal beyond STRAIGHTEST of the leg's reach gets the leg reaching towards it -> (M, 22, 3).
    The M poses are frames in time order: the knee bends the way it bends now (off the old
    hip-ankle line, so a foot planted ahead cannot flip it backwards), towards the facing as the
    leg straightens, turning smoothly over the frames (steady_pole)."""
    hip, knee, ankle, toe = HIPS[side], KNEES[side], ANKLES[side], FEET[side]
    out = poses.copy()
    foot_offset = poses[:, toe] - poses[:, ankle]
    upper = norm(poses[:, knee] - poses[:, hip], keepdims=True)
    lower = norm(poses[:, ankle] - poses[:, knee], keepdims=True)
    axis = normalize(poses[:, ankle] - poses[:, hip])
    bend = poses[:, knee] - poses[:, hip]
    bend -= np.sum(bend * axis, axis=-1, keepdims=True) * axis
    facing = normalize(cross(poses[:, HIPS[0]] - poses[:, HIPS[1]], UP))
    pole = steady_pole(bend, facing)
    # A knee never bends backwards: a nearly straight leg's bend is noise, and followed, it bent
    # the knee back for a few frames, then flipped it forward (a 42 cm pop).
    pole -= 2.0 * np.minimum(np.sum(pole * facing, axis=-1, keepdims=True), 0.0) * facing
    # Nor does it straighten fully: near straight a knee swings far for a small change of reach
    # (one came back from straight to reach its lifting foot 23 cm in a frame).
    reach = foot_goal - foot_offset - poses[:, hip]
    length = np.maximum(norm(reach, keepdims=True), 1e-9)
    reach *= np.minimum(1.0, STRAIGHTEST * (upper + lower) / length)
    out[:, knee], out[:, ankle] = two_bone_ik(poses[:, hip], poses[:, hip] + reach, upper, lower, pole)
    out[:, toe] = out[:, ankle] + foot_offset
    return out


def reach_with_legs(poses: np.ndarray, feet: np.ndarray) -> np.ndarray:
    """Poses (M, 22, 3) with both legs re-solved from their hips (reach_with_leg) to the feet
    (M, 2, 3), left then right -> (M, 22, 3)."""
    for side in range(2):
        poses = reach_with_leg(poses, side, feet[:, side])
    return poses

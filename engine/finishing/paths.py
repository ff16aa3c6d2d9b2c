"""Pelvis strokes walked on time: a person whose pelvis has a stroke goes along it, from its first
point at its first frame to its last at its last, through the keyposes the warp placed.

Where along the stroke the generated person is, frame by frame, is a monotone match of the pelvis
to the stroke (nearest points, in order, at most `PathConfig.top_speed`): a stroke that loops or
doubles back (a dancer's) is not jumped across, as the nearest point alone would. Between
keyframes the person keeps the generated motion's pace along the stroke (a pause to pick up a
box stays a pause), stretched to meet the keys; where that pace rushes (the generated motion
stood still, then hurried to catch up with a stroke it did not follow), the person goes on
evenly instead. Held-out real dancers' pelvises were 32 cm off, most of it along the stroke; so
matched and timed, 22 cm, and synthesized scenes' 12.4 -> 11.7 cm (evening out every interval
took those to 16.6 cm: their pauses are real).

A 2D stroke does not give depth; the ground does: it is lifted to where the stroke's ray meets
the pelvis height at which the lower foot touches the ground (or walked on the floor path itself
where the floor plan drew it). In depth, along the camera ray, a pelvis moves only a share of
the way there (`depth_share`, growing to all of it where the generated pelvis strays far from its
stroke: `far_off`): taken whole where the pelvis was off its stroke in the sketch plane, the
lifted stroke's depth (from a generated pelvis height that bobs, seen at 20 degrees) put
synthesized and hand-drawn pelvises 1-2 cm further from the held-out motion than the generated
depth did, while real dancers' generated depth is the worse one; and where the sketch plane
already has the pelvis on its stroke, the generated depth bowed off the path (by 18 cm more than
the held-out motion on hand-drawn storyboards). A quarter of the way, in both: pelvis error
sketch-only 11.6 -> 10.7 cm, hand-drawn 17.2 -> 15.6, sketch + text 14.9 -> 14.1, real 22.3 ->
21.5 (same generated motions, three seeds).

Joint arrays are (N, H, 22, 3) in metres.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar, NamedTuple

import numpy as np
from scipy.ndimage import gaussian_filter1d, uniform_filter1d

from ..camera import StoryboardCamera
from ..geometry.polylines import resample_polyline
from ..geometry.rotations import norm
from ..skeleton import JOINT_INDEX
from ..storyboard import Storyboard, Trajectory
from .keys import key_frames, spread
from .warp import LEVEL, grounding_height

PELVIS = JOINT_INDEX["pelvis"]
PATH_SAMPLES = 200   # points a stroke is resampled to when matching a motion to it


@dataclass
class PathConfig:
    DURATIONS: ClassVar[tuple[str, ...]] = ("falloff", "smoothing", "speed_window", "way_smoothing", "depth_smoothing")
    # (frames at TUNED_FPS)
    falloff: int = 12             # frames over which the keyframes' hold on the offsets fades out beyond them
    smoothing: float = 2.5        # frames; Gaussian sigma of the per-frame offsets (4 cut a stroke's
                                  # corners: a walk along it slowed to a halt where it turned back)
    passes: int = 2               # smoothing pulls points off the stroke a little; place them again
    tolerance: float = 0.03       # m in the sketch plane; closer than this to its stroke, a pelvis is
                                  # left alone (a hand-drawn stroke wobbles; the walk should not)
    top_speed: float = 4.0        # m/s; the fastest a pelvis is taken to go along its stroke
    rush_speeds: tuple[float, float] = (2.5, 3.5)   # m/s; a generated pace along a stroke faster than the
                                  # first (over speed_window frames) is blended towards even progress, wholly
                                  # at the second ((2, 3) did as well on real dancers, worse on synthesized
                                  # scenes)
    speed_window: int = 5         # frames
    way_smoothing: float = 1.5    # frames; Gaussian sigma of the progress along a stroke
    foot_height: float = 0.02     # m; height of the foot joint standing on the ground (as FeetConfig's)
    depth_share: float = 0.25     # share of the way along the camera ray a pelvis moves towards its place
                                  # on the lifted stroke (the rest of the way is in the sketch plane);
                                  # 0 suits synthesized scenes best, 0.5 real dancers (module doc)
    depth_smoothing: float = 5.0  # frames; Gaussian sigma of that move (2.5 jolted real dancers' pelvises)
    far_off: tuple[float, float] = (0.1, 0.4)   # m in the sketch plane: where the generated pelvis strays
                                  # further from its stroke (90th percentile over the span) than the first,
                                  # the share grows, to all of the way beyond the second (a person the model
                                  # left standing while the stroke walks 2 m has no depth of its own)


class StrokePath(NamedTuple):
    """A pelvis stroke resampled evenly: `points` (S, 2) in its own plane (the sketch plane, or
    the floor for a floor path), `length` (S,) metres along it on the ground."""
    points: np.ndarray
    length: np.ndarray
    on_floor: bool

    @classmethod
    def of(cls, stroke: Trajectory, camera: StoryboardCamera, height: float) -> "StrokePath":
        """The stroke, its ground lengths measured with the sketch lifted to `height` (m)."""
        if stroke.floor is not None:
            points = resample_polyline(np.asarray(stroke.floor, float), PATH_SAMPLES)
            ground = points
        else:
            points = resample_polyline(np.asarray(stroke.points, float), PATH_SAMPLES)
            ground = camera.unproject_to_height(points, height)[:, [0, 2]]
        steps = norm(np.diff(ground, axis=0))
        return cls(points, np.concatenate([[0.0], np.cumsum(steps)]), stroke.floor is not None)

    def seen(self, pelvis: np.ndarray, camera: StoryboardCamera) -> np.ndarray:
        """Pelvis positions (M, 3) in the path's plane -> (M, 2)."""
        return pelvis[:, [0, 2]] if self.on_floor else camera.project(pelvis)

    def along(self, points: np.ndarray, near: np.ndarray) -> np.ndarray:
        """Metres along the path (M,) of points (M, 2) projected onto the segments either side of
        their matched samples `near` (M,), never back."""
        best = np.full(len(points), np.inf)
        out = self.length[near].astype(float)
        for lo in (np.maximum(near - 1, 0), near):
            hi = np.minimum(lo + 1, len(self.points) - 1)
            seg = self.points[hi] - self.points[lo]
            t = np.clip(np.sum((points - self.points[lo]) * seg, -1) / np.maximum(np.sum(seg * seg, -1), 1e-12), 0.0, 1.0)
            dist = norm(self.points[lo] + t[:, None] * seg - points)
            closer = dist < best
            best[closer] = dist[closer]
            out[closer] = (self.length[lo] + t * (self.length[hi] - self.length[lo]))[closer]
        return np.maximum.accumulate(out)

    def place(self, way: np.ndarray, height: np.ndarray, camera: StoryboardCamera) -> np.ndarray:
        """World points (M, 3) `way` (M,) metres along the path, at pelvis heights (M,)."""
        at = np.stack([np.interp(way, self.length, self.points[:, i]) for i in range(2)], -1)
        if self.on_floor:
            return np.stack([at[:, 0], height, at[:, 1]], -1)
        return camera.unproject_to_height(at, height)


def follow_paths(joints: np.ndarray, storyboard: Storyboard, config: PathConfig = PathConfig(),
                 fps: float = 20.0) -> np.ndarray:
    """People whose pelvis has a stroke walk it on time with the lower foot on the ground; the
    keyposes stay where they are, the offsets are smoothed, and beyond the stroke's span its ends'
    offsets hold, easing to none at the nearest keyframes. joints (N, H, 22, 3) -> same."""
    out = joints.copy()
    n, cam = len(joints), storyboard.camera
    back = cam.basis()[2]
    level = abs(back[1]) <= LEVEL
    for stroke in storyboard.trajectories:
        if stroke.joint != "pelvis" or (level and stroke.floor is None):
            continue
        h = storyboard.agent_index(stroke.agent)
        span = np.arange(stroke.start, min(stroke.end, n - 1) + 1)
        if len(span) < 2:
            continue
        keys = key_frames(storyboard)[h]
        way = None
        for step in range(config.passes):   # smoothing pulls points off the stroke a little
            first = step == 0
            pelvis = out[span, h, PELVIS]
            height = pelvis[:, 1] + grounding_height(out[span, h], config.foot_height)
            height = smoothed_keeping_ends(height[:, None], config.smoothing)[:, 0]   # the lower foot changes
            path = StrokePath.of(stroke, cam, float(np.mean(height)))
            if way is None:   # metres along the stroke at each frame of its span
                holding = storyboard.holding(objects_only=True)[span, h].any(-1)
                way = _stroke_timing(path, path.seen(pelvis, cam), span, keys, holding, fps, config)
            target = path.place(way, height, cam)
            apart = norm(path.seen(target, cam) - path.seen(pelvis, cam), keepdims=True)
            off = np.clip(apart / config.tolerance - 1.0, 0.0, 1.0)   # a hand-drawn stroke wobbles; the walk should not
            move = target - pelvis
            if first:   # in depth, part of the way (all of it far off); in the sketch plane where it is off the stroke
                deeper = (move @ back)[:, None] * back                 # (M, 3) along the camera ray
                near, far_off = config.far_off
                far = np.clip((np.percentile(apart, 90) - near) / (far_off - near), 0.0, 1.0)
                share = config.depth_share + (1.0 - config.depth_share) * far
                shift = (smoothed_keeping_ends((move - (1.0 - share) * deeper) * off, config.smoothing)
                         + smoothed_keeping_ends(share * deeper * (1.0 - off), config.depth_smoothing))
            else:
                shift = smoothed_keeping_ends(move * off, config.smoothing)
            out[:, h] += _beyond_span(n, span, keys, shift, config.falloff)[:, None, :]
    return out


def _stroke_timing(path: StrokePath, seen: np.ndarray, span: np.ndarray, keys: list[int], holding: np.ndarray,
                   fps: float, config: PathConfig) -> np.ndarray:
    """Metres along the path (M,) to be at each frame of the span, for a pelvis seen at (M, 2)."""
    top = config.top_speed / fps / max(path.length[-1] / (PATH_SAMPLES - 1), 1e-9)   # samples a frame
    come = path.along(seen, matched(seen, path.points, int(np.clip(np.ceil(top), 1, PATH_SAMPLES)), span[-1] in keys))
    way = timed_way(come, path.length[-1], [i for i, f in enumerate(span) if f in keys], holding, fps, config)
    return smoothed_keeping_ends(way[:, None], config.way_smoothing)[:, 0]


def matched(points: np.ndarray, path: np.ndarray, most_step: int, to_end: bool = True) -> np.ndarray:
    """Indices (M,) into a path (S, D) for points (M, D) in time order: from its first point (to
    its last with `to_end`: a keyed end is there, be it where the path crosses itself), never
    back, at most `most_step` a frame, nearest in total (dynamic programming). Without `to_end`
    a motion that stopped short of the path's end is matched where it is."""
    if to_end:   # the last point reachable
        most_step = max(most_step, -(-(len(path) - 1) // max(len(points) - 1, 1)))
    cost = norm(points[:, None] - path[None])            # (M, S)
    total = np.empty_like(cost)
    total[0] = np.inf
    total[0, 0] = cost[0, 0]
    for t in range(1, len(points)):   # best total arriving at each index from the window behind it
        total[t] = cost[t] + _trailing_min(total[t - 1], most_step)
    out = np.empty(len(points), int)
    out[-1] = len(path) - 1 if to_end else int(np.argmin(total[-1]))
    for t in range(len(points) - 1, 0, -1):
        lo = max(out[t] - most_step, 0)
        out[t - 1] = lo + int(np.argmin(total[t - 1, lo:out[t] + 1]))
    return out


def _trailing_min(values: np.ndarray, span: int) -> np.ndarray:
    """(S,) -> out[i] = min(values[max(i - span, 0):i + 1]), windows doubled: log2(span) array
    minima instead of one filter call per frame of the match (the filter's overhead was 70% of it)."""
    out, width = values.copy(), 1
    while 2 * width <= span + 1:
        out[width:] = np.minimum(out[width:], out[:-width])
        width *= 2
    rest = span + 1 - width
    if rest > 0:
        out[rest:] = np.minimum(out[rest:], out[:-rest])
    return out


def timed_way(come: np.ndarray, end: float, keys: list[int], holding: np.ndarray, fps: float,
              config: PathConfig) -> np.ndarray:
    """Metres along the stroke (M,) to be at each frame of its span: `come` (M,) where the motion
    is, kept at the span's keyframes (indices `keys`), from 0 at its first frame to `end` m (the
    stroke's length) at its last unless keyed there; between them its pace, stretched
    to meet them, blended towards even progress as far as it rushes (config.rush_speeds), but
    not where the person holds an object (`holding` (M,) bool): there the generated pace is the
    contacts' (evened out, it put holders 0.5 cm further from their grips and 0.3 cm deeper
    into the boxes)."""
    m = len(come)
    anchors = sorted(set(keys) | {0, m - 1})
    at = np.maximum.accumulate([come[i] if i in keys else 0.0 if i == 0 else end for i in anchors])
    even = np.interp(np.arange(m), anchors, at)
    way = even.copy()
    slow, fast = config.rush_speeds
    for (a, b), (va, vb) in zip(zip(anchors, anchors[1:]), zip(at, at[1:])):
        pace = come[a:b + 1] - come[a]
        if pace[-1] <= 1e-3:   # the motion stands: even progress
            continue
        speed = uniform_filter1d(np.diff(pace), config.speed_window, mode="nearest").max() * fps
        rush = 0.0 if holding[a:b + 1].any() else float(np.clip((speed - slow) / (fast - slow), 0.0, 1.0))
        way[a:b + 1] = (1 - rush) * (va + (vb - va) * pace / pace[-1]) + rush * even[a:b + 1]
    return way


def smoothed_keeping_ends(values: np.ndarray, sigma: float) -> np.ndarray:
    """values (M, D) smoothed (Gaussian, `sigma` frames) with each end's value and slope kept: the
    ends are extended by point reflection (a walk's offset that grows to its end still gets there)."""
    pad = min(int(4 * sigma) + 1, len(values) - 1)
    if pad < 1:
        return values.copy()
    extended = np.concatenate([2 * values[:1] - values[pad:0:-1], values, 2 * values[-1:] - values[-2:-pad - 2:-1]])
    return gaussian_filter1d(extended, sigma, axis=0, mode="nearest")[pad:pad + len(values)]


def _beyond_span(n: int, span: np.ndarray, keys: list[int], shift: np.ndarray, falloff: int) -> np.ndarray:
    """Offsets (n, 3) from a stroke span's (M, 3): held beyond the span and eased to none at the
    nearest keyframes outside it; none at the keyframes (the warp placed those poses)."""
    outside = sorted(set(keys) - set(span.tolist()))
    frames = np.asarray(outside + span.tolist())
    values = np.concatenate([np.zeros((len(outside), 3)), shift])
    order = np.argsort(frames)
    full = np.stack([np.interp(np.arange(n), frames[order], values[order, i]) for i in range(3)], -1)
    if keys:
        full -= spread(n, keys, full[keys], falloff)
    return full

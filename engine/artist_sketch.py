"""Storyboards drawn the way artists draw, from a clean traced one (engine.sketchify at noise 0).

Traced storyboards are a home ground: 48-point paths, exact bone lengths, keys on the source's
own frames. An artist's differ, and two kinds are made here, each from a seed:

`hand_drawn`: figures stretched or squashed by up to 12% (per key, about the pelvis), every
placed joint 2-3 cm off, spine and collar joints often left unplaced, interior keys and contact
spans a few frames off, strokes short and wobbly (8-20 points), a box drawn as its four corners,
each hand joined to the grip the app's contact tool shows nearest it, then mended as the app
mends them (engine.grips: which of an object's grips a hand holds is no 2D drawing's to say).
`posed_with_tools`: what the app's keypose tool gives an artist who drags only the end effectors:
the canvas's standing template (engine.poses) placed at the pelvis by a click, then ankles, feet,
wrists and head dragged to where they belong with the canvas's rig (engine.rig: the limbs follow by
IK with the template's drawn bone lengths, so a hand beyond the drawn arm's reach stops short);
paths, object and contacts as in `hand_drawn`.
The benchmark scores both (engine.bench.protocol); training can learn from them
(DatasetConfig.artist_share, through `redrawn`).
"""
from __future__ import annotations

import copy
from dataclasses import dataclass

import numpy as np

from .geometry.polylines import resample_polyline
from .grips import anchors_in_sketch, with_grips_fitted
from .poses import standing_pose_2d
from .rig import drag_pose
from .skeleton import HANDS, JOINT_INDEX
from .storyboard import HANDS as HAND_NAMES
from .storyboard import Keypose, Storyboard, StoryboardError

UNPLACED_CANDIDATES = ("spine1", "spine2", "spine3", "l_collar", "r_collar")
DRAGGED = ("l_ankle", "r_ankle", "l_foot", "r_foot", "l_wrist", "r_wrist", "head")   # in the artist's order


@dataclass(frozen=True)
class ArtistConfig:
    stretch: float = 0.12              # figure scale per axis within 1 +- this
    joint_offset_m: tuple[float, float] = (0.02, 0.03)
    unplaced_share: float = 0.5        # chance that each spine / collar joint is left out
    key_shift: int = 4                 # interior keys move by 1..this frames, either way
    span_shift: int = 4                # contact span ends likewise
    stroke_points: tuple[int, int] = (8, 20)
    wobble_m: float = 0.015            # low-frequency wobble of a stroke, amplitude
    corner_jitter_m: float = 0.02


# Drawn more roughly still (artist_check --harsh): a check that the finishing was not tuned to the above.
HARSH = ArtistConfig(stretch=0.18, joint_offset_m=(0.03, 0.05), key_shift=6, span_shift=6, stroke_points=(5, 12),
                     wobble_m=0.03, corner_jitter_m=0.04)


def hand_drawn(clean: Storyboard, seed: int, config: ArtistConfig = ArtistConfig()) -> Storyboard:
    rng = np.random.default_rng(seed)
    sb = _with_rough_paths_and_spans(clean, rng, config)
    sb.keyposes = [_drawn_figure(k, rng, config) for k in _shifted_keys(clean, rng, config)]
    return _valid(with_grips_fitted(_grips_clicked(sb)), clean)


def posed_with_tools(clean: Storyboard, seed: int, config: ArtistConfig = ArtistConfig()) -> Storyboard:
    rng = np.random.default_rng(seed)
    sb = _with_rough_paths_and_spans(clean, rng, config)
    template = standing_pose_2d(clean.camera)
    sb.keyposes = [_posed_figure(k, template, rng, config) for k in _shifted_keys(clean, rng, config)]
    return _valid(with_grips_fitted(_grips_clicked(sb)), clean)


def redrawn(clean: Storyboard, seed: int, posed: bool = False) -> Storyboard:
    """`clean` drawn by hand (or posed with the tools), or itself where a window's storyboard
    cannot be redrawn into a valid one (training takes whatever windows the clips give)."""
    try:
        return (posed_with_tools if posed else hand_drawn)(clean, seed)
    except (StoryboardError, ValueError):
        return clean


def _valid(sb: Storyboard, clean: Storyboard) -> Storyboard:
    """The storyboard, or with the clean contact spans where shifted ones clash (a hand-off's
    spans overlapping): the app refuses such a storyboard, so an artist would fix it."""
    try:
        sb.validate()
    except StoryboardError:
        sb.contacts = copy.deepcopy(clean.contacts)
        sb.validate()
    return sb


def _grips_clicked(sb: Storyboard) -> Storyboard:
    """Each object contact's grip the one the app shows nearest its hand (engine.grips.
    anchors_in_sketch) at the hand's key nearest the span's start, on the object's outline
    nearest that frame."""
    for c in sb.contacts:
        wrist = HANDS[HAND_NAMES.index(c.hand)]
        keys = [k for k in sb.keyposes if k.agent == c.agent and k.mask[wrist]]
        outlines = [o for o in sb.object_keys if o.object == c.object]
        if c.object is None or not keys or not outlines:
            continue
        key = min(keys, key=lambda k: (abs(k.frame - min(max(k.frame, c.start), c.end)), abs(k.frame - c.start)))
        outline = min(outlines, key=lambda o: abs(o.frame - key.frame)).outline
        spec = sb.objects[sb.object_index(c.object)].spec
        shown = anchors_in_sketch(spec.anchors, outline, sb.camera)
        c.anchor = int(np.argmin(np.linalg.norm(shown - key.points[wrist], axis=-1)))
    return sb


def _shifted_keys(clean: Storyboard, rng: np.random.Generator, config: ArtistConfig) -> list[Keypose]:
    """Keys at the first and last frame stay; interior ones move a few frames (per agent: each
    key is placed by hand on the timeline)."""
    last = clean.length - 1
    out = []
    for k in clean.keyposes:
        frame = k.frame
        if 0 < frame < last:
            frame = int(np.clip(frame + rng.choice([-1, 1]) * rng.integers(1, config.key_shift + 1), 1, last - 1))
        out.append(Keypose(k.agent, frame, k.points.copy(), k.mask.copy()))
    seen, unique = set(), []
    for k in out:  # two keys of one agent landing on one frame: the artist keeps one
        if (k.agent, k.frame) not in seen:
            seen.add((k.agent, k.frame))
            unique.append(k)
    return unique


def _drawn_figure(k: Keypose, rng: np.random.Generator, config: ArtistConfig) -> Keypose:
    pelvis = k.points[JOINT_INDEX["pelvis"]]
    scale = 1.0 + rng.uniform(-config.stretch, config.stretch, 2)
    points = pelvis + (k.points - pelvis) * scale
    points = points + _offsets(rng, len(points), config)
    mask = k.mask.copy()
    for name in UNPLACED_CANDIDATES:
        if rng.random() < config.unplaced_share:
            mask[JOINT_INDEX[name]] = False
    return Keypose(k.agent, k.frame, np.where(mask[:, None], points, 0.0), mask)


def _posed_figure(k: Keypose, template: np.ndarray, rng: np.random.Generator, config: ArtistConfig) -> Keypose:
    points = template + k.points[JOINT_INDEX["pelvis"]] + _offsets(rng, 1, config)   # placed by a click
    placed = np.ones(len(points), bool)
    for name in DRAGGED:
        j = JOINT_INDEX[name]
        if k.mask[j]:
            points = drag_pose(points, placed, j, k.points[j] + _offsets(rng, 1, config)[0], template=template)
    return Keypose(k.agent, k.frame, points, placed)


def _offsets(rng: np.random.Generator, count: int, config: ArtistConfig) -> np.ndarray:
    """(count, 2) offsets of 2-3 cm in random directions."""
    angle = rng.uniform(0, 2 * np.pi, count)
    length = rng.uniform(*config.joint_offset_m, count)
    return length[:, None] * np.stack([np.cos(angle), np.sin(angle)], -1)


def _with_rough_paths_and_spans(clean: Storyboard, rng: np.random.Generator, config: ArtistConfig) -> Storyboard:
    sb = copy.deepcopy(clean)
    for t in sb.trajectories:
        t.points = _wobbly(t.points, rng, config)
    for p in sb.object_paths:
        p.points = _wobbly(p.points, rng, config)
    for key in sb.object_keys:
        lo, hi = key.outline.min(0), key.outline.max(0)
        corners = np.array([[lo[0], lo[1]], [hi[0], lo[1]], [hi[0], hi[1]], [lo[0], hi[1]]])
        key.outline = corners + rng.normal(0, config.corner_jitter_m / 2, corners.shape)
    last = sb.length - 1
    for c in sb.contacts:
        start = c.start + rng.integers(-config.span_shift, config.span_shift + 1)
        end = c.end + rng.integers(-config.span_shift, config.span_shift + 1)
        c.start, c.end = int(np.clip(start, 0, last - 1)), int(np.clip(end, 1, last))
        if c.end <= c.start:
            c.end = min(c.start + 1, last)
    return sb


def _wobbly(points: np.ndarray, rng: np.random.Generator, config: ArtistConfig) -> np.ndarray:
    """A stroke redrawn by hand: 8-20 points along it, with a slow sideways wobble."""
    count = int(rng.integers(config.stroke_points[0], config.stroke_points[1] + 1))
    drawn = resample_polyline(points, count)
    s = np.linspace(0.0, 1.0, count)[:, None]
    phase, freq = rng.uniform(0, 2 * np.pi, 2), rng.uniform(1.0, 2.5, 2)
    wobble = config.wobble_m * np.sin(2 * np.pi * freq * s + phase)
    return drawn + wobble

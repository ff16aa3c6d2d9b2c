"""RetrievAdapt: the retrieval baseline (paper, section 4): retrieve the training window whose
motion best matches the storyboard, retime it, align it, and blend it toward the sketch.

Index: fixed-length windows of training clips (the dataset's windowing: `window` frames every
`stride` at `fps`). The features are the windows' 3D entity points (joints, object roots and
object centres) per frame, kept so that they can be projected through *the query's* camera:
a storyboard is compared with each candidate in the sketch plane, after the best ground-plane
yaw and translation of the candidate (a closed-form-per-candidate fit, so the comparison does
not depend on where or which way the training clip happened to move), and, for two people,
under both assignments of agents to people. Time is normalised (window frame = query frame
scaled to the window's length). Cost = weighted mean squared sketch error of keyposes,
trajectory samples, object paths and outline centres + a contact-timing mismatch term +
penalties for a missing or different object.

Adaptation of the nearest window: (1) retime: a piecewise-linear warp through source frames
picked per keyframe by dynamic programming, so keyposes land on their keyframes; (2) refit the
rigid yaw + translation on the retimed clip; (3) blend: image-plane offsets at the retrieved
depth (the sketch target back-projected at the joint's own depth) toward keyposes, the nearest
point of each trajectory stroke, and the object's path and outlines, plus 3D offsets of held
hands onto their anchors, spread in time by smooth fall-off curves (which also denoise); the
whole body follows its pelvis, then each joint its own residual; rotations are re-derived by
IK with the retrieved person's skeleton and the joints re-posed by FK, twice.
"""
from __future__ import annotations

import itertools
import json
import time
from dataclasses import asdict, dataclass, fields
from pathlib import Path
from typing import Generator, Sequence

import numpy as np

from ..atomic import atomic_write
from ..clip import MotionClip
from ..controls import Controls, build_controls
from ..geometry.polylines import closest_on_polyline
from ..geometry.rotations import matrix_to_6d
from ..io.resample import resample_clip
from ..objects import local_to_world
from ..sampling.events import GenerationResult, StepEvent
from ..skeleton import HANDS, JOINT_INDEX, NUM_JOINTS, fit_offsets, forward_kinematics, inverse_kinematics
from ..storyboard import Storyboard
from .adaptation import fit_ground_rigid, keyframe_warp, sample_frames, smooth_offsets, transform_clip

JOINT, OBJECT_ROOT, OBJECT_CENTRE = 0, 1, 2   # kinds of sketch point
_CLIP_FIELDS = tuple(f.name for f in fields(MotionClip))


@dataclass
class IndexConfig:
    window: int = 120          # frames per indexed window; shorter clips are one window
    stride: int = 30
    fps: float = 20.0          # clips are resampled to this rate
    min_frames: int = 20       # shorter clips are not indexed


@dataclass
class AdaptConfig:
    keypose_weight: float = 1.0       # shares of the retrieval cost per kind of sketch point
    trajectory_weight: float = 0.5
    object_weight: float = 0.5
    path_stride: int = 3              # frames between the path samples compared
    contact_weight: float = 0.05      # m^2 per unit of contact-timing mismatch (share of frames)
    missing_object_cost: float = 1.0  # m^2 when the storyboard has an object the window lacks
    object_type_cost: float = 0.05    # m^2 when the window's object is of another type
    yaw_steps: int = 720
    refit_iterations: int = 3         # rigid refits after retiming (path targets re-snapped)
    choose_among: int = 1             # the seed picks among this many nearest windows
    retime: bool = True
    max_stretch: float = 2.0          # retiming never plays a piece faster or slower than this
    blend: bool = True
    falloff_frames: float = 8.0       # how far in time a blended correction reaches
    contact_blend_weight: float = 0.5  # pull of held hands toward their anchors
    blend_iterations: int = 3


@dataclass
class Match:
    window: int                # index into RetrievalIndex.windows
    people: tuple[int, ...]    # window person shown as agent h
    yaw: float                 # radians about +Y ...
    offset: tuple[float, float, float]  # ... and ground translation: x' = R x + offset
    cost: float


@dataclass
class Adapted:
    clip: MotionClip           # the result, N = storyboard.length frames
    match: Match
    source_frames: np.ndarray  # (N,) window frame shown at each output frame (the time warp)


class RetrievalIndex:
    """Windows of training clips with their per-frame entity points (see module docstring)."""

    def __init__(self, clips: list[MotionClip], windows: np.ndarray, config: IndexConfig):
        self.clips = clips
        self.windows = windows            # (W, 3) int: clip, start frame, length
        self.config = config
        self.num_humans = clips[0].num_humans
        self.num_objects = max(c.num_objects for c in clips)
        self.start_frame = np.cumsum([0] + [c.num_frames for c in clips])[:-1]   # (C,)
        self.points = np.concatenate([_entity_points(c, self.num_objects) for c in clips])  # (F, E, 3)
        self.contact = np.concatenate([c.contact if c.contact is not None else
                                       np.zeros((c.num_frames, self.num_humans, 2)) for c in clips]) > 0.5
        self.object_types = [[str(c.obj_type[o]) if c.obj_type is not None else "box"
                              for o in range(c.num_objects)] for c in clips]

    @classmethod
    def build(cls, clips: Sequence[MotionClip], config: IndexConfig = IndexConfig()) -> "RetrievalIndex":
        """Index clips (e.g. StoryboardWindows(...).clips or MotionClip.load of the training
        split). All must have the same number of people."""
        kept, windows = [], []
        for clip in clips:
            clip = resample_clip(clip, config.fps)
            if clip.num_frames < config.min_frames:
                continue
            length = min(config.window, clip.num_frames)
            starts = list(range(0, clip.num_frames - length + 1, config.stride))
            if starts[-1] != clip.num_frames - length:  # the tail gets a window of its own
                starts.append(clip.num_frames - length)
            windows += [(len(kept), s, length) for s in starts]
            kept.append(clip)
        if not kept:
            raise ValueError(f"no clip has the {config.min_frames} frames the index needs")
        if len({c.num_humans for c in kept}) > 1:
            raise ValueError("all indexed clips must have the same number of people")
        return cls(kept, np.array(windows, dtype=np.int64), config)

    def save(self, path: str | Path) -> None:
        arrays = {"config": np.str_(json.dumps(asdict(self.config))), "windows": self.windows,
                  "num_clips": np.int64(len(self.clips))}
        for i, clip in enumerate(self.clips):
            for name in _CLIP_FIELDS:
                value = getattr(clip, name)
                if value is not None:
                    arrays[f"clip{i}:{name}"] = np.asarray(value)
        with atomic_write(path) as f:
            np.savez_compressed(f, **arrays)

    @classmethod
    def load(cls, path: str | Path) -> "RetrievalIndex":
        with np.load(path, allow_pickle=False) as z:
            config = IndexConfig(**json.loads(str(z["config"])))
            clips = []
            for i in range(int(z["num_clips"])):
                kw = {name: z[f"clip{i}:{name}"] for name in _CLIP_FIELDS if f"clip{i}:{name}" in z.files}
                kw["fps"], kw["scenario"] = float(kw["fps"]), str(kw.get("scenario", ""))
                clips.append(MotionClip(**kw))
            return cls(clips, z["windows"], config)

    def window_clip(self, window: int) -> MotionClip:
        clip, start, length = (int(v) for v in self.windows[window])
        return self.clips[clip].slice(start, start + length)


def _entity_points(clip: MotionClip, num_objects: int) -> np.ndarray:
    """(N, H * 22 + 2 * num_objects, 3): joints, then object roots, then object box centres
    (zeros for object slots the clip does not fill)."""
    n = clip.num_frames
    roots, centres = np.zeros((n, num_objects, 3)), np.zeros((n, num_objects, 3))
    for o in range(clip.num_objects):
        height = float(clip.obj_size[o][1]) if clip.obj_size is not None else 0.0
        pose = clip.obj_pose[:, o].astype(float)
        roots[:, o] = pose[:, :3]
        centres[:, o] = local_to_world(np.array([[0.0, height / 2, 0.0]]), pose)[:, 0]
    return np.concatenate([clip.joints.reshape(n, -1, 3), roots, centres], axis=1).astype(np.float32)


# ---- the query's sketch points ------------------------------------------------------------------

@dataclass
class _SketchPoints:
    frame: np.ndarray    # (P,) storyboard frame
    kind: np.ndarray     # (P,) JOINT / OBJECT_ROOT / OBJECT_CENTRE
    who: np.ndarray      # (P,) agent or object index
    joint: np.ndarray    # (P,) joint index (0 for objects)
    uv: np.ndarray       # (P, 2) sketch target
    weight: np.ndarray   # (P,) sums to 1
    keypose: np.ndarray  # (P,) bool: from a keypose or an object outline (a keyframe point)

    def entities(self, people: tuple[int, ...], num_humans: int, num_objects: int) -> np.ndarray:
        """(P,) column of RetrievalIndex.points for each point with agents shown by `people`;
        -1 for an object slot the index does not have."""
        person = np.asarray(people)[np.where(self.kind == JOINT, self.who, 0)]
        base = num_humans * NUM_JOINTS + np.where(self.kind == OBJECT_CENTRE, num_objects, 0)
        column = np.where(self.kind == JOINT, person * NUM_JOINTS + self.joint, base + self.who)
        return np.where((self.kind != JOINT) & (self.who >= num_objects), -1, column)


def _sketch_points(c: Controls, config: AdaptConfig) -> _SketchPoints:
    # Paths are sampled every `path_stride` frames: dense samples cost time and add little.
    sampled = (np.arange(len(c.kp_mask)) % config.path_stride == 0)
    groups = []  # (frame, kind, who, joint, uv, share, keypose)
    for mask, uv, weight, is_key in ((c.kp_mask, c.kp2d, config.keypose_weight, True),
                                     (c.tr_mask & sampled[:, None, None], c.tr2d, config.trajectory_weight, False)):
        f, h, j = np.nonzero(mask)
        groups.append((f, np.full(len(f), JOINT), h, j, uv[f, h, j], weight, is_key))
    for mask, uv, kind, is_key in ((c.objpath_mask & sampled[:, None], c.objpath2d, OBJECT_ROOT, False),
                                   (c.obj_mask, c.obj2d[..., :2], OBJECT_CENTRE, True)):
        f, o = np.nonzero(mask)
        groups.append((f, np.full(len(f), kind), o, np.zeros(len(f), int), uv[f, o], config.object_weight, is_key))
    groups = [g for g in groups if len(g[0]) and g[5] > 0]
    if not groups:
        raise ValueError("the storyboard has no keypose, trajectory or object stroke to retrieve by")
    total = sum(g[5] for g in groups)
    weight = np.concatenate([np.full(len(g[0]), g[5] / total / len(g[0])) for g in groups])
    return _SketchPoints(*(np.concatenate([g[i] for g in groups]) for i in range(5)), weight,
                         np.concatenate([np.full(len(g[0]), g[6]) for g in groups]))


def _assignments(num_humans: int) -> list[tuple[int, ...]]:
    """Ways to show the window's people as the storyboard's agents (all of them up to 3)."""
    if num_humans <= 3:
        return list(itertools.permutations(range(num_humans)))
    return [tuple(range(num_humans))]


# ---- retrieval ----------------------------------------------------------------------------------

def retrieve(index: RetrievalIndex, storyboard: Storyboard, config: AdaptConfig = AdaptConfig(),
             seed: int = 0, chunk: int = 1024) -> Match:
    """The nearest window under the storyboard's camera (see the module docstring)."""
    if len(storyboard.agents) != index.num_humans:
        raise ValueError(f"the storyboard has {len(storyboard.agents)} agents, the index clips "
                         f"{index.num_humans} people")
    c = build_controls(storyboard)
    sketch = _sketch_points(c, config)
    n = storyboard.length
    windows = index.windows
    # Window frame shown at each storyboard frame under uniform timing: (W, N).
    scale = (windows[:, 2:3] - 1) / max(n - 1, 1)
    frame_of = index.start_frame[windows[:, 0]][:, None] + windows[:, 1:2] + np.rint(np.arange(n) * scale).astype(int)

    objects_in = np.array([len(index.object_types[clip]) for clip in windows[:, 0]])   # (W,)
    penalty = np.zeros(len(windows))
    for o, obj in enumerate(storyboard.objects):
        for w, (clip, _, _) in enumerate(windows):
            types = index.object_types[clip]
            if o >= len(types):
                penalty[w] += config.missing_object_cost
            elif types[o] != obj.spec.type:
                penalty[w] += config.object_type_cost

    costs, results = [], []
    for people in _assignments(index.num_humans):
        columns = sketch.entities(people, index.num_humans, index.num_objects)
        for lo in range(0, len(windows), chunk):
            rows = slice(lo, lo + chunk)
            frames = frame_of[rows][:, sketch.frame]                                   # (w, P)
            points = index.points[frames, np.maximum(columns, 0)].astype(float)        # (w, P, 3)
            present = (columns >= 0) & ((sketch.kind == JOINT) | (sketch.who < objects_in[rows, None]))
            weights = sketch.weight * present
            weights /= np.maximum(weights.sum(axis=1, keepdims=True), 1e-12)
            yaw, offset, residual = fit_ground_rigid(points, weights, sketch.uv, storyboard.camera, config.yaw_steps)
            labels = index.contact[frame_of[rows]][:, :, list(people)]                 # (w, N, H, 2)
            mismatch = np.mean(labels != c.contact[None], axis=(1, 2, 3))
            costs.append(residual + config.contact_weight * mismatch + penalty[rows])
            results += [(lo + i, people, yaw[i], offset[i]) for i in range(len(yaw))]
    cost = np.concatenate(costs)
    order = np.argsort(cost, kind="stable")[:max(config.choose_among, 1)]
    pick = order[np.random.default_rng(seed).integers(len(order))] if len(order) > 1 else order[0]
    w, people, yaw, offset = results[pick]
    return Match(int(w), tuple(int(p) for p in people), float(yaw), tuple(float(v) for v in offset), float(cost[pick]))


# ---- adaptation ---------------------------------------------------------------------------------

def adapt(index: RetrievalIndex, match: Match, storyboard: Storyboard,
          config: AdaptConfig = AdaptConfig()) -> Adapted:
    """Retime, realign and blend the matched window toward the storyboard (module docstring)."""
    c = build_controls(storyboard)
    sketch = _sketch_points(c, config)
    source = _reorder_people(index.window_clip(match.window), match.people)
    aligned = transform_clip(source, match.yaw, np.asarray(match.offset))
    n, length = storyboard.length, source.num_frames
    camera = storyboard.camera
    columns = sketch.entities(tuple(range(index.num_humans)), index.num_humans, index.num_objects)
    usable = columns >= 0
    if config.retime:
        points = _entity_points(aligned, index.num_objects).astype(float)              # (L, E, 3)
        keys = np.unique(sketch.frame[sketch.keypose & usable])
        errors = np.zeros((len(keys), length))
        for k, q in enumerate(keys):
            at = sketch.keypose & usable & (sketch.frame == q)
            err = np.sum((camera.project(points[:, columns[at]]) - sketch.uv[at]) ** 2, axis=-1)  # (L, P_k)
            errors[k] = err @ sketch.weight[at] / sketch.weight[at].sum()
        times = keyframe_warp(errors, keys, n, length, config.max_stretch)
    else:
        times = np.linspace(0.0, length - 1, n)
    clip = sample_frames(aligned, times, fps=storyboard.fps)

    # Rigid refit now that the timing matches the storyboard. Path samples are spaced by arc
    # length, not by time, so they are re-targeted to the nearest point of their path (ICP).
    weights = sketch.weight[usable] / sketch.weight[usable].sum()
    targets = sketch.uv[usable]
    for _ in range(config.refit_iterations):
        points = _entity_points(clip, index.num_objects).astype(float)[sketch.frame[usable], columns[usable]]
        yaw, offset, _ = fit_ground_rigid(points[None], weights[None], targets, camera, config.yaw_steps)
        clip = transform_clip(clip, yaw[0], offset[0])
        points = _entity_points(clip, index.num_objects).astype(float)[sketch.frame[usable], columns[usable]]
        targets = _nearest_on_paths(sketch, usable, camera.project(points))
    offsets = _skeletons(source)
    if config.blend:
        clip = _blend_object(clip, c, storyboard, config)
        for _ in range(config.blend_iterations):
            clip = _blend_people(clip, c, storyboard, offsets, config)
    else:
        clip = _posed(clip, clip.joints, offsets)
    if clip.phase is None:
        clip.phase = np.full((n, 3), 1.0 / 3.0, np.float32)
    return Adapted(clip, match, times)


def retrieve_adapt(index: RetrievalIndex, storyboard: Storyboard, seed: int = 0,
                   config: AdaptConfig = AdaptConfig()) -> MotionClip:
    """RetrievAdapt in one call: storyboard -> a MotionClip of storyboard.length frames."""
    return adapt(index, retrieve(index, storyboard, config, seed), storyboard, config).clip


DEFAULT_DATA = Path(__file__).resolve().parents[2] / "data"
LIBRARY_SEEDS = range(100, 160)   # synth split bucket 100-159: training seeds, never the test split's


def default_index(data_dir: Path = DEFAULT_DATA, clips: int = 60) -> tuple["RetrievalIndex", str]:
    """RetrievAdapt's library when no index file is given: the first `clips` training-split clips
    of data_dir/synth, or the same number of scenes synthesized afresh with training seeds (a
    fresh clone has no data/). Never the test split. Returns the index and a line saying which."""
    from ..dataset import split_files
    from ..synth import SCENARIOS, synthesize
    synth_dir = Path(data_dir) / "synth"
    if synth_dir.is_dir() and any(synth_dir.glob("*.npz")):
        library = [MotionClip.load(p) for p in split_files(synth_dir).train[:clips]]
        source = f"{len(library)} training-split clips of {synth_dir}"
    else:
        library = [synthesize(SCENARIOS[s % len(SCENARIOS)], s) for s in LIBRARY_SEEDS[:clips]]
        source = f"{len(library)} scenes synthesized with training seeds {LIBRARY_SEEDS.start}+"
    return RetrievalIndex.build(library), source


def sample_retrieval(index: RetrievalIndex, storyboard: Storyboard, config: AdaptConfig = AdaptConfig(),
                     seed: int = 0) -> Generator[StepEvent, None, GenerationResult]:
    """The sampler's streaming contract for RetrievAdapt: one StepEvent (the finished motion,
    its phase labels or a uniform occupancy, the retrieval cost), then the GenerationResult.
    There is no latent: the event's latent is an empty (1, 0, V, 0) array."""
    start = time.perf_counter()
    adapted = adapt(index, retrieve(index, storyboard, config, seed), storyboard, config)
    elapsed = time.perf_counter() - start
    clip = adapted.clip
    entities = clip.num_humans + clip.num_objects
    yield StepEvent(step=0, num_steps=1, t=0.0, latent=np.zeros((1, 0, entities, 0), np.float32),
                    decode=lambda: clip, phase=np.asarray(clip.phase), energies={"retrieval_cost": adapted.match.cost})
    return GenerationResult(clips=[clip], wall_time_s=elapsed, first_step_s=elapsed, network_evals=0)


def _nearest_on_paths(sketch: _SketchPoints, usable: np.ndarray, projected: np.ndarray) -> np.ndarray:
    """Targets (P', 2) for the usable points: keyframe points keep theirs, each path sample
    moves to the nearest point of its path (the polyline of that path's samples in frame order).
    projected: (P', 2) where the usable points are now."""
    uv, is_key = sketch.uv[usable].copy(), sketch.keypose[usable]
    track = np.stack([sketch.kind, sketch.who, sketch.joint], axis=1)[usable]
    for key in np.unique(track[~is_key], axis=0):
        on = ~is_key & np.all(track == key, axis=1)
        path = uv[on][np.argsort(sketch.frame[usable][on], kind="stable")]
        uv[on] = closest_on_polyline(projected[on], path)
    return uv


def _reorder_people(clip: MotionClip, people: tuple[int, ...]) -> MotionClip:
    order = list(people)
    kw = {f: getattr(clip, f) for f in _CLIP_FIELDS}
    for name in ("joints", "rot6d", "contact"):
        if kw[name] is not None:
            kw[name] = kw[name][:, order]
    if clip.bone_offsets is not None:
        kw["bone_offsets"] = clip.bone_offsets[order]
    return MotionClip(**kw)


def _skeletons(clip: MotionClip) -> np.ndarray:
    """(H, 22, 3) the retrieved people's own bone offsets (fitted when the clip has none)."""
    if clip.bone_offsets is not None:
        return np.asarray(clip.bone_offsets, float)
    return np.stack([fit_offsets(clip.joints[:, h].astype(float)) for h in range(clip.num_humans)])


def _posed(clip: MotionClip, joints: np.ndarray, offsets: np.ndarray) -> MotionClip:
    """The clip with rotations solved by IK for `joints` (N, H, 22, 3) and joints re-posed by FK,
    so that joints, rotations and bone lengths agree."""
    rot = np.stack([inverse_kinematics(joints[:, h], offsets[h]) for h in range(joints.shape[1])], axis=1)
    posed = np.stack([forward_kinematics(joints[:, h, 0], rot[:, h], offsets[h]) for h in range(joints.shape[1])], 1)
    kw = {f: getattr(clip, f) for f in _CLIP_FIELDS}
    kw.update(joints=posed, rot6d=matrix_to_6d(rot), bone_offsets=offsets)
    return MotionClip(**kw)


def _in_plane(storyboard: Storyboard, target_uv: np.ndarray, points: np.ndarray) -> np.ndarray:
    """3D offsets (..., 3) moving world points (..., 3) onto sketch targets (..., 2) within the
    image plane, i.e. onto the targets back-projected at the points' own depth."""
    return (target_uv - storyboard.camera.project(points)) @ storyboard.camera.basis()[:2]


def _blend_object(clip: MotionClip, c: Controls, storyboard: Storyboard, config: AdaptConfig) -> MotionClip:
    if clip.num_objects == 0 or not storyboard.objects:
        return clip
    n, count = clip.num_frames, min(clip.num_objects, len(storyboard.objects))
    pose = clip.obj_pose.astype(float)
    root = pose[:, :count, :3]
    centre = _entity_points(clip, clip.num_objects)[:, clip.num_humans * NUM_JOINTS + clip.num_objects:][:, :count]
    target, weight = np.zeros((n, count, 3)), np.zeros((n, count))
    for path in storyboard.object_paths:
        o = storyboard.object_index(path.object)
        if o < count:
            span = slice(path.start, path.end + 1)
            uv = closest_on_polyline(storyboard.camera.project(root[span, o]), path.points)
            target[span, o], weight[span, o] = _in_plane(storyboard, uv, root[span, o]), 1.0
    keyed = c.obj_mask[:, :count]
    target[keyed] = _in_plane(storyboard, c.obj2d[:, :count, :2][keyed], centre[keyed])
    weight[keyed] = 1.0
    shift = smooth_offsets(target, weight, config.falloff_frames)                  # (N, count, 3)
    kw = {f: getattr(clip, f) for f in _CLIP_FIELDS}
    pose[:, :count, :3] += shift
    kw["obj_pose"] = pose
    if clip.obj_anchors is not None:
        anchors = clip.obj_anchors.astype(float).copy()
        anchors[:, :count] += shift[:, :, None]
        kw["obj_anchors"] = anchors
    return MotionClip(**kw)


def _body_targets(clip: MotionClip, c: Controls, storyboard: Storyboard,
                  config: AdaptConfig) -> tuple[np.ndarray, np.ndarray]:
    """Wanted 3D offsets (N, H, 22, 3) and their weights (N, H, 22) for every constrained joint."""
    joints = clip.joints.astype(float)
    n, h = joints.shape[:2]
    target, weight = np.zeros((n, h, NUM_JOINTS, 3)), np.zeros((n, h, NUM_JOINTS))
    for stroke in storyboard.trajectories:
        a, j = storyboard.agent_index(stroke.agent), JOINT_INDEX[stroke.joint]
        span = slice(stroke.start, stroke.end + 1)
        uv = closest_on_polyline(storyboard.camera.project(joints[span, a, j]), stroke.points)
        target[span, a, j], weight[span, a, j] = _in_plane(storyboard, uv, joints[span, a, j]), 1.0
    key = c.kp_mask
    target[key], weight[key] = _in_plane(storyboard, c.kp2d[key], joints[key]), 1.0
    held = c.contact_anchor >= 0                                                   # (N, H, 2)
    if held.any() and clip.obj_anchors is not None:
        k_max = max(len(o.spec.anchors) for o in storyboard.objects)
        anchors = np.asarray(clip.obj_anchors, float)
        f, a, side = np.nonzero(held)
        o, k = np.divmod(c.contact_anchor[f, a, side], k_max)
        ok = (o < anchors.shape[1]) & (k < anchors.shape[2])
        f, a, side, o, k = f[ok], a[ok], side[ok], o[ok], k[ok]
        wrist = np.asarray(HANDS)[side]
        target[f, a, wrist] = anchors[f, o, k] - joints[f, a, wrist]
        weight[f, a, wrist] = config.contact_blend_weight
    return target, weight


def _blend_people(clip: MotionClip, c: Controls, storyboard: Storyboard, offsets: np.ndarray,
                  config: AdaptConfig) -> MotionClip:
    """One pass: the whole body follows the pelvis correction, each joint then its residual;
    IK + FK restore the skeleton."""
    pelvis = JOINT_INDEX["pelvis"]
    target, weight = _body_targets(clip, c, storyboard, config)
    body_shift = smooth_offsets(target[:, :, pelvis], weight[:, :, pelvis], config.falloff_frames)  # (N, H, 3)
    joints = clip.joints.astype(float) + body_shift[:, :, None]
    target = target - body_shift[:, :, None]
    n, h = weight.shape[:2]
    shift = smooth_offsets(target.reshape(n, h * NUM_JOINTS, 3), weight.reshape(n, -1), config.falloff_frames)
    joints = joints + shift.reshape(n, h, NUM_JOINTS, 3)
    return _posed(clip, joints, offsets)

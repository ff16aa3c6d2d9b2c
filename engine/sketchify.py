"""Storyboard synthesis: draw a storyboard from a 3D clip the way an artist would.

The clip is seen through a storyboard camera (Sketch2Anim ranges), keyframes are picked at
motion-salient frames, and every human, object and contact becomes the storyboard element the
artist would sketch for it: keyposes, joint paths, object outlines and paths, contact spans.
`noise` in [0, 0.8] makes strokes hand-like (wobble, over- and under-shoot at the ends,
uneven point spacing, jittered joints); at 0 every point is an exact projection.

Randomness comes only from `seed`, in three independent streams (camera, choices, stroke
noise), so for one seed the choices stay the same while the noise level changes.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import gaussian_filter1d
from scipy.spatial import ConvexHull

from .camera import StoryboardCamera
from .clip import MotionClip
from .objects import DEFAULT_SIZES, ObjectSpec, local_to_world, world_to_local
from .skeleton import HANDS as HAND_JOINTS
from .skeleton import JOINT_INDEX, JOINT_NAMES, NUM_JOINTS
from .storyboard import (AGENT_COLORS, HANDS, Agent, Contact, Keypose, ObjectKey, ObjectPath,
                         SceneObject, Storyboard, Trajectory)

PELVIS = JOINT_INDEX["pelvis"]


@dataclass(frozen=True)
class SketchifyConfig:
    # Camera ranges in degrees; the defaults are Sketch2Anim's test-time ranges.
    elevation_range: tuple[float, float] = (15.0, 30.0)
    azimuth_range: tuple[float, float] = (30.0, 45.0)
    # Keyposes: which joints the artist draws (None = all 22).
    keypose_joints: tuple[str, ...] | None = None
    # Keyframes closer than this share of the even spacing N / K are avoided while others exist.
    keyframe_min_gap: float = 0.5
    # Weight of a contact label change against the (normalised) motion-change peak.
    contact_event_weight: float = 1.0
    # Paths besides the pelvis (always drawn over the whole clip), each drawn with
    # `extra_path_probability` per human over a random span of at least `extra_path_min_span`.
    extra_path_joints: tuple[str, ...] = ("l_wrist", "r_wrist", "head", "l_foot", "r_foot")
    extra_path_probability: float = 0.3
    extra_path_min_span: float = 0.4
    max_stroke_points: int = 48
    # Contact label spans shorter than this many frames are treated as label flicker.
    min_contact_frames: int = 2
    # Hand-drawing perturbation at noise 1 (scaled linearly by noise).
    wobble_m: float = 0.03              # low-frequency wobble amplitude, metres ...
    wobble_per_m: float = 0.03          # ... plus this much per metre of stroke length
    end_shoot: float = 0.12             # over/under-shoot at each end, share of stroke length
    spacing_jitter: float = 0.9         # uneven point spacing, share of the even spacing
    joint_jitter_m: float = 0.04        # independent per-joint keypose error
    figure_offset_m: float = 0.05       # whole keypose misplaced
    figure_scale: float = 0.08          # whole keypose drawn too big or small
    outline_scale: float = 0.10         # object outline drawn too big or small

    @classmethod
    def training(cls, **overrides) -> "SketchifyConfig":
        """Wider camera ranges for training, as Sketch2Anim trains on more views than it tests."""
        overrides.setdefault("elevation_range", (5.0, 60.0))
        overrides.setdefault("azimuth_range", (-180.0, 180.0))
        return cls(**overrides)


def sketchify(clip: MotionClip, keyframes: int = 4, noise: float = 0.0, seed: int = 0,
              camera: StoryboardCamera | None = None,
              config: SketchifyConfig = SketchifyConfig()) -> Storyboard:
    """A storyboard for `clip` with `keyframes` keyframes (0 = paths and contacts only).

    The camera, unless given, is drawn from `seed` within the config's ranges and looks at the
    scene's centre. Agents are named 'A', 'B', ...; objects by their type.
    """
    if not 0.0 <= noise <= 1.0:
        raise ValueError(f"noise must be in [0, 1], got {noise}")
    if keyframes < 0:
        raise ValueError(f"keyframes must be >= 0, got {keyframes}")
    cam_rng, choice_rng, noise_rng = (np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(3))
    specs = _object_specs(clip)
    anchors = _world_anchors(clip, specs)
    if camera is None:
        camera = draw_camera(cam_rng, config, scene_centre(clip))
    n, num_humans = clip.num_frames, clip.num_humans
    agents = [Agent(chr(ord("A") + h), color=AGENT_COLORS[h % len(AGENT_COLORS)]) for h in range(num_humans)]
    objects = [SceneObject(oid, spec) for oid, spec in zip(_object_ids(specs), specs)]
    sb = Storyboard(fps=float(clip.fps), length=n, camera=camera, agents=agents, objects=objects)
    frames = choose_keyframes(clip, keyframes, config)
    joints2d = camera.project(clip.joints)                       # (N, H, 22, 2)

    drawn_joints = config.keypose_joints or JOINT_NAMES
    mask = np.isin(np.arange(NUM_JOINTS), [JOINT_INDEX[j] for j in drawn_joints])
    for f in frames:
        for h, agent in enumerate(agents):
            pts = _hand_keypose(joints2d[f, h], noise, noise_rng, config)
            sb.keyposes.append(Keypose(agent.id, int(f), np.where(mask[:, None], pts, 0.0), mask.copy()))

    for h, agent in enumerate(agents):
        drawn = [j for j in config.extra_path_joints if choice_rng.random() < config.extra_path_probability]
        for name in ["pelvis"] + drawn:
            start, end = (0, n - 1) if name == "pelvis" else _random_span(n, config.extra_path_min_span, choice_rng)
            path = joints2d[start:end + 1, h, JOINT_INDEX[name]]
            sb.trajectories.append(Trajectory(agent.id, name, start, end,
                                              hand_stroke(path, noise, noise_rng, config)))

    for o, obj in enumerate(objects):
        for f in frames:
            outline = _silhouette(obj.spec, clip.obj_pose[f, o], camera)
            sb.object_keys.append(ObjectKey(obj.id, int(f), _hand_outline(outline, noise, noise_rng, config)))
        root2d = camera.project(clip.obj_pose[:, o, :3])
        sb.object_paths.append(ObjectPath(obj.id, 0, n - 1, hand_stroke(root2d, noise, noise_rng, config)))

    sb.contacts = contacts_from_labels(clip, anchors, agents, objects, config.min_contact_frames)
    sb.validate()
    return sb


# ---- camera and keyframes --------------------------------------------------------------------

def scene_centre(clip: MotionClip) -> tuple[float, float, float]:
    """Mean of the entities' mean positions (each human's joints, each object's box centre)."""
    centres = list(clip.joints.mean(axis=(0, 2)))
    for o, spec in enumerate(_object_specs(clip)):
        centres.append(clip.obj_pose[:, o, :3].mean(axis=0) + (0.0, spec.size[1] / 2, 0.0))
    return tuple(float(x) for x in np.mean(centres, axis=0))


def draw_camera(rng: np.random.Generator, config: SketchifyConfig,
                target: tuple[float, float, float]) -> StoryboardCamera:
    return StoryboardCamera(float(rng.uniform(*config.elevation_range)),
                            float(rng.uniform(*config.azimuth_range)), target)


def motion_salience(clip: MotionClip, contact_event_weight: float = 1.0) -> np.ndarray:
    """(N,) how much happens at each frame: peaks of joint and object acceleration (starts,
    stops, turns, the extrema of velocity) and changes of the contact labels."""
    pos = clip.joints.reshape(clip.num_frames, -1, 3)
    if clip.num_objects:
        pos = np.concatenate([pos, clip.obj_pose[:, :, :3]], axis=1)
    accel = np.zeros(clip.num_frames)
    if clip.num_frames >= 3:
        accel[1:-1] = np.linalg.norm(pos[2:] - 2 * pos[1:-1] + pos[:-2], axis=-1).mean(axis=1)
    score = gaussian_filter1d(accel, 2.0, mode="nearest")
    score /= max(score.max(), 1e-9)
    if clip.contact is not None and contact_event_weight > 0:
        labels = clip.contact.reshape(clip.num_frames, -1) > 0.5
        events = np.zeros(clip.num_frames)
        events[1:] = np.any(labels[1:] != labels[:-1], axis=1)
        score += contact_event_weight * np.minimum(gaussian_filter1d(events, 1.0, mode="constant") * 2.5, 1.0)
    return score


def choose_keyframes(clip: MotionClip, count: int, config: SketchifyConfig = SketchifyConfig()) -> np.ndarray:
    """`count` sorted, distinct frames: the first and the last, then the most salient frames
    that keep a minimum gap to those already chosen (the farthest frame once none is left)."""
    n = clip.num_frames
    count = min(count, n)
    chosen = [0, n - 1][:count]
    score = motion_salience(clip, config.contact_event_weight)
    gap = config.keyframe_min_gap * n / max(count, 1)
    frames = np.arange(n)
    while len(chosen) < count:
        dist = np.min(np.abs(frames[:, None] - np.array(chosen)[None, :]), axis=1)
        allowed = dist >= gap
        chosen.append(int(np.argmax(np.where(allowed, score, -np.inf))) if allowed.any() else int(np.argmax(dist)))
    return np.array(sorted(chosen), dtype=int)


def _random_span(n: int, min_share: float, rng: np.random.Generator) -> tuple[int, int]:
    length = int(rng.integers(max(2, int(np.ceil(min_share * n))), n + 1))
    start = int(rng.integers(0, n - length + 1))
    return start, start + length - 1


# ---- objects and contacts ---------------------------------------------------------------------

def _object_specs(clip: MotionClip) -> list[ObjectSpec]:
    specs = []
    for o in range(clip.num_objects):
        kind = str(clip.obj_type[o]) if clip.obj_type is not None else "box"
        size = tuple(clip.obj_size[o]) if clip.obj_size is not None else DEFAULT_SIZES[kind]
        local = None
        if clip.obj_anchors is not None:  # the clip's own grasp points, in the object's frame
            local = world_to_local(clip.obj_anchors[0, o].astype(float), clip.obj_pose[0, o].astype(float))
        specs.append(ObjectSpec(kind, size, local))
    return specs


def _object_ids(specs: list[ObjectSpec]) -> list[str]:
    ids = []
    for spec in specs:
        same = sum(s.type == spec.type for s in specs[:len(ids)])
        ids.append(spec.type if same == 0 else f"{spec.type}_{same + 1}")
    return ids


def _world_anchors(clip: MotionClip, specs: list[ObjectSpec]) -> list[np.ndarray]:
    """Per object (N, K, 3) world anchors: the clip's, else the spec's carried by the pose."""
    if clip.obj_anchors is not None:
        return [clip.obj_anchors[:, o] for o in range(clip.num_objects)]
    return [local_to_world(spec.anchors[None], clip.obj_pose[:, o].astype(float)) for o, spec in enumerate(specs)]


def _silhouette(spec: ObjectSpec, pose: np.ndarray, camera: StoryboardCamera) -> np.ndarray:
    """Convex hull (V, 2), counter-clockwise, of the object's bounding shape at `pose` (7,)."""
    w, h, d = spec.size
    if spec.type == "canister":
        a = np.linspace(0, 2 * np.pi, 16, endpoint=False)
        r = min(w, d) / 2
        ring = np.stack([r * np.cos(a), np.zeros_like(a), r * np.sin(a)], axis=1)
        local = np.concatenate([ring, ring + (0.0, h, 0.0)])
    else:
        corners = np.array(np.meshgrid([-0.5, 0.5], [0.0, 1.0], [-0.5, 0.5], indexing="ij")).reshape(3, -1).T
        local = corners * (w, h, d)
    pts = camera.project(local_to_world(local, np.asarray(pose, float)))
    return pts[ConvexHull(pts).vertices]


def contacts_from_labels(clip: MotionClip, anchors: list[np.ndarray], agents: list[Agent],
                         objects: list[SceneObject], min_frames: int = 2) -> list[Contact]:
    """One Contact per contiguous labelled span of a hand (clip.contact (N, H, 2) > 0.5),
    holding whichever is nearest over the span: an object anchor or another person's hand."""
    if clip.contact is None:
        return []
    out = []
    labels = clip.contact > 0.5
    padded = np.concatenate([np.zeros((1,) + labels.shape[1:], bool), labels,
                             np.zeros((1,) + labels.shape[1:], bool)])
    for h in range(clip.num_humans):
        for side in range(2):
            edges = np.flatnonzero(np.diff(padded[:, h, side].astype(np.int8)))
            for start, stop in zip(edges[0::2], edges[1::2]):
                if stop - start < min_frames:
                    continue
                contact = _nearest_holder(clip, anchors, h, side, start, stop)
                if contact is None:
                    continue
                kind, i, k = contact
                c = Contact(agents[h].id, HANDS[side], int(start), int(stop - 1))
                if kind == "object":
                    c.object, c.anchor = objects[i].id, k
                else:
                    c.other_agent, c.other_hand = agents[i].id, HANDS[k]
                out.append(c)
    return out


def _nearest_holder(clip, anchors, h, side, start, stop):
    """('object', o, anchor) or ('hand', human, side) nearest to the hand over [start, stop)."""
    hand = clip.joints[start:stop, h, HAND_JOINTS[side]]                    # (L, 3)
    best, best_dist = None, np.inf
    for o, a in enumerate(anchors):
        dist = np.linalg.norm(a[start:stop] - hand[:, None], axis=-1).mean(axis=0)  # (K,)
        if dist.min() < best_dist:
            best, best_dist = ("object", o, int(np.argmin(dist))), dist.min()
    for other in range(clip.num_humans):
        if other == h:
            continue
        dist = np.linalg.norm(clip.joints[start:stop, other][:, list(HAND_JOINTS)] - hand[:, None], axis=-1).mean(axis=0)
        if dist.min() < best_dist:
            best, best_dist = ("hand", other, int(np.argmin(dist))), dist.min()
    return best


# ---- hand-drawing perturbation ----------------------------------------------------------------

def hand_stroke(path: np.ndarray, noise: float, rng: np.random.Generator,
                config: SketchifyConfig = SketchifyConfig()) -> np.ndarray:
    """An exact 2D path (M, 2), one point per frame, -> a stroke (L, 2) as a hand draws it.

    At noise 0 the points are evenly spaced in arc length on the path (ends included).
    The random draws do not depend on `noise`, so one rng state gives errors that scale with it.
    """
    path = np.asarray(path, float)
    count = int(np.clip(len(path), 2, config.max_stroke_points))
    seg = np.linalg.norm(np.diff(path, axis=0), axis=-1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    length = s[-1]
    shoot = rng.uniform(-1.0, 1.0, 2)
    spacing = rng.uniform(-0.5, 0.5, count)
    wobble = _wobble(rng, count, closed=False)
    if length < 1e-9:  # a joint that never moves: a dot, drawn as two points
        return np.repeat(path[:1], count, axis=0) + noise * config.wobble_m * wobble
    # Over- (negative start, end past the path) and under-shoot (the stroke stops short).
    lo = -noise * config.end_shoot * shoot[0] * length
    hi = length * (1.0 + noise * config.end_shoot * shoot[1])
    t = np.linspace(0.0, 1.0, count)
    t[1:-1] += noise * config.spacing_jitter * spacing[1:-1] / (count - 1)
    where = lo + np.sort(t) * (hi - lo)
    points = np.stack([np.interp(where, s, path[:, d]) for d in range(2)], axis=-1)
    # Past the ends, continue along the end tangents.
    start_dir, end_dir = _end_directions(path, s)
    points += np.minimum(where, 0.0)[:, None] * start_dir + np.maximum(where - length, 0.0)[:, None] * end_dir
    amplitude = noise * (config.wobble_m + config.wobble_per_m * length)
    return points + amplitude * wobble


def _end_directions(path: np.ndarray, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit tangents at the start and end, over the first and last tenth of the path."""
    reach = 0.1 * s[-1]
    a = np.array([np.interp(reach, s, path[:, d]) for d in range(2)]) - path[0]
    b = path[-1] - np.array([np.interp(s[-1] - reach, s, path[:, d]) for d in range(2)])
    return a / max(np.linalg.norm(a), 1e-12), b / max(np.linalg.norm(b), 1e-12)


def _wobble(rng: np.random.Generator, count: int, closed: bool) -> np.ndarray:
    """(count, 2) smooth offsets of unit-ish size: three low harmonics with random phases.
    A closed outline uses whole cycles so its start and end meet."""
    t = np.linspace(0.0, 1.0, count, endpoint=not closed)[:, None, None]
    freq = np.array([1.0, 2.0, 3.0])[None, :, None] if closed else rng.uniform(0.3, 2.5, (1, 3, 1))
    phase = rng.uniform(0, 2 * np.pi, (1, 3, 2))
    weight = rng.normal(0.0, 1.0, (1, 3, 2)) / np.array([1.0, 2.0, 3.0])[None, :, None]
    return np.sum(weight * np.sin(2 * np.pi * freq * t + phase), axis=1) / 1.2


def _hand_keypose(points: np.ndarray, noise: float, rng: np.random.Generator,
                  config: SketchifyConfig) -> np.ndarray:
    """(22, 2) exact projection -> drawn: misplaced and mis-scaled figure plus joint jitter."""
    offset = rng.normal(0.0, 1.0, 2)
    scale = rng.normal(0.0, 1.0)
    jitter = rng.normal(0.0, 1.0, points.shape)
    pelvis = points[PELVIS]
    drawn = pelvis + (points - pelvis) * (1.0 + noise * config.figure_scale * scale)
    return drawn + noise * (config.figure_offset_m * offset + config.joint_jitter_m * jitter)


def _hand_outline(hull: np.ndarray, noise: float, rng: np.random.Generator,
                  config: SketchifyConfig) -> np.ndarray:
    """Convex hull (V, 2) -> a lasso around it: edges subdivided (vertices kept), then the
    same wobble and scaling as strokes."""
    nxt = np.roll(hull, -1, axis=0)
    pieces = np.maximum(np.ceil(np.linalg.norm(nxt - hull, axis=1) / 0.08), 1).astype(int)
    t = np.concatenate([np.arange(p) / p for p in pieces])
    idx = np.repeat(np.arange(len(hull)), pieces)
    outline = hull[idx] + t[:, None] * (nxt[idx] - hull[idx])
    centre = hull.mean(axis=0)
    scale = rng.normal(0.0, 1.0)
    wobble = _wobble(rng, len(outline), closed=True)
    perimeter = float(np.sum(np.linalg.norm(nxt - hull, axis=1)))
    outline = centre + (outline - centre) * (1.0 + noise * config.outline_scale * scale)
    return outline + noise * (config.wobble_m + config.wobble_per_m * perimeter / 4) * wobble

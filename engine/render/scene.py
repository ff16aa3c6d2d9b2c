"""What the renderer draws at one instant: a plain snapshot built from a clip and a storyboard.

The renderer never reads clips or storyboards itself; `scene_from_clip` is the one place that
turns them into a `SceneState`, so the app, the CLI demo and the tests all see the same picture.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..clip import MotionClip
from ..objects import ObjectSpec
from ..skeleton import JOINT_INDEX, NUM_JOINTS, rest_pose
from ..storyboard import AGENT_COLORS, Storyboard

OBJECT_PATH_COLOR = "#8a7a66"


@dataclass
class Polyline:
    points: np.ndarray  # (P, 3) world metres
    color: str          # "#rrggbb"


@dataclass
class PlacedObject:
    spec: ObjectSpec
    pose: np.ndarray  # (7,) xyz + quaternion wxyz


@dataclass
class SceneState:
    people: np.ndarray = field(default_factory=lambda: np.zeros((0, NUM_JOINTS, 3), np.float32))  # (H, 22, 3)
    colors: tuple[str, ...] = AGENT_COLORS   # person h is drawn in colors[h % len(colors)]
    contact: np.ndarray | None = None        # (H, 2) left / right hand in contact (> 0.5 glows)
    objects: list[PlacedObject] = field(default_factory=list)
    ghosts: list[np.ndarray] = field(default_factory=list)         # each (H, 22, 3)
    target_paths: list[Polyline] = field(default_factory=list)     # what the artist asked for
    generated_paths: list[Polyline] = field(default_factory=list)  # what the motion does

    def color(self, person: int) -> str:
        return self.colors[person % len(self.colors)]

    def points(self) -> np.ndarray:
        """(M, 3) what there is to see: joints of people and ghosts, path points, and the corners
        of a box around each object; a unit box's corners if the scene is empty."""
        pts = [np.asarray(self.people, float).reshape(-1, 3)]
        pts += [np.asarray(g, float).reshape(-1, 3) for g in self.ghosts]
        pts += [np.asarray(p.points, float) for p in self.target_paths + self.generated_paths]
        for o in self.objects:
            half = np.asarray(o.spec.size) / 2
            pts.append(_corners(o.pose[:3] - half * [1, 0, 1], o.pose[:3] + half * [1, 2, 1]))
        pts = np.concatenate(pts)
        return pts if len(pts) else _corners(np.array([-0.5, 0.0, -0.5]), np.array([0.5, 1.0, 0.5]))


def _corners(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """(8, 3) corners of the box lo..hi."""
    return np.stack(np.meshgrid(*zip(lo, hi), indexing="ij"), -1).reshape(8, 3)


@dataclass
class SceneOptions:
    ghosts: bool = True           # the clip's bodies at the storyboard's keyframes
    target_paths: bool = True     # storyboard strokes lifted to 3D
    generated_paths: bool = True  # the clip's paths of the joints the storyboard constrains
    path_joints: tuple[str, ...] = ("pelvis",)  # always traced, besides constrained joints


def objects_at(clip: MotionClip, frame: int) -> list[PlacedObject]:
    out = []
    for o in range(clip.num_objects):
        kind = str(clip.obj_type[o]) if clip.obj_type is not None else "box"
        spec = ObjectSpec(kind, tuple(clip.obj_size[o])) if clip.obj_size is not None else ObjectSpec(kind)
        out.append(PlacedObject(spec, np.asarray(clip.obj_pose[frame, o], np.float64)))
    return out


def scene_from_clip(clip: MotionClip | None, frame: int = 0, storyboard: Storyboard | None = None,
                    options: SceneOptions | None = None) -> SceneState:
    """The scene at `frame` (clamped to the clip), with the storyboard's overlays."""
    options = options or SceneOptions()
    colors = tuple(a.color for a in storyboard.agents) if storyboard and storyboard.agents else AGENT_COLORS
    state = SceneState(colors=colors)
    if storyboard is not None and options.target_paths:
        state.target_paths = lift_storyboard_paths(storyboard, clip)
    if clip is None:
        return state
    frame = min(max(int(frame), 0), clip.num_frames - 1)
    state.people = clip.joints[frame]
    state.contact = None if clip.contact is None else clip.contact[frame]
    state.objects = objects_at(clip, frame)
    if storyboard is not None and options.ghosts:
        state.ghosts = [clip.joints[k] for k in storyboard.keyframes() if k < clip.num_frames]
    if options.generated_paths:
        state.generated_paths = generated_paths(clip, storyboard, options.path_joints)
    return state


def generated_paths(clip: MotionClip, storyboard: Storyboard | None,
                    always: tuple[str, ...] = ("pelvis",)) -> list[Polyline]:
    """Whole-clip paths of each person's `always` joints and storyboard-constrained joints,
    and of each object that has a storyboard path."""
    wanted = {(h, JOINT_INDEX[j]) for h in range(clip.num_humans) for j in always}
    colors = AGENT_COLORS
    object_ids = set()
    if storyboard is not None:
        colors = tuple(a.color for a in storyboard.agents) or AGENT_COLORS
        wanted |= {(storyboard.agent_index(t.agent), JOINT_INDEX[t.joint]) for t in storyboard.trajectories}
        object_ids = {storyboard.object_index(p.object) for p in storyboard.object_paths}
    paths = [Polyline(clip.joints[:, h, j], colors[h % len(colors)])
             for h, j in sorted(wanted) if h < clip.num_humans]
    paths += [Polyline(clip.obj_pose[:, o, :3], OBJECT_PATH_COLOR)
              for o in sorted(object_ids) if o < clip.num_objects]
    return paths


def lift_storyboard_paths(storyboard: Storyboard, clip: MotionClip | None = None) -> list[Polyline]:
    """Storyboard strokes as 3D polylines: each sketch point is cast through the storyboard camera
    onto the horizontal plane at the joint's height (its mean height in the clip over the stroke's
    frames, or its rest-pose height without a clip or frames of it there); object paths onto the
    object's height."""
    rest = rest_pose()
    cam = storyboard.camera
    out = []
    for t in storyboard.trajectories:
        h, j = storyboard.agent_index(t.agent), JOINT_INDEX[t.joint]
        heights = clip.joints[t.start:t.end + 1, h, j, 1] if clip is not None and h < clip.num_humans else []
        height = float(np.mean(heights)) if len(heights) else float(rest[j, 1])   # (a clip that ends before it)
        out.append(Polyline(cam.unproject_to_height(t.points, height),
                            storyboard.agents[h].color or AGENT_COLORS[h % len(AGENT_COLORS)]))
    for p in storyboard.object_paths:
        o = storyboard.object_index(p.object)
        heights = clip.obj_pose[p.start:p.end + 1, o, 1] if clip is not None and o < clip.num_objects else []
        height = float(np.mean(heights)) if len(heights) else 0.0
        out.append(Polyline(cam.unproject_to_height(p.points, height), OBJECT_PATH_COLOR))
    return out

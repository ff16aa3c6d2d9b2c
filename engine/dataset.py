"""Training data: fixed-length windows of clips, each with a storyboard drawn from it.

Clips are NPZ files (engine/clip.py): synthesized scenes (two people, one object, phase and
contact labels) and imported real motion capture (two people, no object, no labels). Every
clip is resampled to the dataset's fps once and kept in memory; an item is one window of
`window` frames, canonicalized (entities' mean ground position at the first frame moved to
the origin, then a random yaw about +Y), and sketchified with a random noise level and a random
camera in the wide training ranges. Randomness is seeded by (config.seed, epoch, index), so an
item is the same every time it is read in the same epoch.

Item (a dict of torch tensors; N = window, fixed H = 2 humans, O = 1 object slot, K = 4 anchors):
  joints        (N, 2, 22, 3) float32   world joints, metres, Y up
  rot6d         (N, 2, 22, 6) float32   local rotations (the root's carries the yaw)
  obj_pose      (N, 1, 7)     float32   xyz + quaternion wxyz; zeros when there is no object
  obj_anchors   (N, 1, 4, 3)  float32   world anchors; zeros when there is no object
  obj_present   ()            float32   1 when the clip has an object
  phase         (N, 3)        float32   approach / contact / carry occupancy labels
  contact_label (N, 2, 2)     float32   hand contact labels (named apart from the control
                                        `contact`, which is what the storyboard asks for)
  has_labels    ()            float32   0 for clips without phase and contact labels
  valid         (N,)          float32   1 on real frames, 0 on the held last frame that pads a
                                        clip shorter than the window
  noise         ()            float32   the storyboard's noise level
  and every field of engine.controls.Controls, float32 (masks as 0/1) except contact_anchor
  (int64, -1 = none): kp2d (N,2,22,2), kp_mask (N,2,22), tr2d (N,2,22,2), tr_mask (N,2,22),
  obj2d (N,1,4), obj_mask (N,1), objpath2d (N,1,2), objpath_mask (N,1), contact (N,2,2),
  contact_anchor (N,2,2), camera (3,3), cam_target (3,).
"""
from __future__ import annotations

import re
import zlib
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import Sequence

import numpy as np
import torch
from torch.utils.data import Dataset

from .artist_sketch import redrawn
from .clip import ClipError, MotionClip
from .controls import build_controls
from .geometry.rotations import matrix_to_quat, quat_to_matrix
from .io.resample import resample_clip
from .mirrored import without_mirrored_template
from .models.slots import MODEL_FPS, NUM_HUMANS, fixed_controls
from .objects import NUM_ANCHORS
from .sketchify import SketchifyConfig, sketchify
from .storyboard import Storyboard
from .synth.captions import caption
from .text import tokenize, with_unknown_words

# CMU salsa takes (lead/follow pair) that training never sees. Take 10 is the held-out pair
# because it is the shortest (1197 frames at 120 fps, ~10 s), so holding it out costs the least
# training data (~7% of the frames), it is a complete synchronized pair recorded separately from
# the others, and its only known defect (a tremble in the first seconds) is easy to trim in
# evaluation, while takes 06, 07 and 09 have head or shoe errors that would pollute a test set.
HELD_OUT_SALSA_TAKES = ("60_10/61_10",)


@dataclass
class DatasetConfig:
    window: int = 120                 # frames per item (6 s at 20 fps)
    stride: int = 30                  # frames between window starts within a clip
    fps: float = MODEL_FPS            # clips at another rate are resampled to this
    min_frames: int = 60              # shorter clips are skipped; longer ones below `window` are padded
    keyframe_range: tuple[int, int] = (2, 6)     # keyframes per storyboard, inclusive
    noise_range: tuple[float, float] = (0.0, 0.8)
    random_yaw: bool = True
    sketch: SketchifyConfig = field(default_factory=SketchifyConfig.training)
    artist_share: float = 0.0         # storyboards redrawn the way artists draw (engine.artist_sketch),
                                      # half by hand, half posed with the canvas's tools
    unknown_word_share: float = 0.1   # caption words replaced by ones the text encoder does not know
    sparse_share: float = 0.0         # storyboards cut to their first keyposes (half of them the last
                                      # ones too) and where the objects start: the caption says the rest
    seed: int = 0


@dataclass
class Splits:
    train: list[Path]
    val: list[Path]
    test: list[Path]


def split_files(synth_dir: str | Path | None = None, real_dir: str | Path | None = None,
                val_share: float = 0.05, test_share: float = 0.05,
                held_out_takes: Sequence[str] = HELD_OUT_SALSA_TAKES) -> Splits:
    """Train / val / test lists of clip files.

    Synthesized clips split by their seed (the last integer in the file name, else a hash of the
    name): seed mod 1000 below 1000 * test_share is test, the next 1000 * val_share is val, so a
    clip keeps its split when more are synthesized. Real clips whose file name contains a take
    of a held-out pair (e.g. '60_10' or '61_10') are test; the other real clips train.
    """
    splits = Splits([], [], [])
    for path in sorted(Path(synth_dir).glob("*.npz")) if synth_dir else []:
        bucket = _file_seed(path) % 1000
        if bucket < 1000 * test_share:
            splits.test.append(path)
        elif bucket < 1000 * (test_share + val_share):
            splits.val.append(path)
        else:
            splits.train.append(path)
    held = [take for pair in held_out_takes for take in pair.split("/")]
    for path in sorted(Path(real_dir).glob("*.npz")) if real_dir else []:
        (splits.test if any(take in path.stem for take in held) else splits.train).append(path)
    return splits


def _file_seed(path: Path) -> int:
    numbers = re.findall(r"\d+", path.stem)
    return int(numbers[-1]) if numbers else zlib.crc32(path.stem.encode())


class StoryboardWindows(Dataset):
    """Windows of clips with synthesized storyboards; see the module docstring for the item."""

    def __init__(self, files: Sequence[str | Path], config: DatasetConfig = DatasetConfig()):
        self.config = config
        self.epoch = 0
        self.clips: list[MotionClip] = []
        starts = []
        for path in files:
            clip = _checked(MotionClip.load(path), path)
            clip = resample_clip(clip, config.fps)
            if clip.num_frames < config.min_frames:
                continue
            last = max(clip.num_frames - config.window, 0)
            offsets = list(range(0, last + 1, config.stride))
            if offsets[-1] != last:  # the tail gets a window of its own
                offsets.append(last)
            starts += [(len(self.clips), s) for s in offsets]
            self.clips.append(clip)
        self.windows = np.array(starts, dtype=np.int64).reshape(-1, 2)  # (items, 2): clip, start

    def set_epoch(self, epoch: int) -> None:
        """New noise, cameras and yaws for every item (call before each epoch)."""
        self.epoch = epoch

    def __len__(self) -> int:
        return len(self.windows)

    def __getitem__(self, index: int) -> dict[str, torch.Tensor]:
        cfg = self.config
        rng = np.random.default_rng([cfg.seed, self.epoch, index])
        yaw = rng.uniform(-np.pi, np.pi) if cfg.random_yaw else 0.0
        noise = float(rng.uniform(*cfg.noise_range))
        keyframes = int(rng.integers(cfg.keyframe_range[0], cfg.keyframe_range[1] + 1))
        sketch_seed = int(rng.integers(2**31))

        clip_index, start = self.windows[index]
        clip = self.clips[clip_index]
        window, valid = _window(clip, int(start), cfg.window)
        window = canonicalize(window, yaw)
        storyboard = sketchify(window, keyframes, noise, sketch_seed, config=cfg.sketch)
        if cfg.artist_share > 0 and rng.random() < cfg.artist_share:   # no draw at 0: streams unchanged
            # Mended as a request mends it: the model learns from what it will be given.
            storyboard = without_mirrored_template(redrawn(storyboard, sketch_seed, posed=bool(rng.integers(2))))
        thumbnail = np.random.default_rng([cfg.seed, self.epoch, index, 2])     # its own stream too
        if cfg.sparse_share > 0 and thumbnail.random() < cfg.sparse_share:
            storyboard = sparse(storyboard, with_end=bool(thumbnail.integers(2)))
        controls = build_controls(storyboard)

        item = _motion_arrays(window)
        item["valid"] = valid
        item["noise"] = np.float32(noise)
        item.update(fixed_controls(controls))
        words = np.random.default_rng([cfg.seed, self.epoch, index, 1])   # its own stream: the sketch's stays
        item.update(with_unknown_words(tokenize(caption(window, words)), cfg.unknown_word_share, words))
        return {k: torch.from_numpy(np.asarray(v)) for k, v in item.items()}


def sparse(storyboard: Storyboard, with_end: bool = True) -> Storyboard:
    """Only each person's first keypose (and last, `with_end`) and each object's first key: no
    strokes, no contacts (a quick thumbnail with a sentence under it). With full sketches only,
    a model learns to leave the text aside: the sketch says it all (and with the ends drawn,
    nearly all: fine-tuned on those, the teacher's noise prediction moved by 0.4% for a caption)."""
    ends = {frame for agent in storyboard.agents
            for frame in _first_and_last([k.frame for k in storyboard.keyposes if k.agent == agent.id], with_end)}
    firsts = {o.id: min(k.frame for k in storyboard.object_keys if k.object == o.id)
              for o in storyboard.objects if any(k.object == o.id for k in storyboard.object_keys)}
    return replace(storyboard, keyposes=[k for k in storyboard.keyposes if k.frame in ends],
                   object_keys=[k for k in storyboard.object_keys if firsts.get(k.object) == k.frame],
                   trajectories=[], object_paths=[], contacts=[])


def _first_and_last(frames: list[int], with_last: bool) -> set[int]:
    if not frames:
        return set()
    return {min(frames), max(frames)} if with_last else {min(frames)}


def _checked(clip: MotionClip, path) -> MotionClip:
    if clip.num_humans != NUM_HUMANS:
        raise ClipError(f"{path}: the dataset needs {NUM_HUMANS} humans, the clip has {clip.num_humans}")
    if clip.num_objects > 1:
        raise ClipError(f"{path}: the dataset has one object slot, the clip has {clip.num_objects} objects")
    if clip.num_objects and (clip.obj_anchors is None or clip.obj_anchors.shape[2] != NUM_ANCHORS):
        raise ClipError(f"{path}: the dataset needs {NUM_ANCHORS} anchors per object")
    return clip


def _window(clip: MotionClip, start: int, length: int) -> tuple[MotionClip, np.ndarray]:
    """Frames [start, start + length), holding the last frame when the clip is shorter.
    Returns the window and its valid-frame mask (length,) float32."""
    frames = np.minimum(np.arange(start, start + length), clip.num_frames - 1)
    valid = (np.arange(start, start + length) < clip.num_frames).astype(np.float32)
    kw = {f.name: getattr(clip, f.name) for f in fields(clip)}
    for name in ("joints", "rot6d", "obj_pose", "obj_anchors", "phase", "contact"):
        if kw[name] is not None:
            kw[name] = kw[name][frames]
    return MotionClip(**kw), valid


def _yaw_matrix(yaw: float) -> np.ndarray:
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def canonicalize(clip: MotionClip, yaw: float = 0.0) -> MotionClip:
    """The same motion moved so the entities' (pelvises', object roots') mean ground position
    at the first frame is the origin (heights kept), then turned by `yaw` radians about +Y."""
    ground = [clip.joints[0, :, 0]] + ([clip.obj_pose[0, :, :3]] if clip.num_objects else [])
    shift = np.concatenate(ground).mean(axis=0) * (1.0, 0.0, 1.0)
    R = _yaw_matrix(yaw)
    kw = {f.name: getattr(clip, f.name) for f in fields(clip)}
    kw["joints"] = (clip.joints - shift) @ R.T
    rot6d = clip.rot6d.copy()
    # Only the root's local rotation is global: turn both of its 6D columns.
    rot6d[:, :, 0, :3] = rot6d[:, :, 0, :3] @ R.T
    rot6d[:, :, 0, 3:] = rot6d[:, :, 0, 3:] @ R.T
    kw["rot6d"] = rot6d
    if clip.num_objects:
        pose = clip.obj_pose.astype(float).copy()
        pose[..., :3] = (pose[..., :3] - shift) @ R.T
        pose[..., 3:] = matrix_to_quat(R @ quat_to_matrix(pose[..., 3:]))
        kw["obj_pose"] = pose
        if clip.obj_anchors is not None:
            kw["obj_anchors"] = (clip.obj_anchors - shift) @ R.T
    return MotionClip(**kw)


def _motion_arrays(clip: MotionClip) -> dict[str, np.ndarray]:
    n = clip.num_frames
    present = clip.num_objects == 1
    obj_pose = clip.obj_pose if present else np.zeros((n, 1, 7))
    anchors = clip.obj_anchors if present else np.zeros((n, 1, NUM_ANCHORS, 3))
    labelled = clip.phase is not None and clip.contact is not None
    return {
        "joints": clip.joints.astype(np.float32),
        "rot6d": clip.rot6d.astype(np.float32),
        "obj_pose": np.asarray(obj_pose, np.float32),
        "obj_anchors": np.asarray(anchors, np.float32),
        "obj_present": np.float32(present),
        "phase": np.asarray(clip.phase if labelled else np.zeros((n, 3)), np.float32),
        "contact_label": np.asarray(clip.contact if labelled else np.zeros((n, NUM_HUMANS, 2)), np.float32),
        "has_labels": np.float32(labelled),
    }

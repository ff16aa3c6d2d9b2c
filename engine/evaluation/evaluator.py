"""The frozen motion evaluator behind FID and storyboard-to-motion R-precision (DESIGN.md sec. 4).

In the style of the text-to-motion evaluators of Guo et al. (2022), with the text encoder
replaced by a storyboard encoder: a motion encoder (both people's joints and the object's pose
over a window, canonicalised to the first frame, see features.py) and a storyboard encoder (the
control tensors) map into one 256-d space where matched pairs are close. Both are a linear
frame embedding, two strided temporal convolutions, a bidirectional GRU, a masked mean over
time and a linear head; embeddings are unit vectors, so Euclidean ranking (metrics.r_precision)
is cosine ranking. Trained contrastively by train_evaluator.py on the training split only.

What the benchmark calls (motions: a sequence of MotionClip, or a dict of batched joints
(B,N,2,22,3), obj_pose (B,N,1,7) and optionally obj_present (B,), valid (B,N); controls: a
sequence of Controls or Storyboard, or a dict of batched Controls fields with one object slot):
  load_evaluator(path) -> MotionEvaluator
  motion_embeddings(evaluator, motions) -> (M, D)     story_embeddings(evaluator, controls) -> (M, D)
  fid(evaluator, generated, reference) -> float
  r_precision_top3(evaluator, controls, generated) -> float   (batches of 32)
  embedding_diversity(evaluator, motions) -> float
Give it windows of `config.window` frames (what it was trained on); shorter ones are padded and
masked, longer ones are read whole. FID on unit embeddings is small in absolute terms (at most
4 for the mean term); compare it only between runs of one evaluator version.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, fields
from pathlib import Path
from typing import Any, Sequence

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

from ..atomic import atomic_write
from ..clip import MotionClip
from ..controls import Controls, build_controls
from ..io.resample import resample_clip
from ..metrics import frechet_distance, r_precision
from ..storyboard import Storyboard
from .features import MOTION_FEATURES, NUM_HUMANS, STORY_FEATURES, motion_features, story_features

FILE_FORMAT = "sketch2colab-motion-evaluator"
FILE_VERSION = 1
DEFAULT_PATH = Path(__file__).resolve().parents[2] / "resources" / "evaluator.pt"
MIN_FRAMES = 8              # the two stride-2 convolutions need a few frames to look at
STD_FLOOR = 0.05            # sparse channels (masks, keypose points) would otherwise blow up
R_PRECISION_BATCH = 32
R_PRECISION_TOP_K = 3


class EvaluatorError(ValueError):
    """An evaluator file that cannot be used, or inputs it cannot read."""


@dataclass
class EvaluatorConfig:
    hidden: int = 96           # width of the frame embedding, convolutions and each GRU direction
    embed: int = 256           # embedding width
    window: int = 120          # frames the evaluator is trained on (6 s)
    fps: float = 20.0          # clips at another rate are resampled to this

    @classmethod
    def large(cls) -> "EvaluatorConfig":
        return cls(hidden=256)


class SequenceEncoder(nn.Module):
    """Per-frame features (B, N, F) and valid (B, N) -> unit embeddings (B, embed)."""

    def __init__(self, in_features: int, config: EvaluatorConfig):
        super().__init__()
        h = config.hidden
        # Feature standardisation measured on the training set, saved with the weights.
        self.register_buffer("feature_mean", torch.zeros(in_features))
        self.register_buffer("feature_std", torch.ones(in_features))
        self.frame = nn.Linear(in_features, h)
        self.temporal = nn.Sequential(
            nn.Conv1d(h, h, 4, stride=2, padding=1), nn.LeakyReLU(0.2),
            nn.Conv1d(h, h, 4, stride=2, padding=1), nn.LeakyReLU(0.2))
        self.gru = nn.GRU(h, h, batch_first=True, bidirectional=True)
        self.head = nn.Linear(2 * h, config.embed)

    def forward(self, features: torch.Tensor, valid: torch.Tensor) -> torch.Tensor:
        x = (features - self.feature_mean) / self.feature_std
        x = F.leaky_relu(self.frame(x), 0.2)
        x = self.temporal(x.transpose(1, 2)).transpose(1, 2)                  # (B, ~N/4, h)
        out, _ = self.gru(x)
        # A downsampled step is valid when any frame of its 4-frame stride is.
        mask = F.max_pool1d(valid[:, None].float(), 4, 4, ceil_mode=True)[:, 0, :out.shape[1]]
        pooled = (out * mask[..., None]).sum(1) / mask.sum(1, keepdim=True).clamp_min(1.0)
        return F.normalize(self.head(pooled), dim=-1)


class MotionEvaluator(nn.Module):
    """The two encoders. encode_motion(batch) / encode_story(controls) -> (B, embed) unit vectors."""

    def __init__(self, config: EvaluatorConfig = EvaluatorConfig(), card: dict | None = None):
        super().__init__()
        self.config = config
        self.card = dict(card or {})          # provenance written by the trainer (model card)
        self.motion_encoder = SequenceEncoder(MOTION_FEATURES, config)
        self.story_encoder = SequenceEncoder(STORY_FEATURES, config)

    def encode_motion(self, batch: dict[str, torch.Tensor]) -> torch.Tensor:
        feats = motion_features(batch["joints"], batch["obj_pose"], batch["obj_present"], batch["valid"],
                                self.config.fps)
        return self.motion_encoder(feats, batch["valid"])

    def encode_story(self, controls: dict[str, torch.Tensor]) -> torch.Tensor:
        return self.story_encoder(story_features(controls, controls["valid"]), controls["valid"])

    def num_parameters(self) -> int:
        return sum(p.numel() for p in self.parameters())


# ---- files ------------------------------------------------------------------------------------

def save_evaluator(evaluator: MotionEvaluator, path: str | Path) -> None:
    """Half-precision weights, config and model-card fields in one torch file."""
    state = {k: v.detach().cpu().half() if v.is_floating_point() else v.detach().cpu()
             for k, v in evaluator.state_dict().items()}
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    with atomic_write(path) as f:
        torch.save({"format": FILE_FORMAT, "version": FILE_VERSION, "config": asdict(evaluator.config),
                    "card": evaluator.card, "state": state}, f)


def load_evaluator(path: str | Path = DEFAULT_PATH, device: str | torch.device = "cpu") -> MotionEvaluator:
    """The frozen evaluator in eval mode (float32, no gradients). Raises EvaluatorError with a
    one-line reason for a missing, corrupt or foreign file."""
    path = Path(path)
    if not path.is_file():
        raise EvaluatorError(f"{path}: no motion evaluator there (train one with "
                             f"python -m engine.evaluation.train_evaluator)")
    try:
        blob = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as e:  # pickle, zip and I/O errors all mean "not an evaluator file"
        raise EvaluatorError(f"{path}: not a readable motion evaluator file ({type(e).__name__})") from None
    if not isinstance(blob, dict) or blob.get("format") != FILE_FORMAT:
        raise EvaluatorError(f"{path}: not a motion evaluator file (format tag missing)")
    if blob.get("version") != FILE_VERSION:
        raise EvaluatorError(f"{path}: evaluator file version {blob.get('version')}, this program reads {FILE_VERSION}")
    try:
        known = {f.name for f in fields(EvaluatorConfig)}
        evaluator = MotionEvaluator(EvaluatorConfig(**{k: v for k, v in blob["config"].items() if k in known}),
                                    blob.get("card"))
        evaluator.load_state_dict({k: v.float() if v.is_floating_point() else v for k, v in blob["state"].items()})
    except (KeyError, TypeError, RuntimeError) as e:
        raise EvaluatorError(f"{path}: evaluator weights do not fit the network ({str(e).splitlines()[0]})") from None
    evaluator.eval().requires_grad_(False)
    return evaluator.to(device)


# ---- inputs -----------------------------------------------------------------------------------

def _hold_last(x: np.ndarray, length: int) -> np.ndarray:
    return x[np.minimum(np.arange(length), len(x) - 1)]


def motion_batch(motions: Sequence[MotionClip] | dict[str, Any], fps: float = 20.0) -> dict[str, torch.Tensor]:
    """Clips (resampled to `fps`, padded to the longest by holding the last frame) or a dict of
    batched arrays -> float32 tensors joints (B,N,2,22,3), obj_pose (B,N,1,7), obj_present (B,),
    valid (B,N). A dict without obj_present / valid counts objects as present when their pose is
    nonzero and every frame as valid."""
    if isinstance(motions, dict):
        joints = torch.as_tensor(motions["joints"]).float()
        obj_pose = torch.as_tensor(motions["obj_pose"]).float()
        b, n = joints.shape[:2]
        present = motions.get("obj_present")
        if present is None:
            present = obj_pose.abs().flatten(1).sum(1) > 0
        present = torch.as_tensor(present).float()
        valid = motions.get("valid")
        valid = torch.ones(b, n) if valid is None else torch.as_tensor(valid).float()
        batch = {"joints": joints, "obj_pose": obj_pose, "obj_present": present, "valid": valid}
    else:
        clips = [resample_clip(c, fps) for c in motions]
        if not clips:
            raise EvaluatorError("no motions to embed")
        n = max(c.num_frames for c in clips)
        joints, poses, present, valid = [], [], [], []
        for c in clips:
            if c.num_humans != NUM_HUMANS or c.num_objects > 1:
                raise EvaluatorError(f"the evaluator reads 2 people and at most 1 object, got "
                                     f"{c.num_humans} people and {c.num_objects} objects")
            joints.append(_hold_last(c.joints, n))
            poses.append(_hold_last(c.obj_pose, n) if c.num_objects else np.zeros((n, 1, 7), np.float32))
            present.append(float(c.num_objects == 1))
            valid.append(np.arange(n) < c.num_frames)
        batch = {"joints": torch.from_numpy(np.stack(joints)).float(),
                 "obj_pose": torch.from_numpy(np.stack(poses)).float(),
                 "obj_present": torch.tensor(present), "valid": torch.from_numpy(np.stack(valid)).float()}
    _check_batch(batch["joints"].shape, "motions", (NUM_HUMANS, 22, 3))
    return batch


def story_batch(controls: Sequence[Controls | Storyboard] | dict[str, Any]) -> dict[str, torch.Tensor]:
    """Storyboards or Controls (object axis padded to one slot, frames padded with empty
    controls) or a dict of batched Controls fields -> tensors of those fields plus valid (B, N)."""
    if isinstance(controls, dict):
        batch = {f.name: torch.as_tensor(controls[f.name]) for f in fields(Controls)}
        b, n = batch["kp_mask"].shape[:2]
        valid = controls.get("valid")
        batch["valid"] = torch.ones(b, n) if valid is None else torch.as_tensor(valid).float()
    else:
        items = [build_controls(c) if isinstance(c, Storyboard) else c for c in controls]
        if not items:
            raise EvaluatorError("no storyboards to embed")
        n = max(c.kp_mask.shape[0] for c in items)
        stacked: dict[str, list] = {f.name: [] for f in fields(Controls)}
        valid = []
        for c in items:
            for f in fields(Controls):
                v = np.asarray(getattr(c, f.name))
                if f.name.startswith("obj"):
                    if v.shape[1] > 1:
                        raise EvaluatorError(f"the evaluator reads at most 1 object, the storyboard has {v.shape[1]}")
                    if v.shape[1] == 0:
                        v = np.zeros((v.shape[0], 1) + v.shape[2:], v.dtype)
                if f.name not in ("camera", "cam_target"):
                    pad = np.full((n - len(v),) + v.shape[1:], -1 if f.name == "contact_anchor" else 0, v.dtype)
                    v = np.concatenate([v, pad])
                stacked[f.name].append(v)
            valid.append(np.arange(n) < c.kp_mask.shape[0])
        batch = {k: torch.from_numpy(np.stack(v)) for k, v in stacked.items()}
        batch["valid"] = torch.from_numpy(np.stack(valid)).float()
    _check_batch(batch["kp_mask"].shape, "storyboards", (NUM_HUMANS, 22))
    return batch


def _check_batch(shape: torch.Size, what: str, tail: tuple) -> None:
    if len(shape) != 2 + len(tail) or tuple(shape[2:]) != tail:
        raise EvaluatorError(f"{what}: expected (B, N, {', '.join(map(str, tail))}), got {tuple(shape)}")
    if shape[1] < MIN_FRAMES:
        raise EvaluatorError(f"{what}: the evaluator needs at least {MIN_FRAMES} frames, got {shape[1]}")


def _slice(batch: dict[str, torch.Tensor], start: int, stop: int, device) -> dict[str, torch.Tensor]:
    return {k: v[start:stop].to(device) for k, v in batch.items()}


# ---- what the benchmark calls ------------------------------------------------------------------

@torch.no_grad()
def motion_embeddings(evaluator: MotionEvaluator, motions, chunk: int = 256) -> np.ndarray:
    """Motions (see module docstring) -> (M, embed) float64 unit vectors."""
    batch = motion_batch(motions, evaluator.config.fps)
    device = next(evaluator.parameters()).device
    m = len(batch["joints"])
    return np.concatenate([evaluator.encode_motion(_slice(batch, s, s + chunk, device)).double().cpu().numpy()
                           for s in range(0, m, chunk)])


@torch.no_grad()
def story_embeddings(evaluator: MotionEvaluator, controls, chunk: int = 256) -> np.ndarray:
    """Storyboards / controls (see module docstring) -> (M, embed) float64 unit vectors."""
    batch = story_batch(controls)
    device = next(evaluator.parameters()).device
    m = len(batch["kp_mask"])
    return np.concatenate([evaluator.encode_story(_slice(batch, s, s + chunk, device)).double().cpu().numpy()
                           for s in range(0, m, chunk)])


def embedding_fid(a: np.ndarray, b: np.ndarray) -> float:
    """Frechet distance between Gaussians fitted to two embedding sets (M, D) and (M', D)."""
    if len(a) < 2 or len(b) < 2:
        raise EvaluatorError(f"FID needs at least 2 motions per set, got {len(a)} and {len(b)}")
    return frechet_distance(a.mean(0), np.cov(a, rowvar=False), b.mean(0), np.cov(b, rowvar=False))


def fid(evaluator: MotionEvaluator, generated, reference) -> float:
    """FID between generated and reference motions in the evaluator's motion embedding space."""
    return embedding_fid(motion_embeddings(evaluator, generated), motion_embeddings(evaluator, reference))


def r_precision_top3(evaluator: MotionEvaluator, controls, generated, shuffle_seed: int | None = 0) -> float:
    """Storyboard -> motion R-precision, top 3 in batches of 32; controls[i] is the storyboard
    of generated[i]. Pairs are shuffled with a fixed seed first (None keeps the order), because
    neighbouring windows of one test clip are near duplicates that would share a batch."""
    story = story_embeddings(evaluator, controls)
    motion = motion_embeddings(evaluator, generated)
    if len(story) != len(motion):
        raise EvaluatorError(f"{len(story)} storyboards but {len(motion)} motions")
    if shuffle_seed is not None:
        order = np.random.default_rng(shuffle_seed).permutation(len(story))
        story, motion = story[order], motion[order]
    return r_precision(story, motion, top_k=R_PRECISION_TOP_K, batch=R_PRECISION_BATCH)


def embedding_diversity(evaluator: MotionEvaluator, motions, samples: int = 300, seed: int = 0) -> float:
    """Guo et al.'s Diversity: mean embedding distance between two random draws of `samples`
    motions (fewer when the set is smaller). metrics.diversity is the per-storyboard spread of
    variations in joint space, a different figure."""
    emb = motion_embeddings(evaluator, motions)
    k = min(samples, len(emb))
    rng = np.random.default_rng(seed)
    a, b = rng.choice(len(emb), k, replace=False), rng.choice(len(emb), k, replace=False)
    return float(np.mean(np.linalg.norm(emb[a] - emb[b], axis=-1)))

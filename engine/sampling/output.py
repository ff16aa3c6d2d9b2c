"""From latents to what the sampler hands out: decoded motion (remembered per latent), clips of the
storyboard's people and objects at the storyboard's frame rate, and the finished result.

The networks work on fixed slots at MODEL_FPS (engine.models.slots); everything here maps back to
the request's storyboard: its agents and objects, its frames and frame rate.
"""
from __future__ import annotations

from dataclasses import replace
from typing import Callable

import numpy as np
import torch

from ..clip import MotionClip
from ..finishing import FinishConfig, finish
from ..io.resample import resample_clip, resample_linear
from ..models.slots import MODEL_FPS
from ..request import ModelView, Request
from ..skeleton import HANDS


class LatentDecoder:
    """The VQ-VAE decode of z (K, T, V, d) -> motion dict, remembered for the same tensor:
    planning, the first guidance step and the result often decode the latent the step before them
    did (the sampler never changes a latent in place). One read and one write of the pair: a
    StepEvent's decode may run on another thread."""

    def __init__(self, vqvae: torch.nn.Module):
        self._vqvae = vqvae
        self._last: tuple[torch.Tensor | None, dict] = (None, {})

    def __call__(self, z: torch.Tensor) -> dict[str, torch.Tensor]:
        last, motion = self._last
        if z is not last:
            motion = self._vqvae.decode(z)
            self._last = (z, motion)
        return motion


class Output:
    """Shapes decoded motion (K, N padded frames at MODEL_FPS, all slots) into the storyboard's."""

    def __init__(self, request: Request, view: ModelView):
        self.storyboard, self.config = request.storyboard, request.config
        self.frames = view.frames
        self.humans, self.objects = len(self.storyboard.agents), len(self.storyboard.objects)

    def storyboard_view(self, motion: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
        """The decoded slots that the storyboard uses (its agents, its objects)."""
        h, o = self.humans, self.objects
        return {"joints": motion["joints"][:, :, :h], "rot6d": motion["rot6d"][:, :, :h],
                "obj_pose": motion["obj_pose"][:, :, :o], "obj_anchors": motion["obj_anchors"][:, :, :o]}

    def phase(self, occupancy: torch.Tensor | None, k: int) -> np.ndarray:
        """Variation k's CTMC occupancy (frames at MODEL_FPS, 3); uniform before the first plan."""
        if occupancy is None:
            return np.full((self.frames, 3), 1.0 / 3.0, np.float32)
        return occupancy[k, :self.frames].numpy().astype(np.float32)

    def at_storyboard_rate(self, per_frame: np.ndarray) -> np.ndarray:
        """(frames at MODEL_FPS, ...) -> (the storyboard's frames, ...), linearly in time."""
        if self.storyboard.fps == MODEL_FPS:
            return per_frame
        return resample_linear(per_frame, MODEL_FPS, self.storyboard.fps)[:self.storyboard.length].astype(per_frame.dtype)

    def clip(self, motion: dict[str, torch.Tensor], k: int, phase: np.ndarray, contact: bool = True) -> MotionClip:
        """Variation k of a decoded motion as a clip of the storyboard's agents and objects at its
        frame rate; `phase` (frames at MODEL_FPS, 3) is the occupancy to give it; `contact`: measure
        its hand contacts (not when finishing will move the hands)."""
        n, h, o, sb = self.frames, self.humans, self.objects, self.storyboard
        joints = motion["joints"][k, :n, :h].numpy()
        rot6d = motion["rot6d"][k, :n, :h].numpy()
        kw = {}
        if o:
            kw = dict(obj_pose=motion["obj_pose"][k, :n, :o].numpy(),
                      obj_anchors=motion["obj_anchors"][k, :n, :o].numpy(),
                      obj_type=np.array([ob.spec.type for ob in sb.objects]),
                      obj_size=np.array([ob.spec.size for ob in sb.objects], np.float32))
        clip = MotionClip(fps=MODEL_FPS, joints=_finite(joints), rot6d=_finite(rot6d), phase=phase,
                          scenario="generated", **{k2: _finite(v) if v.dtype.kind == "f" else v
                                                   for k2, v in kw.items()})
        if sb.fps != MODEL_FPS:
            clip = resample_clip(clip, sb.fps).slice(0, sb.length)
        return replace(clip, contact=_hand_contact(clip.joints, clip.obj_anchors, clip.phase)) if contact else clip

    def final_clips(self, motion: dict[str, torch.Tensor], occupancy: torch.Tensor | None,
                    checkpoint: Callable[[], None] = lambda: None) -> list[MotionClip]:
        """Every variation, through engine.finishing unless the config says not to (`checkpoint`
        run between its stages), its hand contacts measured on the result."""
        finishing = self.config.finish
        clips = [self.clip(motion, k, self.phase(occupancy, k), contact=not finishing)
                 for k in range(motion["joints"].shape[0])]
        if not finishing:
            return clips
        config = FinishConfig(polish=self.config.polish)
        finished = [finish(clip, self.storyboard, config, checkpoint) for clip in clips]
        return [replace(c, contact=_hand_contact(c.joints, c.obj_anchors, c.phase)) for c in finished]


def _hand_contact(joints: np.ndarray, anchors: np.ndarray | None, phase: np.ndarray,
                  reach: float = 0.08, softness: float = 0.02) -> np.ndarray:
    """Per-hand contact probability (N, H, 2): the CTMC's in-contact occupancy times how close
    the hand is to the nearest object anchor or other person's hand (1 within `reach` metres)."""
    hands = joints[:, :, list(HANDS)]                                   # (N, H, 2, 3)
    n, h = hands.shape[:2]
    targets = [hands.reshape(n, 1, h * 2, 3)]
    if anchors is not None:
        targets.append(anchors.reshape(n, 1, -1, 3))
    dist = np.linalg.norm(hands.reshape(n, h * 2, 1, 3) - np.concatenate(targets, 2), axis=-1)
    own = np.eye(h * 2, dtype=bool)                                     # a hand is not its own partner
    same_person = np.kron(np.eye(h, dtype=bool), np.ones((2, 2), bool))
    dist[:, :, :h * 2][:, own | same_person] = np.inf
    near = 0.5 * (1.0 - np.tanh((dist.min(-1) - reach) / (2 * softness)))  # a logistic that cannot overflow
    return (near.reshape(n, h, 2) * (phase[:, 1:].sum(-1))[:, None, None]).astype(np.float32)


def _finite(a: np.ndarray) -> np.ndarray:
    """Never hand out NaN: an untrained or diverged model's output is clamped to the scene's scale."""
    return np.nan_to_num(a, nan=0.0, posinf=10.0, neginf=-10.0).astype(np.float32)

"""The contract between the sketch encoders and the U-Net backbone.

The encoders (encoders.py) turn a batch of control tensors into a Conditioning; the backbone
(unet.py) consumes it. Classifier-free guidance drops it per sample with `drop` (a dropped
sample must behave exactly like "no storyboard").
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import torch

CONDITION_TYPES = ("kf", "tr", "o")   # keyposes, joint trajectories, object boxes / paths


@dataclass
class Conditioning:
    residual: torch.Tensor       # (B, T_lat, V, d_model) per-latent-step features per entity:
                                 # trajectory-path residuals + time-gated keyframe adapter output
    temporal_bias: torch.Tensor  # (B, T_lat, T_lat) additive temporal self-attention bias from
                                 # the along-path phase (s, s_dot, curvature)
    embed: torch.Tensor          # (B, d_e) pooled storyboard embedding (d_e = 256)
    drop: torch.Tensor | None = None  # (B,) bool: True = unconditional for that sample
    by_type: torch.Tensor | None = None  # (B, T_lat, V, 3, d_model) the residual per condition type
                                         # (CONDITION_TYPES; they sum to it): the ControlNet branches' input
    text: torch.Tensor | None = None     # (B, L, d_text) the storyboard text's token features (models/text.py)
    text_mask: torch.Tensor | None = None  # (B, L) 1 where a word is; all 0: no text

    def dropped(self, mask: torch.Tensor) -> "Conditioning":
        """The same conditioning with samples in `mask` (B,) bool marked unconditional."""
        drop = mask if self.drop is None else (self.drop | mask)
        return replace(self, drop=drop)

    def masked(self) -> "Conditioning":
        """Zero the dropped samples' tensors (what the backbone actually sees)."""
        if self.drop is None:
            return self
        keep = (~self.drop).float()
        return replace(self.without_text(self.drop), residual=self.residual * keep[:, None, None, None],
                       temporal_bias=self.temporal_bias * keep[:, None, None],
                       embed=self.embed * keep[:, None], drop=None,
                       by_type=None if self.by_type is None else self.by_type * keep[:, None, None, None, None])

    def without_text(self, mask: torch.Tensor) -> "Conditioning":
        """The samples in `mask` (B,) bool without their text (the sketch stays)."""
        if self.text_mask is None:
            return self
        return replace(self, text_mask=self.text_mask * (~mask).to(self.text_mask.dtype)[:, None])

    def repeat(self, n: int, drop: torch.Tensor | None = None) -> "Conditioning":
        """The batch repeated n times (sample i of copy c is sample i), with `drop` (n B,) or this one's."""
        if drop is None and self.drop is not None:
            drop = self.drop.repeat(n)
        return Conditioning(residual=self.residual.repeat(n, 1, 1, 1), temporal_bias=self.temporal_bias.repeat(n, 1, 1),
                            embed=self.embed.repeat(n, 1), drop=drop,
                            by_type=None if self.by_type is None else self.by_type.repeat(n, 1, 1, 1, 1),
                            text=None if self.text is None else self.text.repeat(n, 1, 1),
                            text_mask=None if self.text_mask is None else self.text_mask.repeat(n, 1))

    def from_step(self, start: int) -> "Conditioning":
        """The window of latent steps start.. (a sequence generated in overlapping windows)."""
        return replace(self, residual=self.residual[:, start:], temporal_bias=self.temporal_bias[:, start:, start:],
                       by_type=None if self.by_type is None else self.by_type[:, start:])

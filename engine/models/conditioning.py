"""The contract between the sketch encoders and the U-Net backbone.

The encoders (encoders.py) turn a batch of control tensors into a Conditioning; the backbone
(unet.py) consumes it. Classifier-free guidance drops it per sample with `drop` (a dropped
sample must behave exactly like "no storyboard").
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import torch


@dataclass
class Conditioning:
    residual: torch.Tensor       # (B, T_lat, V, d_model) per-latent-step features per entity:
                                 # trajectory-path residuals + time-gated keyframe adapter output
    temporal_bias: torch.Tensor  # (B, T_lat, T_lat) additive temporal self-attention bias from
                                 # the along-path phase (s, s_dot, curvature)
    embed: torch.Tensor          # (B, d_e) pooled storyboard embedding (d_e = 256)
    drop: torch.Tensor | None = None  # (B,) bool: True = unconditional for that sample

    def dropped(self, mask: torch.Tensor) -> "Conditioning":
        """The same conditioning with samples in `mask` (B,) bool marked unconditional."""
        drop = mask if self.drop is None else (self.drop | mask)
        return replace(self, drop=drop)

    def masked(self) -> "Conditioning":
        """Zero the dropped samples' tensors (what the backbone actually sees)."""
        if self.drop is None:
            return self
        keep = (~self.drop).float()
        return replace(self, residual=self.residual * keep[:, None, None, None],
                       temporal_bias=self.temporal_bias * keep[:, None, None],
                       embed=self.embed * keep[:, None], drop=None)

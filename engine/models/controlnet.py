"""ControlNet-style conditioning (the paper's "parallel ControlNets" ablation, and the control
branches of the Sketch2Anim-INT baseline in engine.baselines.sketch2anim).

A branch is a copy of the U-Net's down path (its own weights) that reads the noisy input plus one
control's feature map (added after its input convolution through a zero-initialised projection)
and returns, through zero-initialised projections, an addition to every skip connection and to
the bottleneck of the main network. One branch per condition type, run side by side and summed:
the main network itself sees no storyboard. A sample whose conditioning is dropped (classifier-free
guidance) gets no branch contribution at all: exactly the main network, unconditional.
"""
from __future__ import annotations

from dataclasses import replace

import torch
from torch import nn

from .conditioning import CONDITION_TYPES, Conditioning
from .unet import TemporalUNet, UNetConfig


def _zero_linear(inp: int, out: int) -> nn.Linear:
    layer = nn.Linear(inp, out)
    nn.init.zeros_(layer.weight)
    nn.init.zeros_(layer.bias)
    return layer


class ControlBranch(nn.Module):
    def __init__(self, cfg: UNetConfig, hint_dim: int):
        super().__init__()
        self.net = TemporalUNet(replace(cfg, n_heads_out=1, down_only=True, text_dim=0))   # text: the main network's
        self.hint = _zero_linear(hint_dim, cfg.channels[0])
        self.out = nn.ModuleList(_zero_linear(c, c) for c in (*cfg.channels, cfg.channels[-1]))

    def forward(self, z: torch.Tensor, time: torch.Tensor, hint: torch.Tensor,
                entity_pos: torch.Tensor | None) -> list[torch.Tensor]:
        """z (B, T, V, d), hint (B, T, V, hint_dim) -> additions (B*V, T_l, C_l) per level, bottleneck last."""
        b, t, v, _ = hint.shape
        h = self.hint(hint.transpose(1, 2).reshape(b * v, t, -1))
        return [proj(x) for proj, x in zip(self.out, self.net.levels(z, time, entity_pos, h))]


class ParallelControlNets(nn.Module):
    """A backbone with the TemporalUNet's call contract whose storyboard enters only through one
    ControlBranch per condition type (Conditioning.by_type), never as residual, bias or embedding."""

    def __init__(self, cfg: UNetConfig, types: tuple[str, ...] = CONDITION_TYPES):
        super().__init__()
        self.cfg = cfg
        self.main = TemporalUNet(cfg)
        self.types = types
        self.branches = nn.ModuleDict({y: ControlBranch(cfg, cfg.cond_dim) for y in types})

    def control(self, z: torch.Tensor, time: torch.Tensor, cond: Conditioning | None,
                entity_pos: torch.Tensor | None) -> list[torch.Tensor] | None:
        """The summed branch additions, zero for dropped samples; None without a storyboard."""
        if cond is None or cond.by_type is None:
            return None
        b, v = z.shape[0], z.shape[2]
        time = torch.as_tensor(time, dtype=z.dtype, device=z.device).expand(b)
        hints = cond.masked().by_type
        total = None
        for y in self.types:
            adds = self.branches[y](z, time, hints[:, :, :, CONDITION_TYPES.index(y)], entity_pos)
            total = adds if total is None else [a + c for a, c in zip(total, adds)]
        if cond.drop is not None:
            keep = (~cond.drop).to(z.dtype).repeat_interleave(v)[:, None, None]
            total = [a * keep for a in total]
        return total

    def forward(self, z: torch.Tensor, time: torch.Tensor, cond: Conditioning | None = None,
                entity_pos: torch.Tensor | None = None) -> torch.Tensor:
        """As TemporalUNet.forward: -> (B, n_heads_out, T, V, d)."""
        return self.main(z, time, None, entity_pos, control=self.control(z, time, cond, entity_pos))

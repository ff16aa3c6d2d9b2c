"""Classifier-free guidance: one wrapper for every field the sampler drives (the student's
velocity, the teacher's noise prediction)."""
from __future__ import annotations

import torch

from ..models.conditioning import Conditioning
from ..models.teacher import Field


class ClassifierFreeGuidance:
    """Wraps a field f(z, time, cond, entity_pos) into uncond + w (cond - uncond).
    Conditional and unconditional passes run as one batch of 2B. With cond None or w == 1 it is
    the plain conditional field."""

    def __init__(self, field: Field, weight: float = 1.6):
        self.field, self.weight = field, weight

    def __call__(self, z: torch.Tensor, time: torch.Tensor, cond: Conditioning | None = None,
                 entity_pos: torch.Tensor | None = None) -> torch.Tensor:
        if cond is None or self.weight == 1.0:
            return self.field(z, time, cond, entity_pos)
        b = z.shape[0]
        time = torch.as_tensor(time, dtype=z.dtype, device=z.device).expand(b)
        drop = torch.zeros(b, dtype=torch.bool, device=z.device) if cond.drop is None else cond.drop
        both = cond.repeat(2, drop=torch.cat([drop, torch.ones_like(drop)]))
        pos = None if entity_pos is None else entity_pos.repeat(2, 1, 1, 1)
        out = self.field(z.repeat(2, 1, 1, 1), time.repeat(2), both, pos)
        cond_out, uncond_out = out[:b], out[b:]
        return uncond_out + self.weight * (cond_out - uncond_out)

"""Classifier-free guidance: one wrapper for every field the sampler drives (the student's
velocity, the teacher's noise prediction)."""
from __future__ import annotations

import torch

from ..models.conditioning import Conditioning
from ..models.teacher import Field


class ClassifierFreeGuidance:
    """Wraps a field f(z, time, cond, entity_pos) into uncond + w (cond - uncond).
    Conditional and unconditional passes run as one batch of 2B. With cond None or w == 1 it is
    the plain conditional field. With a `text_weight` and a storyboard text, the text gets its own
    weight: uncond + w (sketch - uncond) + text_weight (sketch and text - sketch), where "sketch"
    is the conditional pass without the text (one more pass in the batch; text_weight == w is the
    plain guidance)."""

    def __init__(self, field: Field, weight: float = 1.6, text_weight: float | None = None):
        self.field, self.weight, self.text_weight = field, weight, text_weight

    def __call__(self, z: torch.Tensor, time: torch.Tensor, cond: Conditioning | None = None,
                 entity_pos: torch.Tensor | None = None) -> torch.Tensor:
        text = (cond is not None and self.text_weight is not None and self.text_weight != self.weight
                and cond.text_mask is not None and bool(cond.text_mask.any()))
        if cond is None or (self.weight == 1.0 and not text):
            return self.field(z, time, cond, entity_pos)
        b = z.shape[0]
        time = torch.as_tensor(time, dtype=z.dtype, device=z.device).expand(b)
        drop = torch.zeros(b, dtype=torch.bool, device=z.device) if cond.drop is None else cond.drop
        # Passes in one batch: the full condition, then (text) the sketch alone, then (w != 1) none.
        drops = [drop, drop] if text else [drop]
        if self.weight != 1.0:
            drops.append(torch.ones_like(drop))
        n = len(drops)
        both = cond.repeat(n, drop=torch.cat(drops))
        if text:
            both = both.without_text(torch.arange(n * b, device=z.device) // b == 1)
        pos = None if entity_pos is None else entity_pos.repeat(n, 1, 1, 1)
        out = self.field(z.repeat(n, 1, 1, 1), time.repeat(n), both, pos).split(b)
        cond_out, sketch_out = out[0], out[1] if text else out[0]
        guided = sketch_out if self.weight == 1.0 else out[-1] + self.weight * (sketch_out - out[-1])
        return guided + self.text_weight * (cond_out - sketch_out) if text else guided

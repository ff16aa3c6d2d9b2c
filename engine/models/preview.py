"""The few-step preview student: the guided student's ODE distilled into a few jumps.

The student takes DEFAULT_STEPS Heun steps (5), each two evaluations of a classifier-free guided
field (two passes each): 10 evaluations. The preview student is the same network (initialised
from the student) trained so that one conditional call per step follows that guided ODE over
a jump of 1 / K in t (K = ModelConfig.preview_steps), classifier-free guidance included:

    z_{k+1} = z_k + (t_{k+1} - t_k) * mix(v_preview(z_k, t_k), occupancy)      t_k = 1 - k / K

Targets come from the frozen student itself (`reference_path`: the guided ODE from the same
noise, REFERENCE_STEPS Heun steps in all), so the preview needs no data of its own and inherits
the student's conditioning; each of the K jumps of a reference path is one training example
(teacher forcing, as in progressive distillation). Occupancy and entity positions are given as
the sampler gives them: the phase plan, and the low-resolution decode of the clean estimate
(none at the first step).
"""
from __future__ import annotations

from collections.abc import Callable

import torch
import torch.nn.functional as F

from .conditioning import Conditioning
from .student import RectifiedFlowStudent

PREVIEW_STEPS = 2          # jumps of a preview trained now (ModelConfig.preview_steps: the bundle's own)
REFERENCE_STEPS = 8        # Heun steps of the reference path, whatever the jumps (the full generation takes 9)

# (z, t (B,), cond, entity_pos, occupancy) -> velocity: the guided student field to follow.
GuidedField = Callable[[torch.Tensor, torch.Tensor, Conditioning, torch.Tensor | None, torch.Tensor | None], torch.Tensor]
LowRes = Callable[[torch.Tensor], torch.Tensor]        # clean latent -> entity positions


def preview_times(steps: int = PREVIEW_STEPS) -> list[float]:
    """t_0 = 1 (noise) ... t_steps = 0 (data), evenly spaced (the sampler's flow_times)."""
    return torch.linspace(1.0, 0.0, steps + 1).tolist()


@torch.no_grad()
def reference_path(field: GuidedField, lowres: LowRes, z1: torch.Tensor, cond: Conditioning,
                   occupancy: torch.Tensor | None, steps: int = PREVIEW_STEPS,
                   substeps: int | None = None) -> tuple[list[torch.Tensor], list[torch.Tensor | None]]:
    """The guided ODE from noise z1 (B, T_lat, V, d) by Heun steps, `substeps` per jump (by default
    REFERENCE_STEPS in all): (states at preview_times(steps), K + 1 of them; the entity positions
    the sampler would use at the start of each jump, K of them, None at the first)."""
    substeps = substeps or max(1, REFERENCE_STEPS // steps)
    times = torch.linspace(1.0, 0.0, steps * substeps + 1).tolist()
    z, pos, states, positions = z1, None, [z1], [None]
    for i, (t, t_next) in enumerate(zip(times[:-1], times[1:])):
        def v(x, s):
            return field(x, torch.full((x.shape[0],), s, dtype=x.dtype, device=x.device), cond, pos, occupancy)
        v_start = v(z, t)
        v_end = v(z + (t_next - t) * v_start, t_next)
        z = z + (t_next - t) * 0.5 * (v_start + v_end)
        pos = lowres(z - t_next * v_end) if t_next > 0 else pos
        if (i + 1) % substeps == 0:
            states.append(z)
            positions.append(pos)
    return states, positions[:-1]


def preview_loss(preview: RectifiedFlowStudent, states: list[torch.Tensor], positions: list[torch.Tensor | None],
                 cond: Conditioning, occupancy: torch.Tensor | None) -> dict[str, torch.Tensor]:
    """Mean squared error of the preview's jump velocity against the reference's, per jump of each
    path. states, positions as reference_path returns them; occupancy (B, ...) or None. The first
    jump runs without entity positions (as the sampler's first step), the others in one batch."""
    steps, b = len(states) - 1, states[0].shape[0]
    times = preview_times(steps)
    target = [(states[k + 1] - states[k]) / (times[k + 1] - times[k]) for k in range(steps)]

    def jumps(ks: list[int], pos: torch.Tensor | None) -> torch.Tensor:
        z = torch.cat([states[k] for k in ks])
        t = torch.tensor([times[k] for k in ks], dtype=z.dtype, device=z.device).repeat_interleave(b)
        occ = None if occupancy is None else occupancy.repeat(len(ks), *([1] * (occupancy.dim() - 1)))
        v = preview.velocity(z, t, cond.repeat(len(ks)), pos, occ)
        return F.mse_loss(v, torch.cat([target[k] for k in ks]), reduction="none").flatten(1).mean(1)

    errors = [jumps([0], None)]
    if steps > 1:
        errors.append(jumps(list(range(1, steps)), torch.cat(positions[1:])))
    per_jump = torch.cat(errors).reshape(steps, b).mean(1)
    return {"loss": per_jump.mean(), **{f"jump{k}": per_jump[k].detach() for k in range(steps)}}

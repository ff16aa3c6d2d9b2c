"""Solver steps, apart from the models and the guidance (as diffusers' schedulers and flow_matching's
`solver/`): each step is a small function of a field, the state and the times; the caller (the
sampler) owns the loop, and with it the noise draws, the guidance and the planner.

Rectified flow (the student): time t from 1 (noise) to 0 (data) on z_t = (1 - t) z_0 + t noise;
a velocity field v(z, t) = dz/dt, so the clean estimate at t is z - t v.
VP diffusion (the teacher, engine.models.teacher): diffusion time tau (0 = data), a noise field
eps(z, tau (B,)); DDPM's ancestral step over all the schedule's steps, and DDIM's (eta = 0).
Latents are (B, T, V, d) throughout.
"""
from __future__ import annotations

from typing import Callable

import torch
from torch import Tensor

from ..models.teacher import VPSchedule

VelocityField = Callable[[Tensor, float], Tensor]    # (z, t) -> dz/dt
NoiseField = Callable[[Tensor, Tensor], Tensor]      # (z, tau (B,)) -> predicted noise

LATENT_CLIP = 4.0  # the latent has unit variance: a clean estimate beyond 4 std is an error


# ---- rectified flow ---------------------------------------------------------------------------

def flow_times(steps: int) -> list[float]:
    """t_0 = 1 (noise) ... t_steps = 0 (data), evenly spaced."""
    return torch.linspace(1.0, 0.0, steps + 1).tolist()


def euler_step(field: VelocityField, z: Tensor, t: float, t_next: float) -> Tensor:
    return z + (t_next - t) * field(z, t)


def heun_step(field: VelocityField, z: Tensor, t: float, t_next: float) -> tuple[Tensor, Tensor]:
    """One Heun (trapezoid) step: z at t_next, and the velocity at the Euler predictor's end
    (two evaluations of the field)."""
    v_start = field(z, t)
    v_end = field(z + (t_next - t) * v_start, t_next)
    return z + (t_next - t) * (0.5 * (v_start + v_end)), v_end


def flow_clean_estimate(z: Tensor, velocity: Tensor, t: float) -> Tensor:
    """z_0 predicted from z_t and the velocity there."""
    return z - t * velocity if t > 0 else z


def flow_renoise(z0: Tensor, noise: Tensor, t: float) -> Tensor:
    """z_t from a clean latent and a noise estimate: how a guided z_0 re-enters the trajectory."""
    return (1 - t) * z0 + t * noise if t > 0 else z0


# ---- VP diffusion -----------------------------------------------------------------------------

def clean_estimate(z: Tensor, eps: Tensor, a_t: Tensor, clip: float | None = LATENT_CLIP) -> tuple[Tensor, Tensor]:
    """z0_hat from z_tau and the predicted noise, clipped to [-clip, clip], and the noise made
    consistent with the clipped estimate. At high noise z0_hat = (z - sqrt(1-a) eps) / sqrt(a)
    multiplies any error in eps by 1/sqrt(a) (~150 at tau = 1), which clipping contains
    (as DDPM's clip_denoised does)."""
    z0_hat = (z - (1 - a_t).sqrt() * eps) / a_t.sqrt()
    if clip is None:
        return z0_hat, eps
    z0_hat = z0_hat.clamp(-clip, clip)
    return z0_hat, (z - a_t.sqrt() * z0_hat) / (1 - a_t).sqrt()


def ddpm_times(schedule: VPSchedule) -> tuple[Tensor, Tensor]:
    """DDPM's discrete times tau_i = (i + 1) / steps and alpha_bar there, (steps,) each; the
    steps run i = steps - 1 down to 0."""
    taus = torch.arange(1, schedule.steps + 1, dtype=torch.float32) / schedule.steps
    return taus, schedule.alpha_bar(taus)


def ddpm_step(field: NoiseField, z: Tensor, i: int, taus: Tensor, abar: Tensor,
              generator: torch.Generator | None = None, clip: float | None = LATENT_CLIP) -> tuple[Tensor, Tensor, float]:
    """Ancestral step from tau_i: (z at the previous time, z0_hat, that time (0 after the last))."""
    a_t = abar[i]
    a_prev = abar[i - 1] if i > 0 else torch.tensor(1.0)
    alpha = a_t / a_prev
    eps = field(z, taus[i].expand(z.shape[0]))
    z0_hat, eps = clean_estimate(z, eps, a_t, clip)
    mean = (z - (1 - alpha) / (1 - a_t).sqrt() * eps) / alpha.sqrt()
    if i == 0:
        return mean, z0_hat, 0.0
    var = (1 - alpha) * (1 - a_prev) / (1 - a_t)
    return mean + var.sqrt() * torch.randn(z.shape, generator=generator), z0_hat, float(taus[i - 1])


def ddim_times(steps: int) -> Tensor:
    """tau from 1 to 0 in `steps` even steps, (steps + 1,)."""
    return torch.linspace(1.0, 0.0, steps + 1)


def ddim_step(field: NoiseField, schedule: VPSchedule, z: Tensor, tau: Tensor, tau_next: Tensor,
              clip: float | None = LATENT_CLIP) -> tuple[Tensor, Tensor]:
    """Deterministic DDIM (eta = 0) from tau to tau_next: (z there, z0_hat)."""
    tau = tau.clamp_min(schedule.tau_min)
    a_t, a_next = schedule.alpha_bar(tau), schedule.alpha_bar(tau_next)
    z0_hat, eps = clean_estimate(z, field(z, tau.expand(z.shape[0])), a_t, clip)
    return a_next.sqrt() * z0_hat + (1 - a_next).sqrt() * eps, z0_hat

"""VP diffusion teacher: noise schedule, epsilon-prediction loss, probability-flow velocity,
classifier-free guidance and DDPM / DDIM samplers written as generators (the caller owns the loop).

Diffusion time tau in [0, 1] (0 = data). The schedule is the continuous form of DDPM's linear
betas: beta(tau) = beta_min + tau (beta_max - beta_min), alpha_bar(tau) = exp(-int_0^tau beta),
which with 1000 steps is DDPM's 1e-4 .. 0.02. The forward process is
z_tau = sqrt(abar) z_0 + sqrt(1 - abar) eps.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Iterator

import torch
from torch import nn

from .conditioning import Conditioning
from .unet import TemporalUNet

# A field maps (z (B,T,V,d), time (B,), cond or None, entity_pos or None) -> (B, T, V, d).
Field = Callable[[torch.Tensor, torch.Tensor, "Conditioning | None", "torch.Tensor | None"], torch.Tensor]


@dataclass(frozen=True)
class VPSchedule:
    beta_min: float = 0.1
    beta_max: float = 20.0
    steps: int = 1000            # DDPM discretization; tau_i = (i + 1) / steps

    @property
    def tau_min(self) -> float:
        return 1.0 / self.steps

    def beta(self, tau: torch.Tensor) -> torch.Tensor:
        return self.beta_min + tau * (self.beta_max - self.beta_min)

    def log_alpha_bar(self, tau: torch.Tensor) -> torch.Tensor:
        return -(self.beta_min * tau + 0.5 * (self.beta_max - self.beta_min) * tau ** 2)

    def alpha_bar(self, tau: torch.Tensor) -> torch.Tensor:
        return torch.exp(self.log_alpha_bar(tau))

    def tau_from_log_alpha_bar(self, log_abar: torch.Tensor) -> torch.Tensor:
        """Inverse of log_alpha_bar: the positive root of a tau^2 + b tau + log_abar = 0, in the
        form without cancellation near tau = 0."""
        a, b = 0.5 * (self.beta_max - self.beta_min), self.beta_min
        return -2 * log_abar / (b + torch.sqrt(b * b - 4 * a * log_abar))


def broadcast(x: torch.Tensor, like: torch.Tensor) -> torch.Tensor:
    """(B,) -> (B, 1, 1, ...) matching like's rank."""
    return x.reshape(-1, *([1] * (like.dim() - 1)))


class DiffusionTeacher(nn.Module):
    """Epsilon-prediction VP diffusion on the entity latent, with the backbone as denoiser."""

    def __init__(self, backbone: TemporalUNet, schedule: VPSchedule = VPSchedule()):
        super().__init__()
        if backbone.cfg.n_heads_out != 1:
            raise ValueError("the teacher's backbone must have n_heads_out = 1")
        self.backbone, self.schedule = backbone, schedule

    def eps(self, z: torch.Tensor, tau: torch.Tensor, cond: Conditioning | None = None,
            entity_pos: torch.Tensor | None = None) -> torch.Tensor:
        """Predicted noise (B, T, V, d) at z_tau (B, T, V, d), tau (B,)."""
        return self.backbone(z, tau, cond, entity_pos)[:, 0]

    forward = eps

    def loss(self, z0: torch.Tensor, cond: Conditioning | None, entity_pos: torch.Tensor | None = None,
             generator: torch.Generator | None = None, cond_drop: float = 0.1) -> dict[str, torch.Tensor]:
        """Epsilon MSE at tau ~ U[tau_min, 1], with `cond_drop` of the samples unconditional."""
        b = z0.shape[0]
        s = self.schedule
        tau = s.tau_min + (1 - s.tau_min) * torch.rand(b, generator=generator, device=z0.device)
        noise = torch.randn(z0.shape, generator=generator, device=z0.device)
        abar = broadcast(s.alpha_bar(tau), z0)
        z_tau = abar.sqrt() * z0 + (1 - abar).sqrt() * noise
        if cond is not None:
            cond = cond.dropped(torch.rand(b, generator=generator, device=z0.device) < cond_drop)
        loss = (self.eps(z_tau, tau, cond, entity_pos) - noise).pow(2).mean()
        return {"loss": loss, "eps_mse": loss.detach()}


def pf_velocity(eps_field: Field, schedule: VPSchedule, z: torch.Tensor, tau: torch.Tensor,
                cond: Conditioning | None = None, entity_pos: torch.Tensor | None = None) -> torch.Tensor:
    """Probability-flow ODE velocity dz/dtau (paper eq. pf_velocity):
    -beta(tau)/2 * (z - eps_hat / sqrt(1 - abar(tau))). z (B,T,V,d), tau (B,)."""
    eps = eps_field(z, tau, cond, entity_pos)
    beta = broadcast(schedule.beta(tau), z)
    sigma = broadcast((-torch.expm1(schedule.log_alpha_bar(tau))).sqrt(), z)
    return -0.5 * beta * (z - eps / sigma)


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
        both = Conditioning(residual=cond.residual.repeat(2, 1, 1, 1),
                            temporal_bias=cond.temporal_bias.repeat(2, 1, 1),
                            embed=cond.embed.repeat(2, 1),
                            drop=torch.cat([drop, torch.ones_like(drop)]))
        pos = None if entity_pos is None else entity_pos.repeat(2, 1, 1, 1)
        out = self.field(z.repeat(2, 1, 1, 1), time.repeat(2), both, pos)
        cond_out, uncond_out = out[:b], out[b:]
        return uncond_out + self.weight * (cond_out - uncond_out)


@dataclass
class DiffusionStep:
    index: int              # 0-based step number
    num_steps: int
    tau: float              # diffusion time after this step
    z: torch.Tensor         # (B, T, V, d) current latent
    z0_hat: torch.Tensor    # (B, T, V, d) the clean-latent estimate at this step


LATENT_CLIP = 4.0  # the latent has unit variance: a clean estimate beyond 4 std is an error


def clean_estimate(z: torch.Tensor, eps: torch.Tensor, a_t: torch.Tensor,
                   clip: float | None = LATENT_CLIP) -> tuple[torch.Tensor, torch.Tensor]:
    """z0_hat from z_tau and the predicted noise, clipped to [-clip, clip], and the noise made
    consistent with the clipped estimate. At high noise z0_hat = (z - sqrt(1-a) eps) / sqrt(a)
    multiplies any error in eps by 1/sqrt(a) (~150 at tau = 1), which clipping contains
    (as DDPM's clip_denoised does)."""
    z0_hat = (z - (1 - a_t).sqrt() * eps) / a_t.sqrt()
    if clip is None:
        return z0_hat, eps
    z0_hat = z0_hat.clamp(-clip, clip)
    return z0_hat, (z - a_t.sqrt() * z0_hat) / (1 - a_t).sqrt()


def ddpm_sample(eps_field: Field, schedule: VPSchedule, shape: tuple[int, ...],
                cond: Conditioning | None = None, entity_pos: torch.Tensor | None = None,
                generator: torch.Generator | None = None, clip: float | None = LATENT_CLIP) -> Iterator[DiffusionStep]:
    """Ancestral DDPM over all `schedule.steps` discrete steps. Yields a DiffusionStep per step;
    the last one's z is the sample."""
    n = schedule.steps
    taus = torch.arange(1, n + 1, dtype=torch.float32) / n
    abar = schedule.alpha_bar(taus)
    z = torch.randn(shape, generator=generator)
    for k, i in enumerate(reversed(range(n))):
        a_t = abar[i]
        a_prev = abar[i - 1] if i > 0 else torch.tensor(1.0)
        alpha = a_t / a_prev
        with torch.no_grad():
            eps = eps_field(z, taus[i].expand(shape[0]), cond, entity_pos)
        z0_hat, eps = clean_estimate(z, eps, a_t, clip)
        mean = (z - (1 - alpha) / (1 - a_t).sqrt() * eps) / alpha.sqrt()
        if i > 0:
            var = (1 - alpha) * (1 - a_prev) / (1 - a_t)
            z = mean + var.sqrt() * torch.randn(shape, generator=generator)
        else:
            z = mean
        yield DiffusionStep(k, n, float(taus[i - 1]) if i > 0 else 0.0, z, z0_hat)


def ddim_sample(eps_field: Field, schedule: VPSchedule, shape: tuple[int, ...], num_steps: int = 50,
                cond: Conditioning | None = None, entity_pos: torch.Tensor | None = None,
                generator: torch.Generator | None = None, clip: float | None = LATENT_CLIP) -> Iterator[DiffusionStep]:
    """Deterministic DDIM (eta = 0) on `num_steps` evenly spaced taus from 1 to 0; only the
    initial noise is random, so a seeded generator gives the same sample every time."""
    taus = torch.linspace(1.0, 0.0, num_steps + 1)
    z = torch.randn(shape, generator=generator)
    for k in range(num_steps):
        tau, tau_next = taus[k].clamp_min(schedule.tau_min), taus[k + 1]
        a_t, a_next = schedule.alpha_bar(tau), schedule.alpha_bar(tau_next)
        with torch.no_grad():
            eps = eps_field(z, tau.expand(shape[0]), cond, entity_pos)
        z0_hat, eps = clean_estimate(z, eps, a_t, clip)
        z = a_next.sqrt() * z0_hat + (1 - a_next).sqrt() * eps
        yield DiffusionStep(k, num_steps, float(tau_next), z, z0_hat)


def run_to_end(steps: Iterator[DiffusionStep]) -> torch.Tensor:
    """Drive a sampler generator to its end and return the final latent."""
    last = None
    for last in steps:
        pass
    return last.z

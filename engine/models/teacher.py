"""VP diffusion teacher: noise schedule, epsilon-prediction loss and probability-flow velocity.
Its DDPM and DDIM steps are solvers (engine.sampling.solvers); the sampler owns the loop.

Diffusion time tau in [0, 1] (0 = data). The schedule is the continuous form of DDPM's linear
betas: beta(tau) = beta_min + tau (beta_max - beta_min), alpha_bar(tau) = exp(-int_0^tau beta),
which with 1000 steps is DDPM's 1e-4 .. 0.02. The forward process is
z_tau = sqrt(abar) z_0 + sqrt(1 - abar) eps.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

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

    def noised(self, z0: torch.Tensor, cond: Conditioning | None, generator: torch.Generator | None = None,
               cond_drop: float = 0.1):
        """A training draw: tau ~ U[tau_min, 1] (B,), noise and z_tau like z0, and cond with
        `cond_drop` of the samples unconditional."""
        b = z0.shape[0]
        s = self.schedule
        tau = s.tau_min + (1 - s.tau_min) * torch.rand(b, generator=generator, device=z0.device)
        noise = torch.randn(z0.shape, generator=generator, device=z0.device)
        abar = broadcast(s.alpha_bar(tau), z0)
        z_tau = abar.sqrt() * z0 + (1 - abar).sqrt() * noise
        if cond is not None:
            cond = cond.dropped(torch.rand(b, generator=generator, device=z0.device) < cond_drop)
        return tau, noise, z_tau, cond

    def loss(self, z0: torch.Tensor, cond: Conditioning | None, entity_pos: torch.Tensor | None = None,
             generator: torch.Generator | None = None, cond_drop: float = 0.1) -> dict[str, torch.Tensor]:
        """Epsilon MSE at tau ~ U[tau_min, 1], with `cond_drop` of the samples unconditional."""
        tau, noise, z_tau, cond = self.noised(z0, cond, generator, cond_drop)
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

"""Learned potential V_psi(z) and the Lyapunov loss (paper Sec. 3.3).

V_psi scores latents: low on the motion manifold, high off it. It is trained in two phases
(energy-equilibrium matching): an optimal-transport warm-up on straight paths between data (or
teacher) latents z0 and noise z1, then contrastive divergence with negatives drawn by short
Langevin chains on V_psi. The student is then asked to move along descent directions of the
total potential (V_psi + scheduled energies + lambda_lat E_lat) through L_Lyap.

Scale: V is extensive (a sum of per-latent-step scores plus 0.5 q ||z||^2), so exp(-V) is a
proper density over the whole latent and Langevin steps z - eps grad V + sqrt(2 eps) xi are
meaningful. Losses divide by the number of latent elements so their size does not depend on
T_lat, V or d.

For the trainer:
  ot_warmup_loss(potential, z_data, z_noise, cfg) -> (loss, parts)            phase 1
  langevin_negatives(potential, z_init, cfg, generator) -> z (detached)         phase 2 negatives
  contrastive_divergence_loss(potential, z_pos, z_neg, cfg) -> (loss, parts)    phase 2
  lyapunov_loss(grad_V, velocity, kappa) -> scalar                              student stage
Time convention: noise at t = 1, data at t = 0 (z_t = (1 - t) z0 + t z1), as in the sampler.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import torch
import torch.nn.functional as F
from torch import nn


@dataclass
class PotentialConfig:
    entities: int = 3             # V
    latent_dim: int = 32          # d
    hidden: int = 128
    layers: int = 3               # temporal conv layers (kernel 3)
    quadratic: float = 0.05       # q: keeps V bounded below so Langevin chains cannot run away
    rank_weight: float = 1.0      # weight of the along-path ranking term in the warm-up
    langevin_steps: int = 10
    langevin_step_size: float = 0.01
    langevin_noise: float = 1.0   # 1 = exact Langevin for exp(-V); < 1 sharpens (common in EBMs)
    cd_regularizer: float = 0.1   # weight of the squared network output (keeps the scale bounded)
    kappa: float = 0.1            # Lyapunov margin


class LatentPotential(nn.Module):
    """V_psi: z (B, T_lat, V, d) -> (B,)."""

    def __init__(self, cfg: PotentialConfig | None = None):
        super().__init__()
        cfg = cfg or PotentialConfig()
        self.cfg = cfg
        chans = cfg.entities * cfg.latent_dim
        convs = []
        for i in range(cfg.layers):
            convs += [nn.Conv1d(chans if i == 0 else cfg.hidden, cfg.hidden, 3, padding=1), nn.SiLU()]
        self.body = nn.Sequential(*convs)
        self.score = nn.Conv1d(cfg.hidden, 1, 1)

    def network(self, z: torch.Tensor) -> torch.Tensor:
        """The learned part alone: sum over latent steps of a local score. (B, T_lat, V, d) -> (B,)."""
        b, t = z.shape[:2]
        return self.score(self.body(z.reshape(b, t, -1).transpose(1, 2))).sum((1, 2))

    def forward(self, z: torch.Tensor) -> torch.Tensor:
        return self.network(z) + 0.5 * self.cfg.quadratic * z.flatten(1).pow(2).sum(1)

    def gradient(self, z: torch.Tensor, create_graph: bool = False) -> torch.Tensor:
        """grad_z V_psi (B, T_lat, V, d); create_graph=True when a loss on it should train psi."""
        with torch.enable_grad():
            if not z.requires_grad:
                z = z.detach().requires_grad_(True)
            (g,) = torch.autograd.grad(self(z).sum(), z, create_graph=create_graph)
        return g


def _per_element(x: torch.Tensor, z: torch.Tensor) -> torch.Tensor:
    return x / z[0].numel()


def ot_warmup_loss(potential: LatentPotential, z_data: torch.Tensor, z_noise: torch.Tensor,
                   cfg: PotentialConfig | None = None,
                   generator: torch.Generator | None = None) -> tuple[torch.Tensor, dict]:
    """Warm-up on OT paths z_t = (1 - t) z0 + t z1 between data z0 and noise z1 (B, T_lat, V, d).

    Two terms: grad V(z_t) regresses the path velocity z1 - z0 (V rises from data towards noise
    with the right slope), and a softplus ranking makes V lower at the earlier of two points on
    the same path, margin proportional to their time gap. Returns (loss, parts)."""
    cfg = cfg or potential.cfg
    b = z_data.shape[0]
    t = torch.rand(b, 2, generator=generator, device=z_data.device)
    t_lo, t_hi = t.min(1).values, t.max(1).values

    def at(s: torch.Tensor) -> torch.Tensor:
        s = s[:, None, None, None]
        return (1 - s) * z_data + s * z_noise

    z_lo = at(t_lo).requires_grad_(True)
    v_lo = potential(z_lo)
    (grad,) = torch.autograd.grad(v_lo.sum(), z_lo, create_graph=True)
    match = _per_element((grad - (z_noise - z_data)).pow(2).flatten(1).sum(1), z_data).mean()
    gap = _per_element(potential(at(t_hi)) - v_lo, z_data)
    rank = F.softplus((t_hi - t_lo) - gap).mean()
    return match + cfg.rank_weight * rank, {"ot_match": match.detach(), "ot_rank": rank.detach()}


def langevin_negatives(potential: LatentPotential, z_init: torch.Tensor, cfg: PotentialConfig | None = None,
                       generator: torch.Generator | None = None) -> torch.Tensor:
    """Short Langevin chain z <- z - eps grad V + noise sqrt(2 eps) xi from z_init (B, T_lat, V, d).
    Returns the end states, detached (negatives carry no gradient)."""
    cfg = cfg or potential.cfg
    eps = cfg.langevin_step_size
    z = z_init.detach()
    for _ in range(cfg.langevin_steps):
        xi = torch.randn(z.shape, generator=generator, device=z.device)
        z = (z - eps * potential.gradient(z) + cfg.langevin_noise * math.sqrt(2 * eps) * xi).detach()
    return z


def contrastive_divergence_loss(potential: LatentPotential, z_pos: torch.Tensor, z_neg: torch.Tensor,
                                cfg: PotentialConfig | None = None) -> tuple[torch.Tensor, dict]:
    """CD: lower V on data z_pos, raise it on Langevin negatives z_neg (both (B, T_lat, V, d)),
    plus a squared penalty on the network's output (per element) so V cannot grow without end."""
    cfg = cfg or potential.cfg
    v_pos, v_neg = _per_element(potential(z_pos), z_pos), _per_element(potential(z_neg), z_neg)
    reg = (_per_element(potential.network(z_pos), z_pos).pow(2)
           + _per_element(potential.network(z_neg), z_neg).pow(2)).mean()
    gap = v_pos.mean() - v_neg.mean()
    return gap + cfg.cd_regularizer * reg, {"cd_gap": gap.detach(), "cd_reg": reg.detach()}


def lyapunov_loss(grad_V: torch.Tensor, velocity: torch.Tensor, kappa: float = 0.1) -> torch.Tensor:
    """L_Lyap = E[(max{0, grad V . v + kappa ||grad V||^2})^2], per sample over all latent
    elements, both inner products divided by the element count.

    grad_V: gradient of the total potential at z (B, ...), create_graph=True if psi should learn
    from it; velocity: the direction the state actually moves (B, ...). The student's sampler
    integrates t from 1 to 0 with dz/dt = v_phi, so the state moves along -v_phi: pass -v_phi.
    Zero when velocity descends at least as steeply as -kappa grad V (for kappa < 1, -grad V
    itself costs nothing)."""
    g, v = grad_V.flatten(1), velocity.flatten(1)
    n = g.shape[1]
    slack = (g * v).sum(1) / n + kappa * g.pow(2).sum(1) / n
    return F.relu(slack).pow(2).mean()

"""Learned potential: shapes and gradients, OT warm-up and contrastive divergence separate data
from noise and from Langevin negatives, and the Lyapunov loss."""
import torch

from engine.models.potential import (LatentPotential, PotentialConfig, contrastive_divergence_loss, langevin_negatives,
                                     lyapunov_loss, ot_warmup_loss)

torch.set_num_threads(1)
T, V, D = 8, 3, 4
CFG = PotentialConfig(entities=V, latent_dim=D, hidden=32, layers=2)


def data_latents(b: int, g: torch.Generator) -> torch.Tensor:
    """A structured 'manifold': per-channel sinusoids over time with random phase."""
    t = torch.linspace(0, 1, T)[None, :, None, None]
    amp = 1.3 * (1.0 + 0.2 * torch.randn(b, 1, V, D, generator=g))
    return amp * torch.sin(6.283 * t + 6.283 * torch.rand(b, 1, V, D, generator=g))


def test_potential_shapes_and_gradient():
    pot = LatentPotential()
    z = torch.randn(2, 30, 3, 32)
    assert pot(z).shape == (2,)
    g = pot.gradient(z)
    assert g.shape == z.shape and not g.requires_grad
    assert pot.gradient(z, create_graph=True).requires_grad


def test_warmup_then_contrastive_divergence_ranks_data_below_negatives():
    torch.manual_seed(0)
    g = torch.Generator().manual_seed(0)
    pot = LatentPotential(CFG)
    opt = torch.optim.Adam(pot.parameters(), lr=1e-3)
    for _ in range(120):
        loss, parts = ot_warmup_loss(pot, data_latents(32, g), torch.randn(32, T, V, D, generator=g), generator=g)
        opt.zero_grad()
        loss.backward()
        opt.step()
    assert set(parts) == {"ot_match", "ot_rank"}
    data, noise = data_latents(64, g), torch.randn(64, T, V, D, generator=g)
    assert pot(data).mean() < pot(noise).mean()

    for _ in range(100):
        neg = langevin_negatives(pot, torch.randn(32, T, V, D, generator=g), generator=g)
        loss, parts = contrastive_divergence_loss(pot, data_latents(32, g), neg)
        opt.zero_grad()
        loss.backward()
        opt.step()
    neg = langevin_negatives(pot, torch.randn(64, T, V, D, generator=g), generator=g)
    assert not neg.requires_grad
    with torch.no_grad():
        assert pot(data).mean() < pot(neg).mean() < pot(noise).mean()


def test_langevin_descends_without_noise():
    pot = LatentPotential(PotentialConfig(entities=V, latent_dim=D, hidden=16, layers=1, langevin_noise=0.0))
    z0 = 3.0 * torch.randn(4, T, V, D)
    z = langevin_negatives(pot, z0)
    assert (pot(z) < pot(z0)).all()


def test_lyapunov_loss_zero_for_descent_positive_otherwise():
    g = torch.randn(3, T, V, D)
    assert lyapunov_loss(g, -g, kappa=0.1) == 0
    assert lyapunov_loss(g, -0.5 * g + 0.01 * torch.randn_like(g), kappa=0.1) == 0
    assert lyapunov_loss(g, g, kappa=0.1) > 0
    assert lyapunov_loss(g, torch.zeros_like(g), kappa=0.1) > 0      # standing still misses the margin
    assert lyapunov_loss(g, -0.05 * g, kappa=0.1) > 0               # too weak a descent
    # It trains the velocity towards descent.
    v = torch.randn_like(g, requires_grad=True)
    lyapunov_loss(g, v).backward()
    assert (v.grad * g).sum() > 0  # the gradient step -v.grad moves v against grad V

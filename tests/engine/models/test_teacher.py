"""VP diffusion teacher: schedule, loss, PF velocity (its solver steps: tests/engine/sampling)."""
import torch

from engine.models.teacher import DiffusionTeacher, VPSchedule, pf_velocity
from engine.models.unet import TemporalUNet, UNetConfig
from tests.engine.fixtures import fake_conditioning

torch.set_num_threads(1)
TINY = UNetConfig(channels=(16, 16, 16, 16), embed_dim=32, heads=2)


def test_schedule_matches_ddpm_and_inverts():
    s = VPSchedule()
    tau = torch.linspace(0.001, 1, 100)
    assert torch.allclose(s.tau_from_log_alpha_bar(s.log_alpha_bar(tau)), tau, atol=1e-5)
    # continuous betas integrate to DDPM's linear 1e-4 .. 0.02 over 1000 steps
    assert abs(float(s.beta(torch.tensor(0.001))) / 1000 - 1.2e-4) < 3e-5
    assert float(s.alpha_bar(torch.tensor(1.0))) < 1e-4


def test_pf_velocity_formula():
    s = VPSchedule()
    z, tau = torch.randn(2, 4, 3, 8), torch.tensor([0.3, 0.7])
    eps = torch.randn_like(z)
    v = pf_velocity(lambda *a: eps, s, z, tau)
    abar = s.alpha_bar(tau)[:, None, None, None]
    beta = s.beta(tau)[:, None, None, None]
    assert torch.allclose(v, -0.5 * beta * (z - eps / (1 - abar).sqrt()), atol=1e-5)


def test_loss_decreases_when_overfitting():
    torch.manual_seed(0)
    teacher = DiffusionTeacher(TemporalUNet(TINY))
    z0 = torch.randn(4, 8, 3, 32) * 0.3 + 1.0
    cond = fake_conditioning(4, 8)
    opt = torch.optim.Adam(teacher.parameters(), 1e-2)
    losses = []
    for step in range(60):
        out = teacher.loss(z0, cond, generator=torch.Generator().manual_seed(0))  # one fixed draw
        opt.zero_grad()
        out["loss"].backward()
        opt.step()
        losses.append(out["loss"].item())
    assert losses[-1] < 0.6 * losses[0]

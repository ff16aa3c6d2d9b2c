"""VP diffusion teacher: schedule, loss, PF velocity, CFG wrapper, DDPM / DDIM generators."""
import torch

from engine.models.conditioning import Conditioning
from engine.models.teacher import (ClassifierFreeGuidance, DiffusionTeacher, VPSchedule, ddim_sample,
                                   ddpm_sample, pf_velocity, run_to_end)
from engine.models.unet import TemporalUNet, UNetConfig
from model_fixtures import fake_conditioning

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


def test_cfg_wrapper_semantics_and_single_batch():
    calls = []

    def field(z, t, cond, pos):
        calls.append(z.shape[0])
        keep = (~cond.drop).float()[:, None, None, None] if cond is not None and cond.drop is not None else 1.0
        return z * 0 + keep * cond.embed[:, :1, None, None] + 1.0  # cond: embed[0] + 1, uncond: 1

    cond = Conditioning(residual=torch.zeros(2, 4, 3, 8), temporal_bias=torch.zeros(2, 4, 4),
                        embed=torch.tensor([[2.0], [3.0]]))
    out = ClassifierFreeGuidance(field, weight=1.5)(torch.zeros(2, 4, 3, 8), torch.rand(2), cond)
    assert calls == [4]  # conditional and unconditional in one batch of 2B
    assert torch.allclose(out[0], torch.full_like(out[0], 1 + 1.5 * 2.0))
    assert torch.allclose(out[1], torch.full_like(out[1], 1 + 1.5 * 3.0))
    calls.clear()
    ClassifierFreeGuidance(field, weight=1.0)(torch.zeros(2, 4, 3, 8), torch.rand(2), cond)
    assert calls == [2]


def test_cfg_on_backbone_uses_dropped_branch():
    torch.manual_seed(0)
    teacher = DiffusionTeacher(TemporalUNet(TINY))
    for p in teacher.parameters():
        if p.abs().sum() == 0:
            torch.nn.init.normal_(p, 0, 0.1)
    z, tau, cond = torch.randn(2, 8, 3, 32), torch.rand(2), fake_conditioning(2, 8, d_model=128)
    eps_c, eps_u = teacher.eps(z, tau, cond), teacher.eps(z, tau, None)
    guided = ClassifierFreeGuidance(teacher.eps, 1.6)(z, tau, cond)
    assert torch.allclose(guided, eps_u + 1.6 * (eps_c - eps_u), atol=1e-4)


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


def test_ddim_is_deterministic_and_streams():
    torch.manual_seed(0)
    teacher = DiffusionTeacher(TemporalUNet(TINY)).eval()
    cond = fake_conditioning(1, 8)
    runs = []
    for _ in range(2):
        steps = list(ddim_sample(teacher.eps, teacher.schedule, (1, 8, 3, 32), num_steps=5, cond=cond,
                                 generator=torch.Generator().manual_seed(7)))
        assert [s.index for s in steps] == list(range(5)) and steps[-1].tau == 0.0
        runs.append(steps[-1].z)
    assert torch.equal(runs[0], runs[1])


def test_ddpm_recovers_a_point_mass_with_exact_eps():
    """With the exact noise predictor of data z0 = c, both samplers land on c."""
    s = VPSchedule(steps=100)
    c = 0.5

    def exact_eps(z, tau, cond, pos):
        abar = s.alpha_bar(tau)[:, None, None, None]
        return (z - abar.sqrt() * c) / (1 - abar).sqrt()

    g = torch.Generator().manual_seed(0)
    z = run_to_end(ddpm_sample(exact_eps, s, (2, 4, 3, 2), generator=g))
    assert torch.allclose(z, torch.full_like(z, c), atol=1e-3)
    z = run_to_end(ddim_sample(exact_eps, s, (2, 4, 3, 2), num_steps=10, generator=g))
    assert torch.allclose(z, torch.full_like(z, c), atol=1e-3)

"""Solver steps (rectified flow: Euler, Heun; VP diffusion: DDPM, DDIM) and classifier-free
guidance, each on its own, apart from the sampler's loop."""
import torch

from engine.models.conditioning import Conditioning
from engine.models.teacher import DiffusionTeacher, VPSchedule
from engine.models.unet import TemporalUNet, UNetConfig
from engine.sampling.cfg import ClassifierFreeGuidance
from engine.sampling.solvers import (ddim_step, ddim_times, ddpm_step, ddpm_times, euler_step, flow_clean_estimate,
                                     flow_renoise, flow_times, heun_step)
from tests.engine.fixtures import fake_conditioning

torch.set_num_threads(1)
TINY = UNetConfig(channels=(16, 16, 16, 16), embed_dim=32, heads=2)


def test_heun_is_exact_on_a_straight_path_and_euler_on_a_constant_field():
    """On z_t = (1 - t) z0 + t noise the velocity noise - z0 is constant: one step of either
    solver lands on z0, and the clean estimate and re-noising invert each other."""
    z0, noise = torch.randn(2, 4, 3, 8), torch.randn(2, 4, 3, 8)
    field = lambda z, t: noise - z0  # noqa: E731
    calls = []
    counted = lambda z, t: (calls.append(t), field(z, t))[1]  # noqa: E731
    assert torch.allclose(euler_step(field, noise, 1.0, 0.0), z0, atol=1e-6)
    z, v_end = heun_step(counted, noise, 1.0, 0.0)
    assert calls == [1.0, 0.0] and torch.allclose(z, z0, atol=1e-6)
    z_half = flow_renoise(z0, noise, 0.5)
    assert torch.allclose(flow_clean_estimate(z_half, field(z_half, 0.5), 0.5), z0, atol=1e-6)
    assert torch.allclose(torch.tensor(flow_times(3)), torch.tensor([1.0, 2 / 3, 1 / 3, 0.0]))


def test_heun_is_second_order_where_euler_is_first():
    """dz/dt = z: over one step from t = 1 to 0.9, Heun's error is far below Euler's."""
    field = lambda z, t: z  # noqa: E731
    z = torch.ones(1)
    exact = torch.exp(torch.tensor(-0.1))
    euler_error = (euler_step(field, z, 1.0, 0.9) - exact).abs()
    heun_error = (heun_step(field, z, 1.0, 0.9)[0] - exact).abs()
    assert heun_error < euler_error / 10


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


def test_cfg_gives_the_text_its_own_weight():
    """uncond + w (sketch - uncond) + w_text (sketch and text - sketch), in one batch of 3B; a
    storyboard without text, or w_text == w, is the plain guidance."""
    calls = []

    def field(z, t, cond, pos):   # uncond 1, the sketch adds embed[0], its text 10 per word
        calls.append(z.shape[0])
        keep = (~cond.drop).float()[:, None, None, None]
        words = cond.text_mask.sum(1)[:, None, None, None]
        return z * 0 + 1.0 + keep * (cond.embed[:, :1, None, None] + 10.0 * words)

    def conditioning(words):
        return Conditioning(residual=torch.zeros(2, 4, 3, 8), temporal_bias=torch.zeros(2, 4, 4),
                            embed=torch.tensor([[2.0], [3.0]]), drop=torch.zeros(2, dtype=torch.bool),
                            text=torch.zeros(2, 3, 4), text_mask=torch.tensor(words))

    z, t = torch.zeros(2, 4, 3, 8), torch.rand(2)
    out = ClassifierFreeGuidance(field, 1.5, text_weight=4.0)(z, t, conditioning([[1.0, 1.0, 0.0], [0.0, 0.0, 0.0]]))
    assert calls == [6]
    assert torch.allclose(out[0], torch.full_like(out[0], 1 + 1.5 * 2.0 + 4.0 * 20.0))
    assert torch.allclose(out[1], torch.full_like(out[1], 1 + 1.5 * 3.0))   # no text of its own
    calls.clear()
    out = ClassifierFreeGuidance(field, 1.0, text_weight=3.0)(z, t, conditioning([[1.0, 0.0, 0.0], [1.0, 0.0, 0.0]]))
    sketch = torch.tensor([2.0, 3.0])[:, None, None, None]
    assert calls == [4] and torch.allclose(out, torch.full_like(out, 1 + 3.0 * 10.0) + sketch)
    calls.clear()
    no_text = conditioning([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    plain = ClassifierFreeGuidance(field, 1.5)(z, t, no_text)
    assert torch.equal(ClassifierFreeGuidance(field, 1.5, text_weight=4.0)(z, t, no_text), plain)
    assert calls == [4, 4]


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


def test_ddim_is_deterministic():
    torch.manual_seed(0)
    teacher = DiffusionTeacher(TemporalUNet(TINY)).eval()
    cond = fake_conditioning(1, 8)
    runs = []
    for _ in range(2):
        z = torch.randn((1, 8, 3, 32), generator=torch.Generator().manual_seed(7))
        taus = ddim_times(5)
        for k in range(5):
            z, _ = ddim_step(lambda z, tau: teacher.eps(z, tau, cond), teacher.schedule, z, taus[k], taus[k + 1])
        assert float(taus[-1]) == 0.0
        runs.append(z)
    assert torch.equal(runs[0], runs[1])


def test_ddpm_recovers_a_point_mass_with_exact_eps():
    """With the exact noise predictor of data z0 = c, both samplers land on c."""
    s = VPSchedule(steps=100)
    c = 0.5

    def exact_eps(z, tau):
        abar = s.alpha_bar(tau)[:, None, None, None]
        return (z - abar.sqrt() * c) / (1 - abar).sqrt()

    g = torch.Generator().manual_seed(0)
    z = torch.randn((2, 4, 3, 2), generator=g)
    taus, abar = ddpm_times(s)
    for i in reversed(range(s.steps)):
        z, _, tau = ddpm_step(exact_eps, z, i, taus, abar, g)
    assert tau == 0.0 and torch.allclose(z, torch.full_like(z, c), atol=1e-3)
    z, taus = torch.randn((2, 4, 3, 2), generator=g), ddim_times(10)
    for k in range(10):
        z, _ = ddim_step(exact_eps, s, z, taus[k], taus[k + 1])
    assert torch.allclose(z, torch.full_like(z, c), atol=1e-3)

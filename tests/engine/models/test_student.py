"""Rectified-flow student: sub-field mixing, losses, the time map, loss composition."""
import pytest
import torch

from engine.models.student import (LossWeights, RectifiedFlowStudent, combine_losses, consistency_loss,
                                   draw_flow_sample, mix_subfields, phase1_losses, teacher_velocity_in_t, time_map,
                                   time_map_valid)
from engine.models.teacher import DiffusionTeacher, VPSchedule
from engine.models.unet import TemporalUNet, UNetConfig
from tests.engine.fixtures import fake_conditioning

torch.set_num_threads(1)
TINY = UNetConfig(channels=(16, 16, 16, 16), embed_dim=32, heads=2)


def test_mixing_by_occupancy():
    fields = torch.randn(2, 3, 8, 3, 4)
    assert torch.allclose(mix_subfields(fields), fields.mean(1))
    one_hot = torch.tensor([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])
    out = mix_subfields(fields, one_hot)
    assert torch.allclose(out[0], fields[0, 1]) and torch.allclose(out[1], fields[1, 0])
    per_frame = torch.zeros(2, 32, 3)  # frames (N = 4 T_lat) are averaged into latent steps
    per_frame[:, :16, 2] = 1.0
    per_frame[:, 16:, 0] = 1.0
    out = mix_subfields(fields, per_frame)
    assert torch.allclose(out[:, :4], fields[:, 2, :4]) and torch.allclose(out[:, 4:], fields[:, 0, 4:])


def test_time_map_is_monotone_and_in_range():
    s = VPSchedule()
    t = torch.linspace(0.02, 0.99, 200)
    tau = time_map(s, t)
    assert (tau[1:] > tau[:-1]).all() and time_map_valid(s, t).all()
    assert not time_map_valid(s, torch.tensor([0.0, 0.001, 0.999, 1.0])).any()


def test_converted_teacher_velocity_equals_rf_velocity_on_gaussian_data():
    """Data z0 ~ N(mu, s0^2): the exact VP noise predictor, carried through the time map and
    the chain rule, gives exactly the rectified-flow marginal velocity E[z1 - z0 | z_t]."""
    s = VPSchedule()
    mu, s0 = 0.7, 0.5

    def exact_eps(z, tau, cond, pos):
        abar = s.alpha_bar(tau)[:, None]
        a, sig = abar.sqrt(), (1 - abar).sqrt()
        return sig * (z - a * mu) / (a ** 2 * s0 ** 2 + sig ** 2)

    t = torch.linspace(0.01, 0.99, 60, dtype=torch.float64)
    t = t[time_map_valid(s, t)]
    z = torch.randn(len(t), 5, dtype=torch.float64)
    v = teacher_velocity_in_t(exact_eps, s, z, t)
    tt = t[:, None]
    var = (1 - tt) ** 2 * s0 ** 2 + tt ** 2
    dev = z - (1 - tt) * mu
    v_rf = tt * dev / var - (mu + (1 - tt) * s0 ** 2 * dev / var)
    assert torch.allclose(v, v_rf, atol=1e-9)
    z32 = z.float()  # and in float32, what training uses
    assert torch.allclose(teacher_velocity_in_t(exact_eps, s, z32, t.float()), v_rf.float(), atol=1e-3)


def _models():
    torch.manual_seed(0)
    teacher = DiffusionTeacher(TemporalUNet(TINY)).eval().requires_grad_(False)
    student = RectifiedFlowStudent(TemporalUNet(UNetConfig(**{**TINY.__dict__, "n_heads_out": 3})))
    return teacher, student


def test_phase1_overfit_and_teacher_frozen():
    teacher, student = _models()
    z0, cond = torch.randn(4, 8, 3, 32) * 0.3, fake_conditioning(4, 8)
    occ = torch.softmax(torch.randn(4, 32, 3), -1)
    opt = torch.optim.Adam(student.parameters(), 1e-2)
    losses = []
    for step in range(50):
        terms, _, _ = phase1_losses(student, teacher, z0, cond, occupancy=occ,
                                    generator=torch.Generator().manual_seed(0))  # one fixed draw
        loss = combine_losses(terms)
        opt.zero_grad()
        loss.backward()
        opt.step()
        losses.append(loss.item())
    # an untrained teacher's PF field disagrees with z1 - z0, so the joint optimum stays high
    assert losses[-1] < 0.9 * losses[0]
    assert all(p.grad is None for p in teacher.parameters())


def test_combine_losses_weights_and_unknown_terms():
    terms = {"rf": torch.tensor(1.0), "distill": torch.tensor(2.0), "lyap": torch.tensor(3.0),
             "ctmc": torch.tensor(4.0), "lat": torch.tensor(5.0)}
    assert float(combine_losses(terms)) == pytest.approx(1 + 0.5 * 2 + 0.5 * 3 + 0.1 * 4 + 0.1 * 5)
    assert float(combine_losses(terms, LossWeights(distill=0.0))) == pytest.approx(1 + 1.5 + 0.4 + 0.5)
    with pytest.raises(KeyError):
        combine_losses({"rf": torch.tensor(1.0), "distil": torch.tensor(1.0)})


def test_consistency_term():
    _, student = _models()
    z0, cond = torch.randn(2, 16, 3, 32), fake_conditioning(2, 16)
    sample = draw_flow_sample(z0, cond, torch.Generator().manual_seed(0))
    v = student.velocity(sample.z_t, sample.t, sample.cond)
    assert consistency_loss(student, sample, None, None, v, overlap=4).item() >= 0

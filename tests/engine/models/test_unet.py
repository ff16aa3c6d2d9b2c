"""Temporal U-Net backbone: shapes, conditioning routes, entity-distance bias."""

import torch

from engine.models.unet import TemporalUNet, UNetConfig, count_parameters
from tests.engine.fixtures import fake_conditioning

torch.set_num_threads(1)


def _randomize_zero_inits(model):
    """Zero-initialised output layers hide every route; give them weights for these tests."""
    torch.manual_seed(1)
    with torch.no_grad():
        for p in model.parameters():
            if p.dim() > 0 and p.abs().sum() == 0:
                p.normal_(0, 0.05)
    return model


def test_output_shape_and_heads():
    for heads in (1, 3):
        model = TemporalUNet(UNetConfig(n_heads_out=heads))
        out = model(torch.randn(2, 30, 3, 32), torch.rand(2), fake_conditioning(2, 30), torch.randn(2, 30, 3, 3))
        assert out.shape == (2, heads, 30, 3, 32)


def test_odd_lengths_and_no_conditioning():
    model = TemporalUNet()
    for t in (7, 16, 29):
        assert model(torch.randn(1, t, 3, 32), torch.tensor(0.5)).shape == (1, 1, t, 3, 32)


def test_default_size():
    n = count_parameters(TemporalUNet())
    assert 0.7e6 < n < 2.0e6
    assert count_parameters(TemporalUNet(UNetConfig.large())) > 3 * n


def test_dropped_conditioning_equals_none():
    model = _randomize_zero_inits(TemporalUNet())
    z, t = torch.randn(2, 30, 3, 32), torch.rand(2)
    cond = fake_conditioning(2, 30).dropped(torch.tensor([True, False]))
    out_cond, out_none = model(z, t, cond), model(z, t, None)
    zero = fake_conditioning(2, 30)
    zero.residual.zero_(); zero.temporal_bias.zero_(); zero.embed.zero_()
    assert torch.allclose(out_cond[0], model(z, t, zero)[0], atol=1e-5)
    assert not torch.allclose(out_cond[1], out_none[1], atol=1e-4)


def test_every_route_changes_output():
    model = _randomize_zero_inits(TemporalUNet())
    z, t = torch.randn(1, 30, 3, 32), torch.rand(1)
    cond, pos = fake_conditioning(1, 30), torch.randn(1, 30, 3, 3)
    base = model(z, t, cond, pos)
    for change in ("residual", "temporal_bias", "embed"):
        c2 = fake_conditioning(1, 30, seed=1)
        for other in ("residual", "temporal_bias", "embed"):
            if other != change:
                setattr(c2, other, getattr(cond, other))
        assert not torch.allclose(model(z, t, c2, pos), base, atol=1e-5), change
    assert not torch.allclose(model(z, t, cond, pos * 3), base, atol=1e-5)
    assert not torch.allclose(model(z, t + 0.3, cond, pos), base, atol=1e-5)


def test_batch_items_never_mix():
    model = _randomize_zero_inits(TemporalUNet())
    z, t = torch.randn(2, 30, 3, 32), torch.tensor([0.3, 0.3])
    z2 = z.clone()
    z2[1] += 1.0
    assert torch.allclose(model(z, t)[0], model(z2, t)[0], atol=1e-5)



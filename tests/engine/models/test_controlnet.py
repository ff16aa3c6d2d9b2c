"""Parallel ControlNet branches: a copy of the down path per condition type, zero at start,
nothing for a dropped sample, and the storyboard reaching the output only through them."""
import torch

from engine.models.controlnet import ParallelControlNets
from engine.models.unet import TemporalUNet, UNetConfig
from tests.engine.fixtures import fake_conditioning
from tests.engine.models.test_unet import _randomize_zero_inits

torch.set_num_threads(1)
CFG = UNetConfig(channels=(16, 24, 32, 32), embed_dim=32, heads=2, n_heads_out=3)


def _inputs(b=2, t=30):
    g = torch.Generator().manual_seed(3)
    return torch.randn(b, t, 3, 32, generator=g), torch.rand(b, generator=g), torch.randn(b, t, 3, 3, generator=g)


def test_levels_are_each_skip_then_the_bottleneck():
    net = TemporalUNet(UNetConfig(channels=(16, 24, 32, 32), embed_dim=32, heads=2, down_only=True))
    z, t, pos = _inputs()
    shapes = [tuple(x.shape) for x in net.levels(z, t, pos)]
    assert shapes == [(6, 30, 16), (6, 15, 24), (6, 8, 32), (6, 4, 32), (6, 4, 32)]
    assert not hasattr(net, "output")                 # a branch has no up path


def test_branches_start_at_zero_then_carry_the_storyboard():
    net = ParallelControlNets(CFG)
    z, t, pos = _inputs()
    cond = fake_conditioning(2, 30)
    plain = net.main(z, t, None, pos)
    assert torch.equal(net(z, t, cond, pos), plain)            # zero-initialised projections
    _randomize_zero_inits(net)
    plain = net.main(z, t, None, pos)
    assert not torch.allclose(net(z, t, cond, pos), plain)
    assert torch.equal(net(z, t, None, pos), plain)            # no storyboard: the main network alone


def test_a_dropped_sample_is_exactly_unconditional_and_its_neighbour_is_not_touched():
    net = _randomize_zero_inits(ParallelControlNets(CFG))
    z, t, pos = _inputs()
    cond = fake_conditioning(2, 30)
    both = net(z, t, cond, pos)
    one_dropped = net(z, t, cond.dropped(torch.tensor([True, False])), pos)
    assert torch.allclose(one_dropped[0], net.main(z, t, None, pos)[0], atol=1e-6)
    assert torch.allclose(one_dropped[1], both[1], atol=1e-6)


def test_only_the_branch_of_a_type_reads_that_type():
    net = _randomize_zero_inits(ParallelControlNets(CFG))
    z, t, pos = _inputs()
    cond = fake_conditioning(2, 30)
    before = net(z, t, cond, pos)
    cond.by_type[:, :, :, 1] += 1.0                            # change the trajectory maps
    net.branches["tr"].requires_grad_(False)
    with torch.no_grad():
        for p in net.branches["tr"].parameters():
            p.zero_()                                          # ... and silence the trajectory branch
        silenced = net(z, t, cond, pos)
        cond.by_type[:, :, :, 1] -= 1.0
        assert torch.allclose(net(z, t, cond, pos), silenced, atol=1e-6)
    assert not torch.allclose(before, silenced)

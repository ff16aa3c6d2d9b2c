"""The Sketch2Anim-INT network: raw motion features in and out, its loss, its conditioning."""
import torch

from engine.models.bundle import build_parts, untrained_bundle
from tests.engine.fixtures import FakeClips
from tests.engine.training.test_training import TINY_MODEL

torch.set_num_threads(1)


def _batch(n=2):
    items = [FakeClips(n)[i] for i in range(n)]
    return {k: torch.stack([it[k] for it in items]) for k in items[0]}


def test_raw_features_round_trip_to_the_same_motion():
    bundle = untrained_bundle(TINY_MODEL)
    model = build_parts(TINY_MODEL, ("sketch2anim",))["sketch2anim"]
    batch = _batch()
    x = model.features(bundle.vqvae, batch)
    assert x.shape == (2, batch["joints"].shape[1], 3, 201)
    assert torch.all(x[~batch["obj_present"].bool(), :, 2] == 0)      # an absent object is zero
    motion = model.motion(bundle.vqvae, x)
    assert torch.allclose(motion["joints"], batch["joints"], atol=1e-4)
    present = batch["obj_present"].bool()
    assert torch.allclose(motion["obj_anchors"][present], batch["obj_anchors"][present], atol=1e-4)


def test_loss_trains_the_branches_and_the_encoder():
    bundle = untrained_bundle(TINY_MODEL)
    model = build_parts(TINY_MODEL, ("sketch2anim",))["sketch2anim"]
    torch.nn.init.normal_(model.denoiser.backbone.main.output.weight, 0, 0.01)   # as after a first step
    terms = model.loss(bundle.vqvae, _batch(), torch.Generator().manual_seed(0))
    terms["loss"].backward()
    assert torch.isfinite(terms["loss"])
    exits = model.denoiser.backbone.branches["kf"].out[0].weight   # zero at start, as ControlNet's zero convs:
    assert exits.grad is not None and exits.grad.abs().sum() > 0   # their weights learn first
    assert model.denoiser.backbone.main.output.weight.grad.abs().sum() > 0


def test_the_noise_it_gives_the_solvers_comes_from_its_clean_motion():
    """Predicted clean (MDM's parameterization): DDIM's clean estimate from the derived noise is
    the network's clean motion, at any noise level."""
    model = build_parts(TINY_MODEL, ("sketch2anim",))["sketch2anim"]
    torch.nn.init.normal_(model.denoiser.backbone.main.output.weight, 0, 0.1)
    z, tau = torch.randn(2, 24, 3, 201), torch.tensor([0.05, 0.9])
    with torch.no_grad():
        clean, eps = model.denoiser.clean(z, tau), model.denoiser.eps(z, tau)
    abar = model.denoiser.schedule.alpha_bar(tau).reshape(-1, 1, 1, 1)
    assert torch.allclose((z - (1 - abar).sqrt() * eps) / abar.sqrt(), clean, atol=1e-4)

"""Entity VQ-VAE: shapes, object masking, residual codebooks with restarts, overfitting."""
import torch

from engine.models.vqvae import EntityVQVAE, VQVAEConfig, mean_joint_error
from tests.engine.fixtures import fake_batch

torch.set_num_threads(1)
SMALL = VQVAEConfig(channels=32, codebook_size=64)


def test_shapes_and_decode_layout():
    torch.manual_seed(0)
    model = EntityVQVAE(SMALL)
    batch = fake_batch(2)
    model.fit_normalizer(batch)
    z = model.encode(batch)
    assert z.shape == (2, 30, 3, SMALL.latent_dim)
    out = model.decode(z)
    assert out["joints"].shape == (2, 120, 2, 22, 3)
    assert out["rot6d"].shape == (2, 120, 2, 22, 6)
    assert out["obj_pose"].shape == (2, 120, 1, 7)
    assert out["obj_anchors"].shape == (2, 120, 1, SMALL.anchors_per_object, 3)
    assert torch.allclose(out["obj_pose"][..., 3:].norm(dim=-1), torch.ones(2, 120, 1), atol=1e-5)
    assert model.decode_lowres(z).shape == (2, 30, 3, 3)
    q = model.quantize(model.encode_continuous(batch))
    assert q.codes.shape == (2, 30, 3, SMALL.levels) and q.perplexity.shape == (SMALL.levels,)


def test_absent_object_is_ignored():
    torch.manual_seed(0)
    model = EntityVQVAE(SMALL).eval()
    batch = fake_batch(2)
    batch["obj_present"][:] = 0.0
    e1 = model.encode_continuous(batch)
    batch["obj_pose"] = batch["obj_pose"] + 5.0  # garbage in an absent slot changes nothing
    e2 = model.encode_continuous(batch)
    assert torch.equal(e1, e2)


def test_decoder_is_differentiable():
    model = EntityVQVAE(SMALL)
    z = torch.randn(1, 30, 3, SMALL.latent_dim, requires_grad=True)
    model.decode(z)["joints"].sum().backward()
    assert z.grad is not None and z.grad.abs().sum() > 0


def test_dead_codes_restart_on_data():
    torch.manual_seed(0)
    model = EntityVQVAE(SMALL)
    level = model.quantizer.levels[0]
    r = torch.randn(50, SMALL.latent_dim)
    level(r)
    level.codebook[:] = 100.0  # every code far from the data: all unused from now on
    level.usage[:] = 0.0
    level(r)
    # all codes but the one that took every assignment were dead and restart on data points
    assert int(level.restarts) >= len(level.codebook) - 1
    nearest = torch.cdist(level.codebook, r).min(1).values
    assert int((nearest < 0.1).sum()) >= len(level.codebook) - 1


def test_straight_through_passes_gradients_to_encoder():
    model = EntityVQVAE(SMALL)
    batch = fake_batch(2)
    model.fit_normalizer(batch)
    model.loss(batch)["loss"].backward()
    assert model.human_in.weight.grad.abs().sum() > 0


def test_overfit_reduces_joint_error():
    torch.manual_seed(0)
    model = EntityVQVAE(SMALL)
    batch = fake_batch(2)
    model.fit_normalizer(batch)
    opt = torch.optim.Adam(model.parameters(), 3e-3)
    first = None
    for _ in range(40):
        out = model.loss(batch)
        opt.zero_grad()
        out["loss"].backward()
        opt.step()
        first = first if first is not None else out["loss"].item()
    assert out["loss"].item() < 0.6 * first
    model.eval()
    rec = model.decode(model.encode(batch))
    assert float(mean_joint_error(rec["joints"], batch["joints"])) < 0.5  # metres


def test_latent_scale_calibration():
    model = EntityVQVAE(SMALL)
    batch = fake_batch(2)
    model.fit_normalizer(batch)
    model.calibrate_latent_scale(batch)
    assert abs(float(model.eval().encode(batch).std()) - 1.0) < 1e-3

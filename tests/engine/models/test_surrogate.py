"""Jacobian surrogate: layout of the motion flattening, block-Toeplitz structure, closed-form
fit against exact autograd VJPs of small fake decoders."""
import numpy as np
import pytest
import torch

from engine.models.surrogate import (DEFAULT_LAYOUT, JacobianSurrogate, SurrogateConfig, exact_latent_gradient,
                                     fit_surrogate, flatten_motion, gradient_cosine, init_from_jacobians,
                                     random_cotangents, surrogate_loss, unflatten_motion)
from engine.objects import NUM_ANCHORS

torch.set_num_threads(1)
T, STRIDE, V, D_LAT = 8, 4, 3, 8
N, D = T * STRIDE, DEFAULT_LAYOUT.dim


def toeplitz_decoder(seed: int = 0):
    """A linear decoder that is exactly block-Toeplitz: transposed conv, stride 4, reach +-1 step."""
    torch.manual_seed(seed)
    conv = torch.nn.ConvTranspose1d(V * D_LAT, D, kernel_size=3 * STRIDE, stride=STRIDE, padding=STRIDE)
    conv.requires_grad_(False)

    def decode(z):
        return conv(z.reshape(z.shape[0], T, V * D_LAT).transpose(1, 2)).transpose(1, 2)
    return decode


def small_surrogate(rank: int = V * D_LAT) -> JacobianSurrogate:
    return JacobianSurrogate(SurrogateConfig(frames=N, latent_steps=T, entities=V, latent_dim=D_LAT,
                                             rank=rank, bandwidth=1))


def test_flattening_matches_scene_layout():
    g = torch.Generator().manual_seed(0)
    motion = {"joints": torch.randn(2, 5, 2, 22, 3, generator=g), "rot6d": torch.randn(2, 5, 2, 22, 6, generator=g),
              "obj_pose": torch.randn(2, 5, 1, 7, generator=g), "obj_anchors": torch.randn(2, 5, 1, NUM_ANCHORS, 3, generator=g)}
    flat = flatten_motion(motion)
    assert flat.shape == (2, 5, DEFAULT_LAYOUT.dim)
    ref = DEFAULT_LAYOUT.flatten(motion["joints"][0].numpy(), motion["rot6d"][0].numpy(),
                                 motion["obj_pose"][0].numpy(), [motion["obj_anchors"][0, :, 0].numpy()])
    np.testing.assert_allclose(flat[0].numpy(), ref, rtol=1e-6)
    back = unflatten_motion(flat)
    for k in motion:
        assert torch.equal(back[k], motion[k])


def test_surrogate_is_block_toeplitz_and_banded():
    sur = small_surrogate(rank=4)
    assert sur(torch.zeros(1, N, D)).shape == (1, T, V, D_LAT)
    g = torch.zeros(1, N, D)
    g[0, 3 * STRIDE, 5] = 1.0                       # an impulse in frame group 3
    out = sur(g).abs().sum((-1, -2))[0]
    assert (out[[2, 3, 4]] > 0).all() and (out[[0, 1, 5, 6, 7]] == 0).all()
    g2 = torch.roll(g, STRIDE, 1)                   # shift by one group: response shifts by one step
    assert torch.allclose(sur(g2)[0, 3:6], sur(g)[0, 2:5], atol=1e-6)
    sur_full = JacobianSurrogate()                  # the production configuration
    assert sur_full(random_cotangents(1)).shape == (1, 30, 3, 32)


def test_closed_form_fit_recovers_a_toeplitz_decoder():
    decoder = toeplitz_decoder()
    latents = torch.randn(6, T, V, D_LAT)
    sur = small_surrogate()
    cot = random_cotangents(12, frames=N, generator=torch.Generator().manual_seed(1))
    assert gradient_cosine(sur, decoder, latents[:1].expand(12, -1, -1, -1), cot).mean() < 0.5
    init_from_jacobians(sur, decoder, latents[:2])
    cos = gradient_cosine(sur, decoder, latents[2:].repeat(3, 1, 1, 1), cot)
    assert cos.shape == (12,) and cos.min() > 0.99


def test_fit_on_nonlinear_decoder_and_refinement_does_not_hurt():
    lin = toeplitz_decoder(1)
    mix = torch.nn.Linear(D, D).requires_grad_(False)

    def decoder(z):
        return mix(torch.tanh(lin(z)))

    latents = torch.randn(8, T, V, D_LAT)
    sur = small_surrogate()
    init_from_jacobians(sur, decoder, latents[:3])
    cot = random_cotangents(10, frames=N, generator=torch.Generator().manual_seed(2))
    before = gradient_cosine(sur, decoder, latents[3:5].repeat(5, 1, 1, 1), cot).mean()
    assert before > 0.9
    history = fit_surrogate(sur, decoder, latents, steps=20, batch=4)
    assert len(history) == 20 and np.isfinite(history).all()
    after = gradient_cosine(sur, decoder, latents[3:5].repeat(5, 1, 1, 1), cot).mean()
    assert after > before - 0.02


def test_surrogate_loss_trains_only_the_surrogate():
    decoder = toeplitz_decoder()
    sur = small_surrogate(rank=4)
    z = torch.randn(2, T, V, D_LAT)
    cot = random_cotangents(2, frames=N, generator=torch.Generator().manual_seed(3))
    loss = surrogate_loss(sur, decoder, z, cot)
    loss.backward()
    assert sur.down.grad is not None and loss > 0
    exact = exact_latent_gradient(decoder, z, cot)
    assert exact.shape == z.shape and not exact.requires_grad


def test_any_length_in_whole_frame_groups():
    """Block-Toeplitz: a short clip's gradient maps like the same gradient zero-padded to the
    training length."""
    sur = JacobianSurrogate()
    short = torch.randn(2, 40, sur.cfg.motion_dim, generator=torch.Generator().manual_seed(1))
    padded = torch.cat([short, short.new_zeros(2, 80, sur.cfg.motion_dim)], 1)
    with torch.no_grad():
        assert torch.allclose(sur(short), sur(padded)[:, :10], atol=1e-5)
    with pytest.raises(ValueError, match="multiple of 4 frames"):
        sur(torch.randn(1, 41, sur.cfg.motion_dim))

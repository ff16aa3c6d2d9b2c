"""Jacobian surrogate B_rho ~ (dD/dz)^T: routes motion-space energy gradients to the latent
(paper Sec. 3, u_raw = -B_rho grad_M sum_r lambda_r E_r).

The decoder upsamples time by a stride s = N / T_lat, so frames s q .. s q + s - 1 ("frame
group" q) come mostly from latent steps near q. B_rho is block-Toeplitz over groups: the latent
gradient at step q is sum over offsets o in [-w, w] of U_o V_o^T g[q + o], with g[p] the motion
gradient of group p flattened to s * D numbers and U_o V_o^T a rank-r block that is the same
for every q. It is one fixed linear map (it does not depend on z): cheap every solver step and
stable, where autograd through D would cost a decoder backward and follow its local wiggles.

Motion flattening (D numbers per frame) follows engine.state_vector.SceneLayout:
[human 0: per joint (xyz, rot6d) | human 1 ... | object poses (7 each) | object anchors (K*3 each)].

For the trainer:
  surrogate_loss(surrogate, decoder, z, cotangent) -> scalar   relative L2 to the exact VJP
  random_cotangents(batch, layout, frames, generator) -> (B, N, D)   dense / keyframe / smooth mix
  init_from_jacobians(surrogate, decoder, latents)   closed form: averaged Jacobian blocks + SVD
  fit_surrogate(surrogate, decoder, latents, steps) -> list of losses   Adam refinement on VJPs
  gradient_cosine(surrogate, decoder, z, cotangent) -> (B,)   the acceptance check (>= 0.9)
`decoder` is any callable z (B, T_lat, V, d) -> motion dict (EntityVQVAE.decode) or (B, N, D).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import torch
import torch.autograd.forward_ad as fwAD
import torch.nn.functional as F
from torch import nn

from ..objects import NUM_ANCHORS
from ..skeleton import NUM_JOINTS
from ..state_vector import HUMAN_DIM, SceneLayout

Decoder = Callable[[torch.Tensor], "dict[str, torch.Tensor] | torch.Tensor"]
DEFAULT_LAYOUT = SceneLayout(num_humans=2, anchors_per_object=(NUM_ANCHORS,))


def flatten_motion(motion: dict[str, torch.Tensor]) -> torch.Tensor:
    """Motion dict -> (B, N, D) in SceneLayout order.

    joints (B, N, H, 22, 3), rot6d (B, N, H, 22, 6), obj_pose (B, N, O, 7) and
    obj_anchors (B, N, O, K, 3) (the object entries may be absent for human-only scenes).
    """
    b, n = motion["joints"].shape[:2]
    parts = [torch.cat([motion["joints"], motion["rot6d"]], -1).reshape(b, n, -1)]
    if "obj_pose" in motion and motion["obj_pose"].shape[2] > 0:
        parts += [motion["obj_pose"].reshape(b, n, -1), motion["obj_anchors"].reshape(b, n, -1)]
    return torch.cat(parts, -1)


def unflatten_motion(flat: torch.Tensor, layout: SceneLayout = DEFAULT_LAYOUT) -> dict[str, torch.Tensor]:
    """(B, N, D) -> motion dict (inverse of flatten_motion; objects share one anchor count)."""
    b, n, _ = flat.shape
    h, o = layout.num_humans, layout.num_objects
    hum = flat[..., :h * HUMAN_DIM].reshape(b, n, h, NUM_JOINTS, 9)
    out = {"joints": hum[..., :3], "rot6d": hum[..., 3:]}
    if o:
        k = layout.anchors_per_object[0]
        off = h * HUMAN_DIM
        out["obj_pose"] = flat[..., off:off + 7 * o].reshape(b, n, o, 7)
        out["obj_anchors"] = flat[..., off + 7 * o:].reshape(b, n, o, k, 3)
    return out


@dataclass
class SurrogateConfig:
    frames: int = 120          # N
    latent_steps: int = 30     # T_lat (N must be a multiple)
    entities: int = 3          # V
    latent_dim: int = 32       # d
    motion_dim: int = DEFAULT_LAYOUT.dim  # D = 415 for 2 humans + 1 object with 4 anchors
    # A map that does not depend on z reaches a held-out gradient cosine near 0.9 whatever r and w
    # (rank 96: +0.0004, bandwidth 3: +0.003, measured): the decoder's Jacobian varies with z.
    rank: int = 64             # r per offset block (of V*d = 96)
    bandwidth: int = 2         # w: offsets -w..w latent steps


class JacobianSurrogate(nn.Module):
    """B_rho: motion gradient (B, N, D) -> latent gradient (B, N / stride, V, d) for any N that is a
    multiple of the stride (cfg.frames / cfg.latent_steps)."""

    def __init__(self, cfg: SurrogateConfig | None = None):
        super().__init__()
        cfg = cfg or SurrogateConfig()
        if cfg.frames % cfg.latent_steps:
            raise ValueError(f"frames {cfg.frames} must be a multiple of latent_steps {cfg.latent_steps}")
        self.cfg = cfg
        self.stride = cfg.frames // cfg.latent_steps
        offsets = 2 * cfg.bandwidth + 1
        group = self.stride * cfg.motion_dim
        # V_o for every offset side by side: one matmul projects each frame group to all offsets.
        self.down = nn.Parameter(torch.randn(group, offsets * cfg.rank) / group ** 0.5)
        self.up = nn.Parameter(torch.randn(offsets, cfg.rank, cfg.entities * cfg.latent_dim)
                               / (offsets * cfg.rank) ** 0.5)

    def forward(self, grad_motion: torch.Tensor | dict[str, torch.Tensor]) -> torch.Tensor:
        g = flatten_motion(grad_motion) if isinstance(grad_motion, dict) else grad_motion
        cfg, w = self.cfg, self.cfg.bandwidth
        b, n, dim = g.shape
        # Block-Toeplitz: the same blocks at every latent step, so any clip length in whole frame
        # groups works, not only the training length.
        if dim != cfg.motion_dim or n % self.stride:
            raise ValueError(f"expected motion gradient (B, a multiple of {self.stride} frames, {cfg.motion_dim}), "
                             f"got {tuple(g.shape)}")
        t = n // self.stride
        a = (g.reshape(b, t, -1) @ self.down).reshape(b, t, 2 * w + 1, cfg.rank)
        a = F.pad(a, (0, 0, 0, 0, w, w))                      # zero groups beyond both ends
        # Offset i (o = i - w) reads group q + o, which sits at padded index q + i.
        shifted = torch.stack([a[:, i:i + t, i] for i in range(2 * w + 1)], 2)   # (B, T, K, r)
        out = torch.einsum("btkr,krc->btc", shifted, self.up)
        return out.reshape(b, t, cfg.entities, cfg.latent_dim)


# ---- exact gradients and training ---------------------------------------------------------

def _decode_flat(decoder: Decoder, z: torch.Tensor) -> torch.Tensor:
    out = decoder(z)
    return flatten_motion(out) if isinstance(out, dict) else out


def exact_latent_gradient(decoder: Decoder, z: torch.Tensor, cotangent: torch.Tensor) -> torch.Tensor:
    """Autograd VJP (dD/dz)^T cotangent at z: z (B, T_lat, V, d), cotangent (B, N, D) -> like z."""
    with torch.enable_grad():
        z = z.detach().requires_grad_(True)
        (grad,) = torch.autograd.grad(_decode_flat(decoder, z), z, cotangent)
    return grad


def surrogate_loss(surrogate: JacobianSurrogate, decoder: Decoder, z: torch.Tensor,
                   cotangent: torch.Tensor) -> torch.Tensor:
    """Mean over samples of ||B_rho c - (dD/dz)^T c||^2 / ||(dD/dz)^T c||^2 (relative, so sparse
    energy-like cotangents weigh as much as dense ones). The decoder gets no gradient."""
    exact = exact_latent_gradient(decoder, z, cotangent).flatten(1)
    pred = surrogate(cotangent).flatten(1)
    return ((pred - exact).pow(2).sum(1) / exact.pow(2).sum(1).clamp_min(1e-12)).mean()


def gradient_cosine(surrogate: JacobianSurrogate, decoder: Decoder, z: torch.Tensor,
                    cotangent: torch.Tensor) -> torch.Tensor:
    """Cosine similarity per sample (B,) of the surrogate-routed and the exact latent gradient."""
    exact = exact_latent_gradient(decoder, z, cotangent).flatten(1)
    with torch.no_grad():
        pred = surrogate(cotangent).flatten(1)
    return F.cosine_similarity(pred, exact, dim=1)


def random_cotangents(batch: int, layout: SceneLayout = DEFAULT_LAYOUT, frames: int = 120,
                      generator: torch.Generator | None = None) -> torch.Tensor:
    """(B, N, D) motion-space cotangents, each sample one of three kinds at random:
    dense Gaussian; keyframe-like (joint positions of a few joints at 1-4 frames, as E_key's
    gradient); smooth (low-frequency in time on a few channels, as trajectory/contact terms)."""
    g = generator
    device = g.device if g is not None else torch.device("cpu")   # draws where the generator lives
    dim = layout.dim
    out = torch.zeros(batch, frames, dim, device=device)
    positions = torch.tensor([h * HUMAN_DIM + j * 9 + c for h in range(layout.num_humans)
                              for j in range(NUM_JOINTS) for c in range(3)], device=device)
    time = torch.linspace(0, 1, frames, device=device)
    for i in range(batch):
        kind = int(torch.randint(3, (1,), generator=g, device=device))
        if kind == 0:
            out[i] = torch.randn(frames, dim, generator=g, device=device)
        elif kind == 1:
            count = int(torch.randint(1, 5, (1,), generator=g, device=device))
            at = torch.randint(frames, (count,), generator=g, device=device)
            joints = positions.view(-1, 3)[torch.randperm(len(positions) // 3, generator=g, device=device)[:6]].flatten()
            out[i, at[:, None], joints[None]] = torch.randn(len(at), len(joints), generator=g, device=device)
        else:
            chans = torch.randperm(dim, generator=g, device=device)[:24]
            freq = torch.rand(3, 1, generator=g, device=device) * 4.0
            phase = torch.rand(3, 1, generator=g, device=device) * 6.283
            wave = torch.cos(6.283 * freq * time[None] + phase)               # (3, N)
            out[i, :, chans] = (torch.randn(len(chans), 3, generator=g, device=device) @ wave).T
    return out


@torch.no_grad()
def mean_jacobian_blocks(decoder: Decoder, latents: torch.Tensor, bandwidth: int) -> torch.Tensor:
    """Toeplitz blocks of the decoder Jacobian averaged over latents and latent steps.

    latents (M, T_lat, V, d) -> A (2w+1, s*D, V*d) with A[o + w] = mean_q d(frame group q+o)/d z[q].
    Forward-mode JVPs perturb one latent channel at every `spacing`-th step at once (far enough
    apart that their responses do not overlap within the band): V*d*spacing JVPs per latent.
    """
    m, t, v, d = latents.shape
    w, spacing = bandwidth, 2 * (2 * bandwidth + 1)
    channels = v * d
    blocks, counts = None, torch.zeros(2 * w + 1)
    for z in latents:
        for start in range(min(spacing, t)):
            steps = torch.arange(start, t, spacing)
            tangent = torch.zeros(channels, t, channels)
            tangent[:, steps] = torch.eye(channels)[:, None]
            z_rep = z[None].expand(channels, t, v, d).contiguous()
            with fwAD.dual_level():
                dual = fwAD.make_dual(z_rep, tangent.reshape(channels, t, v, d))
                out = fwAD.unpack_dual(_decode_flat(decoder, dual)).tangent
            groups = out.reshape(channels, t, -1)                           # (V*d, T_lat, s*D)
            if blocks is None:
                blocks = torch.zeros(2 * w + 1, groups.shape[-1], channels)
            for i in range(2 * w + 1):
                valid = steps[(steps + i - w >= 0) & (steps + i - w < t)]
                blocks[i] += groups[:, valid + i - w].sum(1).T
                counts[i] += len(valid)
    return blocks / counts.clamp_min(1.0)[:, None, None]


@torch.no_grad()
def init_from_jacobians(surrogate: JacobianSurrogate, decoder: Decoder, latents: torch.Tensor) -> None:
    """Closed-form fit: the Toeplitz average of the decoder Jacobian, truncated to rank r per
    offset by SVD. This minimises the expected error for isotropic cotangents (Eckart-Young);
    fit_surrogate can refine it on energy-like cotangents."""
    cfg = surrogate.cfg
    blocks = mean_jacobian_blocks(decoder, latents, cfg.bandwidth)          # (K, s*D, V*d)
    u, sv, vh = torch.linalg.svd(blocks, full_matrices=False)
    r = min(cfg.rank, sv.shape[-1])
    root = sv[:, :r].sqrt()
    down = torch.zeros(blocks.shape[0], blocks.shape[1], cfg.rank)
    up = torch.zeros(blocks.shape[0], cfg.rank, blocks.shape[2])
    down[..., :r] = u[..., :r] * root[:, None]
    up[:, :r] = root[..., None] * vh[:, :r]
    surrogate.down.copy_(down.permute(1, 0, 2).reshape(blocks.shape[1], -1))
    surrogate.up.copy_(up)


def fit_surrogate(surrogate: JacobianSurrogate, decoder: Decoder, latents: torch.Tensor, steps: int = 500,
                  batch: int = 16, lr: float = 1e-5, layout: SceneLayout = DEFAULT_LAYOUT,
                  seed: int = 0) -> list[float]:
    """Regress the surrogate on exact VJPs at latents (M, T_lat, V, d) with random cotangents.
    Meant as a refinement after init_from_jacobians (hence the small learning rate: larger
    Adam steps wreck the closed-form fit before they improve it). Returns the loss history."""
    g = torch.Generator().manual_seed(seed)
    opt = torch.optim.Adam(surrogate.parameters(), lr=lr)
    history = []
    for _ in range(steps):
        idx = torch.randint(latents.shape[0], (batch,), generator=g)
        cot = random_cotangents(batch, layout, surrogate.cfg.frames, g)
        loss = surrogate_loss(surrogate, decoder, latents[idx], cot)
        opt.zero_grad()
        loss.backward()
        opt.step()
        history.append(loss.item())
    return history

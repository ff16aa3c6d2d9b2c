"""The shared embedding space of sketch and motion (paper section 3.1): the contrastive alignment
of the 2D and 3D condition encoders, and the latent projection head f_gamma that grounds a
motion latent in that space (its regression E_lat is the sampler's latent energy)."""
from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import nn

from .encoders import CONDITION_TYPES, TIME_FREQUENCIES, EncoderConfig, time_features

# ---- losses in the shared embedding space --------------------------------------------------

def info_nce(a: torch.Tensor, b: torch.Tensor, temperature: float,
             valid: torch.Tensor | None = None) -> torch.Tensor:
    """Symmetric mini-batch InfoNCE between paired rows of a and b (B, d_e): row i of a should
    be closest to row i of b. Only rows with valid (B,) take part; zero with fewer than two."""
    if valid is not None:
        a, b = a[valid], b[valid]
    if a.shape[0] < 2:
        return a.sum() * 0.0 + b.sum() * 0.0
    logits = F.normalize(a, dim=-1) @ F.normalize(b, dim=-1).T / temperature
    labels = torch.arange(a.shape[0], device=a.device)
    return 0.5 * (F.cross_entropy(logits, labels) + F.cross_entropy(logits.T, labels))


def _masked_mean(x: torch.Tensor, valid: torch.Tensor) -> torch.Tensor:
    w = valid.to(x.dtype)
    return (x * w).sum() / w.sum().clamp_min(1.0)


def alignment_loss(s2d: dict, s3d: dict, present: dict, cfg: EncoderConfig) -> tuple[torch.Tensor, dict]:
    """L_align = sum_y ||s3D_y - s2D_y||^2 + lambda_c InfoNCE(y), over samples that have y.
    Embeddings {y: (B, d_e)}; present {y: (B,) bool}. Returns (loss, {name: value})."""
    parts = {}
    for y in CONDITION_TYPES:
        parts[f"align_l2_{y}"] = _masked_mean((s3d[y] - s2d[y]).pow(2).sum(-1), present[y])
        parts[f"align_nce_{y}"] = info_nce(s2d[y], s3d[y], cfg.temperature, present[y])
    loss = sum(parts[f"align_l2_{y}"] + cfg.lambda_nce * parts[f"align_nce_{y}"] for y in CONDITION_TYPES)
    return loss, parts


# ---- latent projection head f_gamma ---------------------------------------------------------

class LatentProjectionHead(nn.Module):
    """f_gamma: latent z (B, T_lat, V, d) -> {y: (B, d_e)} unit vectors in the shared space.

    One trunk with a head per condition type: a single output matched to all three targets (as
    the paper's sum over y reads literally) would be pulled to their mean. Per-token MLP with
    time and entity features, then mean and max pooling (so when things happen survives)."""

    def __init__(self, cfg: EncoderConfig | None = None, max_entities: int = 8):
        super().__init__()
        cfg = cfg or EncoderConfig()
        self.cfg = cfg
        self.entity = nn.Parameter(0.1 * torch.randn(max_entities, cfg.hidden))
        self.inp = nn.Linear(cfg.latent_dim + 2 * TIME_FREQUENCIES, cfg.hidden)
        self.mix = nn.Linear(cfg.hidden, cfg.hidden)
        self.heads = nn.Linear(2 * cfg.hidden, len(CONDITION_TYPES) * cfg.d_e)

    def forward(self, z: torch.Tensor) -> dict[str, torch.Tensor]:
        b, t, v, _ = z.shape
        tf = time_features(torch.linspace(0.0, 1.0, t, device=z.device, dtype=z.dtype))
        x = torch.cat([z, tf[None, :, None].expand(b, t, v, -1)], -1)
        x = F.silu(self.inp(x) + self.entity[:v])
        x = F.silu(self.mix(x)).reshape(b, t * v, -1)
        out = self.heads(torch.cat([x.mean(1), x.amax(1)], -1)).reshape(b, len(CONDITION_TYPES), -1)
        out = F.normalize(out, dim=-1)
        return {y: out[:, i] for i, y in enumerate(CONDITION_TYPES)}


def latent_alignment_loss(head: LatentProjectionHead, z: torch.Tensor, s3d: dict, present: dict,
                          cfg: EncoderConfig) -> tuple[torch.Tensor, dict]:
    """L_lat = sum_y ||f_gamma(z)_y - sg[s3D_y]||^2 + lambda_NCE InfoNCE(f_gamma(z)_y, sg[s3D_y]).
    z (B, T_lat, V, d) clean (data) latents; s3d {y: (B, d_e)}; present {y: (B,) bool}."""
    f = head(z)
    parts = {}
    for y in CONDITION_TYPES:
        target = s3d[y].detach()
        parts[f"lat_l2_{y}"] = _masked_mean((f[y] - target).pow(2).sum(-1), present[y])
        parts[f"lat_nce_{y}"] = info_nce(f[y], target, cfg.temperature, present[y])
    loss = sum(parts[f"lat_l2_{y}"] + cfg.lambda_nce * parts[f"lat_nce_{y}"] for y in CONDITION_TYPES)
    return loss, parts


def latent_energy(head: LatentProjectionHead, z: torch.Tensor, s2d: dict,
                  present: dict | None = None) -> torch.Tensor:
    """E_lat(z) = sum_y ||f_gamma(z)_y - s2D_y||^2 over the condition types the storyboard has.
    z (B, T_lat, V, d), s2d {y: (B, d_e)} -> (B,). Differentiable in z (u_lat = -grad E_lat)."""
    f = head(z)
    total = z.new_zeros(z.shape[0])
    for y in CONDITION_TYPES:
        e = (f[y] - s2d[y]).pow(2).sum(-1)
        total = total + (e if present is None else e * present[y].to(e.dtype))
    return total

"""Temporal U-Net over the entity latent (T_lat, V, d): the backbone of teacher and student.

Four levels halve time (30 -> 15 -> 8 -> 4 latent steps). Each level has a residual block of
temporal convolutions (per entity, FiLM-modulated by the time + storyboard embedding) and an
attention block: local temporal self-attention within each entity (a window of +-`window`
steps, plus Conditioning.temporal_bias resampled to the level's length) followed by
entity-graph attention across the V tokens of each latent step, whose logits subtract
lambda_h * pairwise entity distance (metres, from VQ-VAE decode_lowres; lambda_h >= 0 per head).
Conditioning.residual is projected once and pooled to each level's length, then added after the
level's residual block on the way down. With `text_dim`, the bottleneck cross-attends to the
storyboard text and the words' mean joins the time embedding (models/text.py). The network only maps tensors to tensors; what the
output means (noise, velocity sub-fields) belongs to the teacher and the student.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import torch
import torch.nn.functional as F
from torch import nn

from .conditioning import Conditioning
from .text import TextCrossAttention, pooled_text


@dataclass
class UNetConfig:
    latent_dim: int = 32                          # d of the VQ-VAE latent
    entities: int = 3                             # V
    channels: tuple[int, ...] = (48, 64, 96, 128)  # per level; 4 levels
    embed_dim: int = 128                          # time + storyboard embedding
    heads: int = 4
    window: int = 4                               # local temporal attention radius in steps
    attention_levels: tuple[int, ...] = (1, 2, 3)  # levels (0 = finest) with attention on the
                                                  # way down; the bottleneck always has one
    distance_lambda: float = 1.0                  # initial lambda of the entity-distance bias
    cond_dim: int = 128                           # Conditioning.residual feature size d_model
    cond_embed_dim: int = 256                     # Conditioning.embed size d_e
    n_heads_out: int = 1                          # output fields: 1 teacher, S = 3 student
    down_only: bool = False                       # no up path: a ControlNet branch (models/controlnet.py)
    text_dim: int = 0                             # Conditioning.text width; 0: no text cross-attention

    @classmethod
    def default(cls, **kw) -> "UNetConfig":
        """~1M parameters, ~5 ms per batch-2 forward on 2 CPU cores."""
        return cls(**kw)

    @classmethod
    def large(cls, **kw) -> "UNetConfig":
        """For GPU training: ~4x wider."""
        return cls(**{"channels": (128, 192, 256, 320), "embed_dim": 384, "heads": 8, **kw})


def timestep_embedding(t: torch.Tensor, dim: int) -> torch.Tensor:
    """t (B,) in [0, 1] -> (B, dim) sinusoidal features (t scaled by 1000 as in DDPM)."""
    half = dim // 2
    freqs = torch.exp(-math.log(10000.0) * torch.arange(half, device=t.device, dtype=t.dtype) / half)
    angles = 1000.0 * t[:, None] * freqs[None]
    return torch.cat([angles.sin(), angles.cos()], -1)


class TemporalConv(nn.Module):
    """Kernel-3 convolution over time in channels-last layout, as one matmul over the three
    shifted copies: several times faster than conv1d at these tiny sizes on CPU.
    stride 2 gives ceil(T / 2) outputs."""

    def __init__(self, c_in: int, c_out: int, stride: int = 1):
        super().__init__()
        self.stride = stride
        self.linear = nn.Linear(3 * c_in, c_out)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """x (M, T, C_in) -> (M, T', C_out)."""
        t, s = x.shape[1], self.stride
        p = F.pad(x, (0, 0, 1, 1))
        n = (t + s - 1) // s
        span = s * (n - 1) + 1
        return self.linear(torch.cat([p[:, 0:span:s], p[:, 1:span + 1:s], p[:, 2:span + 2:s]], -1))


class ResBlock(nn.Module):
    """Two temporal convs per entity; FiLM (scale, shift) from the embedding between them."""

    def __init__(self, c_in: int, c_out: int):
        super().__init__()
        self.norm1 = nn.LayerNorm(c_in)
        self.norm2 = nn.LayerNorm(c_out, elementwise_affine=False)  # FiLM supplies the affine
        self.conv1, self.conv2 = TemporalConv(c_in, c_out), TemporalConv(c_out, c_out)
        nn.init.zeros_(self.conv2.linear.weight)
        nn.init.zeros_(self.conv2.linear.bias)
        self.skip = nn.Linear(c_in, c_out) if c_in != c_out else nn.Identity()
        self.film_size = 2 * c_out

    def forward(self, x: torch.Tensor, film: torch.Tensor) -> torch.Tensor:
        """x (B*V, T, C_in), film (B*V, 2 C_out) -> (B*V, T, C_out)."""
        h = self.conv1(F.silu(self.norm1(x)))
        scale, shift = film[:, None].chunk(2, -1)
        return self.skip(x) + self.conv2(F.silu(torch.addcmul(shift, self.norm2(h), 1 + scale)))


class EntityTemporalAttention(nn.Module):
    """Windowed temporal self-attention per entity, then distance-biased attention across entities."""

    def __init__(self, channels: int, heads: int, distance_lambda: float):
        super().__init__()
        self.heads = heads
        self.norm_t, self.norm_e = nn.LayerNorm(channels), nn.LayerNorm(channels)
        self.qkv_t, self.qkv_e = nn.Linear(channels, 3 * channels), nn.Linear(channels, 3 * channels)
        self.out_t, self.out_e = nn.Linear(channels, channels), nn.Linear(channels, channels)
        for lin in (self.out_t, self.out_e):
            nn.init.zeros_(lin.weight)
            nn.init.zeros_(lin.bias)
        # softplus^-1(lambda): lambda stays >= 0 so nearer entities always get more attention
        self.lambda_raw = nn.Parameter(torch.full((heads,), math.log(math.expm1(distance_lambda))))

    def _attend(self, x, norm, qkv, out, bias):
        """x (M, L, C), bias broadcastable to (M, heads, L, L) or None."""
        m, length, c = x.shape
        q, k, v = qkv(norm(x)).reshape(m, length, 3, self.heads, c // self.heads).permute(2, 0, 3, 1, 4)
        y = F.scaled_dot_product_attention(q, k, v, attn_mask=bias)
        return x + out(y.transpose(1, 2).reshape(m, length, c))

    def forward(self, x: torch.Tensor, entities: int, temporal_bias: torch.Tensor,
                distance: torch.Tensor | None) -> torch.Tensor:
        """x (B*V, T, C); temporal_bias (B, T, T) incl. the window mask;
        distance (B, T, V, V) metres or None. Returns (B*V, T, C)."""
        bv, t, c = x.shape
        b = bv // entities
        bias_t = temporal_bias[:, None, None].expand(b, entities, 1, t, t).reshape(bv, 1, t, t)
        h = self._attend(x, self.norm_t, self.qkv_t, self.out_t, bias_t)
        h = h.reshape(b, entities, t, c).transpose(1, 2).reshape(b * t, entities, c)
        bias_e = None
        if distance is not None:
            lam = F.softplus(self.lambda_raw)[None, :, None, None]
            bias_e = -lam * distance.reshape(b * t, 1, entities, entities)
        h = self._attend(h, self.norm_e, self.qkv_e, self.out_e, bias_e)
        return h.reshape(b, t, entities, c).transpose(1, 2).reshape(bv, t, c)


class TemporalUNet(nn.Module):
    def __init__(self, cfg: UNetConfig | None = None):
        super().__init__()
        self.cfg = cfg = cfg or UNetConfig()
        ch, e = cfg.channels, cfg.embed_dim
        self.input = TemporalConv(cfg.latent_dim, ch[0])
        self.entity_embed = nn.Parameter(torch.zeros(cfg.entities, 1, ch[0]))
        self.time_mlp = nn.Sequential(nn.Linear(ch[0], e), nn.SiLU(), nn.Linear(e, e))
        self.cond_embed = nn.Linear(cfg.cond_embed_dim, e)
        self.cond_residual = nn.Linear(cfg.cond_dim, sum(ch))
        nn.init.zeros_(self.cond_residual.weight)
        nn.init.zeros_(self.cond_residual.bias)

        self.down_blocks, self.downsample = nn.ModuleList(), nn.ModuleList()
        self.down_attn = nn.ModuleDict()
        for i, c in enumerate(ch):  # the input conv and each downsample already set the width
            self.down_blocks.append(ResBlock(c, c))
            if i in cfg.attention_levels:
                self.down_attn[str(i)] = EntityTemporalAttention(c, cfg.heads, cfg.distance_lambda)
            if i < len(ch) - 1:
                self.downsample.append(TemporalConv(c, ch[i + 1], stride=2))
        c_prev = ch[-1]
        self.mid_block = ResBlock(ch[-1], ch[-1])
        self.mid_attn = EntityTemporalAttention(ch[-1], cfg.heads, cfg.distance_lambda)
        if cfg.text_dim:
            self.text_attn = TextCrossAttention(ch[-1], cfg.text_dim, cfg.heads)
            self.text_embed = nn.Linear(cfg.text_dim, e)
            nn.init.zeros_(self.text_embed.weight)
            nn.init.zeros_(self.text_embed.bias)
        self.up_blocks, self.upsample = nn.ModuleList(), nn.ModuleList()
        if not cfg.down_only:
            for i in reversed(range(len(ch))):
                self.up_blocks.append(ResBlock(c_prev + ch[i], ch[i]))
                if i > 0:
                    self.upsample.append(TemporalConv(ch[i], ch[i - 1]))
                    c_prev = ch[i - 1]
            self.out_norm = nn.LayerNorm(ch[0])
            self.output = nn.Linear(ch[0], cfg.latent_dim * cfg.n_heads_out)
            nn.init.zeros_(self.output.weight)
            nn.init.zeros_(self.output.bias)
        blocks = [*self.down_blocks, self.mid_block, *self.up_blocks]
        self.film_sizes = [blk.film_size for blk in blocks]
        self.film = nn.Linear(e, sum(self.film_sizes))  # every block's FiLM in one matmul

    def forward(self, z: torch.Tensor, time: torch.Tensor, cond: Conditioning | None = None,
                entity_pos: torch.Tensor | None = None, control: list[torch.Tensor] | None = None) -> torch.Tensor:
        """z (B, T_lat, V, d); time (B,) or scalar in [0, 1]; cond: Conditioning or None (no
        storyboard, the same as all samples dropped); entity_pos (B, T_lat, V, 3) metres or None (no distance bias);
        control: ControlNet additions to each level's skip and to the bottleneck (see `levels`) or None.
        Returns (B, n_heads_out, T_lat, V, d)."""
        b, t, v, d = z.shape
        ctx = self._context(z, time, cond, entity_pos)
        skips, x = self._down(ctx, self._embed_input(z))
        if control is not None:
            skips = [s + c for s, c in zip(skips, control)]
            x = x + control[-1]
        if self.cfg.text_dim:
            x = self.text_attn(x, v, ctx.text, ctx.text_mask)
        k = len(self.down_blocks) + 1
        for j, block in enumerate(self.up_blocks):
            x = block(torch.cat([x, skips.pop()], -1), ctx.film[k])
            k += 1
            if j < len(self.upsample):
                x = self.upsample[j](x.repeat_interleave(2, 1)[:, :skips[-1].shape[1]])
        out = self.output(F.silu(self.out_norm(x)))  # (B*V, T, S*d)
        return out.reshape(b, v, t, self.cfg.n_heads_out, d).permute(0, 3, 2, 1, 4)

    def levels(self, z: torch.Tensor, time: torch.Tensor, entity_pos: torch.Tensor | None = None,
               hint: torch.Tensor | None = None) -> list[torch.Tensor]:
        """The down path's features without storyboard conditioning: each level's skip
        (B*V, T_l, C_l), then the bottleneck's; `hint` (B*V, T_lat, C_0) is added to the input
        features (a ControlNet branch's control)."""
        ctx = self._context(z, time, None, entity_pos)
        x = self._embed_input(z)
        skips, x = self._down(ctx, x if hint is None else x + hint)
        return [*skips, x]

    def _embed_input(self, z: torch.Tensor) -> torch.Tensor:
        """(B, T, V, d) -> (B*V, T, C_0) with the entity embedding."""
        b, t, v, d = z.shape
        x = self.input(z.transpose(1, 2).reshape(b * v, t, d))
        return (x.reshape(b, v, t, -1) + self.entity_embed).reshape(b * v, t, -1)

    def _context(self, z, time, cond, entity_pos) -> "_Context":
        """What every block reads: FiLM per block, temporal bias and entity distances per
        attention level, the storyboard residual per level."""
        cfg = self.cfg
        b, t, v, d = z.shape
        time = torch.as_tensor(time, dtype=z.dtype, device=z.device).expand(b)
        emb = self.time_mlp(timestep_embedding(time, cfg.channels[0]))
        if cond is None:  # "no storyboard" is exactly an all-dropped conditioning
            cond = Conditioning(residual=z.new_zeros(b, t, v, cfg.cond_dim), temporal_bias=z.new_zeros(b, t, t),
                                embed=z.new_zeros(b, cfg.cond_embed_dim))
        cond = cond.masked()
        emb = emb + self.cond_embed(cond.embed)
        if cfg.text_dim:
            emb = emb + self.text_embed(pooled_text(cond.text, cond.text_mask, b, cfg.text_dim, z))
        film = self.film(F.silu(emb)).repeat_interleave(v, 0).split(self.film_sizes, 1)
        lengths = [t]
        for _ in range(len(cfg.channels) - 1):
            lengths.append((lengths[-1] + 1) // 2)
        attn_levels = sorted({*cfg.attention_levels, len(lengths) - 1})
        tbias = {i: self._temporal_bias(cond, lengths[i], b, z) for i in attn_levels}
        distance = {}
        if entity_pos is not None:
            dist = torch.cdist(entity_pos, entity_pos)  # (B, T, V, V)
            distance = {i: _pool_distance(dist, lengths[i]) for i in attn_levels}
        r = self.cond_residual(cond.residual).transpose(1, 2).reshape(b * v, t, -1)
        return _Context(v, film, lengths, tbias, distance, r.split(list(cfg.channels), -1), cond.text, cond.text_mask)

    def _down(self, ctx: "_Context", x: torch.Tensor) -> tuple[list[torch.Tensor], torch.Tensor]:
        """Input features (B*V, T, C_0) -> (each level's skip, the bottleneck's output)."""
        skips = []
        for i, block in enumerate(self.down_blocks):
            x = block(x, ctx.film[i])
            x = x + _pool_time(ctx.residuals[i], ctx.lengths[i])
            if str(i) in self.down_attn:
                x = self.down_attn[str(i)](x, ctx.entities, ctx.tbias[i], ctx.distance.get(i))
            skips.append(x)
            if i < len(self.downsample):
                x = self.downsample[i](x)
        last = len(ctx.lengths) - 1
        x = self.mid_attn(self.mid_block(x, ctx.film[len(self.down_blocks)]), ctx.entities, ctx.tbias[last],
                          ctx.distance.get(last))
        return skips, x

    def _temporal_bias(self, cond, length, b, like) -> torch.Tensor:
        """(B, T_l, T_l): window mask (-inf outside +-window) + the resampled storyboard bias."""
        idx = torch.arange(length, device=like.device)
        far = (idx[:, None] - idx[None]).abs() > self.cfg.window
        mask = torch.zeros(length, length, dtype=like.dtype, device=like.device).masked_fill(far, float("-inf"))
        bias = cond.temporal_bias
        if bias.shape[-1] != length:
            bias = F.adaptive_avg_pool2d(bias[:, None], (length, length))[:, 0]
        return bias + mask


@dataclass
class _Context:
    entities: int
    film: tuple[torch.Tensor, ...]       # per block (B*V, 2 C)
    lengths: list[int]                   # latent steps per level
    tbias: dict[int, torch.Tensor]       # per attention level (B, T_l, T_l)
    distance: dict[int, torch.Tensor]    # per attention level (B, T_l, V, V); empty without positions
    residuals: tuple[torch.Tensor, ...]  # per level (B*V, T, C_l) storyboard residual
    text: torch.Tensor | None            # (B, L, d_text) or None (no text)
    text_mask: torch.Tensor | None       # (B, L)


def _pool_time(x: torch.Tensor, length: int) -> torch.Tensor:
    """(M, T, C) -> (M, length, C) by averaging (identity when already that long)."""
    return x if x.shape[1] == length else F.adaptive_avg_pool1d(x.transpose(1, 2), length).transpose(1, 2)


def _pool_distance(distance: torch.Tensor, length: int) -> torch.Tensor:
    """(B, T, V, V) -> (B, length, V, V)."""
    b, t, v, _ = distance.shape
    if t == length:
        return distance
    pooled = F.adaptive_avg_pool1d(distance.reshape(b, t, v * v).transpose(1, 2), length)
    return pooled.transpose(1, 2).reshape(b, length, v, v)


def count_parameters(module: nn.Module) -> int:
    return sum(p.numel() for p in module.parameters())

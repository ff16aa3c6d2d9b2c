"""Text conditioning (paper Sec. 3.1: "Text is encoded once and applied by a single bottleneck
cross-attention"): a small word-level transformer encoder over engine.text's token ids, the
cross-attention the U-Net applies at its bottleneck, and the words' mean, which the U-Net adds to
its time embedding (every block's FiLM reads it: with the cross-attention alone, fine-tuned on
captions that mostly repeat what the sketch says, the teacher moved its noise prediction by 0.2%).

"No text" is one thing everywhere: an empty text, a text dropped for classifier-free guidance
and a Conditioning without text all attend only to a learned null token, so sketch-only
generation is the model trained with text dropped. The cross-attention's output layer starts at
zero, so adding text to a trained backbone changes nothing until it trains.
"""
from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import nn

from ..text import TEXT_TOKENS, VOCAB_SIZE


class TextEncoder(nn.Module):
    def __init__(self, dim: int = 64, layers: int = 2, heads: int = 4):
        super().__init__()
        self.embed = nn.Embedding(VOCAB_SIZE, dim, padding_idx=0)
        self.position = nn.Parameter(0.02 * torch.randn(TEXT_TOKENS, dim))
        layer = nn.TransformerEncoderLayer(dim, heads, 2 * dim, dropout=0.0, batch_first=True, norm_first=True)
        self.layers = nn.TransformerEncoder(layer, layers, enable_nested_tensor=False)
        self.norm = nn.LayerNorm(dim)

    def forward(self, ids: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        """ids (B, L) int, mask (B, L) 0/1 -> token features (B, L, dim) (meaningless where mask is 0)."""
        present = mask > 0.5
        # A text with no words still needs one key for the encoder's own attention.
        padding = ~(present | (~present.any(1, keepdim=True) & (torch.arange(ids.shape[1], device=ids.device) == 0)))
        x = self.embed(ids) + self.position[:ids.shape[1]]
        return self.norm(self.layers(x, src_key_padding_mask=padding))


def pooled_text(text: torch.Tensor | None, text_mask: torch.Tensor | None, batch: int, dim: int,
                like: torch.Tensor) -> torch.Tensor:
    """The mean of the words' features (B, dim); zero without text."""
    if text is None:
        return like.new_zeros(batch, dim)
    mask = text_mask[..., None].to(text.dtype)
    return (text * mask).sum(1) / mask.sum(1).clamp_min(1.0)


class TextCrossAttention(nn.Module):
    """x (B*V, T, C) attends to its sample's text tokens and a learned null token."""

    def __init__(self, channels: int, text_dim: int, heads: int):
        super().__init__()
        self.heads = heads
        self.norm = nn.LayerNorm(channels)
        self.q, self.kv = nn.Linear(channels, channels), nn.Linear(text_dim, 2 * channels)
        self.null = nn.Parameter(0.02 * torch.randn(2, channels))          # key, value of "no text"
        self.out = nn.Linear(channels, channels)
        nn.init.zeros_(self.out.weight)
        nn.init.zeros_(self.out.bias)

    def forward(self, x: torch.Tensor, entities: int, text: torch.Tensor | None,
                text_mask: torch.Tensor | None) -> torch.Tensor:
        bv, t, c = x.shape
        null = self.null[None, :, None].expand(bv, 2, 1, c)                 # (B*V, 2, 1, C)
        if text is None:
            kv, keep = null, None
        else:
            words = self.kv(text).unflatten(-1, (2, c)).transpose(1, 2).repeat_interleave(entities, 0)
            kv = torch.cat([null, words], 2)                                # (B*V, 2, 1 + L, C)
            keep = torch.cat([torch.ones_like(text_mask[:, :1]), text_mask], 1) > 0.5
            keep = keep.repeat_interleave(entities, 0)[:, None, None]       # (B*V, 1, 1, 1 + L)
        k, v = (kv[:, i].unflatten(-1, (self.heads, c // self.heads)).transpose(1, 2) for i in (0, 1))
        q = self.q(self.norm(x)).unflatten(-1, (self.heads, c // self.heads)).transpose(1, 2)
        y = F.scaled_dot_product_attention(q, k, v, attn_mask=keep)
        return x + self.out(y.transpose(1, 2).reshape(bv, t, c))

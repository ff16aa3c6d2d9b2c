"""Edits known at key frames, spread over the clip: how finishing moves a motion through its
keyposes (and keeps what the keyposes placed) without popping."""
from __future__ import annotations

import numpy as np

from ..storyboard import Storyboard
from ..synth.trajectory import smoothstep


def key_frames(storyboard: Storyboard) -> list[list[int]]:
    """Each agent's sorted keypose frames, in agent order."""
    return [sorted({k.frame for k in storyboard.keyposes if k.agent == a.id and k.mask.any()})
            for a in storyboard.agents]


def spread(n: int, keys: list[int], values: np.ndarray, falloff: int) -> np.ndarray:
    """Offsets at sorted key frames, values (K, ...), spread over n frames -> (n, ...): linear
    between keys, fading to zero over `falloff` frames (smoothstep) before the first and after
    the last."""
    frames = np.arange(n)
    keys_arr = np.asarray(keys, float)
    flat = values.reshape(len(keys), -1)
    out = np.stack([np.interp(frames, keys_arr, flat[:, i]) for i in range(flat.shape[1])], -1)
    gap = np.maximum(keys_arr[0] - frames, frames - keys_arr[-1]).clip(min=0)
    return (out * smoothstep(1.0 - gap / max(falloff, 1))[:, None]).reshape((n,) + values.shape[1:])

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


def room_from_keys(storyboard: Storyboard, n: int, rate: float, bend: float) -> np.ndarray:
    """(n, H) how far (m) each person may have been moved off the motion the warp placed on their
    key frames: none there, growing by `rate` a frame away from them, the growth eased in over
    `bend` frames (a cone's corner at a key is a one-frame kink: 4 cm of the whole body at 25
    frames a metre; bend 0 keeps it); unbounded for a person with no keys."""
    frames, out = np.arange(n), np.full((n, len(storyboard.agents)), np.inf)
    for a, keys in enumerate(key_frames(storyboard)):
        if keys:
            d = np.min(np.abs(frames[:, None] - np.asarray(keys)[None]), axis=1)
            out[:, a] = rate * np.where(d < bend, d ** 2 / (2 * max(bend, 1e-9)), d - bend / 2)
    return out


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


def closeness_to_keys(n: int, keys: list[int], falloff: int) -> np.ndarray:
    """(n,) weights: 1 at the key frames, easing to 0 over `falloff` frames from the nearest."""
    gap = np.min(np.abs(np.arange(n)[:, None] - np.asarray(keys)[None]), axis=1)
    return smoothstep(np.clip(1.0 - gap / max(falloff, 1), 0.0, 1.0))

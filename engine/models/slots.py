"""The models' fixed slots: what every network sees, whatever the storyboard holds.

The networks animate NUM_HUMANS people and NUM_OBJECTS object at MODEL_FPS frames per second.
A storyboard with fewer is padded with empty slots (`fixed_controls`); one at another frame rate
is animated at MODEL_FPS and handed back at its own (engine.request).
"""
from __future__ import annotations

from dataclasses import fields

import numpy as np

from ..controls import Controls

NUM_HUMANS = 2
NUM_OBJECTS = 1
MODEL_FPS = 20.0   # the models learn motion at this rate

_PER_HUMAN = ("kp2d", "kp_mask", "tr2d", "tr_mask", "contact", "contact_anchor")


def fixed_controls(controls: Controls) -> dict[str, np.ndarray]:
    """Controls padded to the model's slots (2 humans, 1 object); masks as 0/1 float32.
    Padded slots are empty (all masks 0, contact_anchor -1)."""
    out = {}
    for f in fields(Controls):
        v = getattr(controls, f.name)
        if f.name.startswith("obj") and v.shape[1] == 0:
            v = np.zeros((v.shape[0], NUM_OBJECTS) + v.shape[2:], v.dtype)
        if f.name in _PER_HUMAN and v.shape[1] < NUM_HUMANS:
            pad = np.full((v.shape[0], NUM_HUMANS - v.shape[1]) + v.shape[2:], -1 if f.name == "contact_anchor" else 0, v.dtype)
            v = np.concatenate([v, pad], 1)
        out[f.name] = v.astype(np.int64 if f.name == "contact_anchor" else np.float32)
    return out

"""Fake training items and batches with the dataset's field names and shapes, for model tests.

An item is what engine.dataset.StoryboardWindows yields: float32 tensors (contact_anchor int64), N frames, 2 humans, 1 object slot with
K = NUM_ANCHORS anchors, plus every field of engine.controls.Controls. The motion is plausible enough for
metre-scale checks: rest-pose people walking on the ground, a box between them.
"""
from __future__ import annotations

import torch

from engine.objects import NUM_ANCHORS
from engine.skeleton import rest_pose
from engine.text import tokenize

FRAMES = 120


def fake_item(seed: int = 0, frames: int = FRAMES, obj_present: bool = True) -> dict[str, torch.Tensor]:
    g = torch.Generator().manual_seed(seed)
    n = frames
    rest = torch.as_tensor(rest_pose(), dtype=torch.float32)               # (22, 3)
    start = torch.tensor([[-1.0, 0.0, 0.0], [1.0, 0.0, 0.0]]) + 0.3 * torch.randn(2, 3, generator=g) * torch.tensor([1.0, 0.0, 1.0])
    velocity = 0.01 * torch.randn(2, 3, generator=g) * torch.tensor([1.0, 0.0, 1.0])
    root = start[None] + torch.arange(n, dtype=torch.float32)[:, None, None] * velocity[None]  # (N, 2, 3)
    wobble = 0.02 * torch.sin(torch.linspace(0, 6.28, n))[:, None, None, None]
    joints = rest[None, None] + root[:, :, None] + wobble + 0.005 * torch.randn(n, 2, 22, 3, generator=g)
    rot6d = torch.tensor([1.0, 0, 0, 0, 1.0, 0]).expand(n, 2, 22, 6) + 0.05 * torch.randn(n, 2, 22, 6, generator=g)
    box = root.mean(1) + torch.tensor([0.0, 0.8, 0.0])                      # (N, 3)
    quat = torch.tensor([1.0, 0, 0, 0]).expand(n, 4)
    obj_pose = torch.cat([box, quat], -1)[:, None]                          # (N, 1, 7)
    around = torch.linspace(0, 6.283, NUM_ANCHORS + 1)[:NUM_ANCHORS]
    offsets = 0.25 * torch.stack([around.cos(), torch.zeros_like(around), around.sin()], -1)  # (K, 3)
    obj_anchors = box[:, None, None] + offsets[None, None]                  # (N, 1, K, 3)
    phase = torch.softmax(torch.randn(n, 3, generator=g), -1)
    contact_label = (torch.rand(n, 2, 2, generator=g) > 0.7).float()
    if not obj_present:
        obj_pose, obj_anchors = torch.zeros_like(obj_pose), torch.zeros_like(obj_anchors)
    item = {
        "joints": joints, "rot6d": rot6d, "obj_pose": obj_pose, "obj_anchors": obj_anchors,
        "obj_present": torch.tensor(float(obj_present)), "phase": phase, "contact_label": contact_label,
        "has_labels": torch.tensor(1.0), "valid": torch.ones(n), "noise": torch.tensor(0.2),
        # Controls
        "contact": contact_label.clone(),
        "kp2d": torch.randn(n, 2, 22, 2, generator=g), "kp_mask": (torch.rand(n, 2, 22, generator=g) > 0.95).float(),
        "tr2d": torch.randn(n, 2, 22, 2, generator=g), "tr_mask": (torch.rand(n, 2, 22, generator=g) > 0.9).float(),
        "obj2d": torch.rand(n, 1, 4, generator=g), "obj_mask": (torch.rand(n, 1, generator=g) > 0.9).float(),
        "objpath2d": torch.randn(n, 1, 2, generator=g), "objpath_mask": (torch.rand(n, 1, generator=g) > 0.5).float(),
        "contact_anchor": torch.full((n, 2, 2), -1, dtype=torch.int64),
        "camera": torch.eye(3), "cam_target": torch.zeros(3),
        **{k: torch.as_tensor(v) for k, v in tokenize(("two people carry the box", "a pair shake hands")[seed % 2]).items()},
    }
    return {k: v if k in ("contact_anchor", "text_ids") else v.float() for k, v in item.items()}


def fake_batch(batch: int = 2, frames: int = FRAMES, seed: int = 0) -> dict[str, torch.Tensor]:
    """Stacked fake items; the last item of a batch of 2+ has no object."""
    items = [fake_item(seed + i, frames, obj_present=(i < batch - 1 or batch == 1)) for i in range(batch)]
    return {k: torch.stack([it[k] for it in items]) for k in items[0]}


class FakeClips(torch.utils.data.Dataset):
    """A map-style dataset of `count` fake items (what the trainer accepts in place of the real one)."""

    def __init__(self, count: int = 8, frames: int = FRAMES):
        self.items = [fake_item(i, frames, obj_present=i % 3 != 2) for i in range(count)]

    def __len__(self) -> int:
        return len(self.items)

    def __getitem__(self, i: int) -> dict[str, torch.Tensor]:
        return self.items[i]


def fake_conditioning(batch: int, t_lat: int, entities: int = 3, d_model: int = 128, d_e: int = 256,
                      seed: int = 0):
    from engine.models.conditioning import Conditioning
    g = torch.Generator().manual_seed(seed)
    return Conditioning(residual=torch.randn(batch, t_lat, entities, d_model, generator=g),
                        temporal_bias=0.1 * torch.randn(batch, t_lat, t_lat, generator=g),
                        embed=torch.randn(batch, d_e, generator=g),
                        by_type=torch.randn(batch, t_lat, entities, 3, d_model, generator=g))

"""Checkpoint files under runs/<stage>/: `checkpoint.pt` (everything needed to resume, rewritten
atomically every few minutes) and `final.pt` (the EMA weights of the stage's parts, what later
stages and the bundle read)."""
from __future__ import annotations

from pathlib import Path

import torch

from ..atomic import atomic_write


class CheckpointError(ValueError):
    """A checkpoint that is missing or cannot be read."""


def save_atomic(obj: dict, path: str | Path) -> None:
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    with atomic_write(path) as f:
        torch.save(obj, f)


def load(path: str | Path) -> dict:
    path = Path(path)
    if not path.exists():
        raise CheckpointError(f"{path}: no checkpoint (train that stage first)")
    try:
        return torch.load(path, map_location="cpu", weights_only=True)
    except Exception as e:
        raise CheckpointError(f"{path}: unreadable checkpoint ({type(e).__name__})") from None

"""Takes: every generation kept with its storyboard, reopened without regenerating.

    handoff.json          the storyboard
    handoff.takes.npz     its takes, newest last: each one's variations (the motion), the seed
                          and settings it was generated with, the storyboard it came from (so
                          that a reopened take knows whether the sketch changed since), and the
                          variation the artist kept

One NPZ (written atomically, numbers only: no pickles), arrays named `t<take>_v<variation>_<clip
array>` (MotionClip.to_arrays) plus `index`, a JSON list of each take's seed, settings, source,
chosen variation and creation time. At most MAX_TAKES are kept, the oldest dropped first.
"""
from __future__ import annotations

import json
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .atomic import atomic_write
from .clip import ClipError, MotionClip

MAX_TAKES = 20
TAKES_SUFFIX = ".takes.npz"
MAX_INDEX_CHARS = 64_000_000       # the index holds each take's storyboard: far below this


class TakesError(ValueError):
    """A takes file that cannot be read (one line)."""


@dataclass
class Take:
    clips: list[MotionClip]          # the variations
    seed: int
    settings: dict                   # the generation's settings as plain values (GenerationSettings)
    source: str                      # the storyboard it was generated from, as JSON
    chosen: int = 0                  # the variation kept
    created: str = field(default_factory=lambda: time.strftime("%Y-%m-%d %H:%M:%S"))

    @property
    def clip(self) -> MotionClip:
        return self.clips[self.chosen]


def takes_path(storyboard_path: str | Path) -> Path:
    """Where the takes of the storyboard at `storyboard_path` live: handoff.json -> handoff.takes.npz."""
    path = Path(storyboard_path)
    return path.with_name(path.stem + TAKES_SUFFIX)


def save_takes(takes: list[Take], path: str | Path) -> None:
    """Write the newest MAX_TAKES takes to `path` atomically (no takes: nothing is written, and a
    file already there is left alone)."""
    takes = takes[-MAX_TAKES:]
    if not takes:
        return
    arrays = {"index": np.str_(json.dumps([
        {"seed": t.seed, "settings": t.settings, "source": t.source, "chosen": t.chosen, "created": t.created,
         "variations": len(t.clips)} for t in takes]))}
    for i, take in enumerate(takes):
        for k, clip in enumerate(take.clips):
            arrays.update({f"t{i}_v{k}_{name}": value for name, value in clip.to_arrays().items()})
    with atomic_write(path) as f:
        np.savez_compressed(f, **arrays)


def load_takes(path: str | Path) -> list[Take]:
    try:
        with np.load(path, allow_pickle=False) as z:
            data = {k: z[k] for k in z.files}
    except Exception as e:  # zipfile, OSError, ValueError: all mean "not a takes file"
        raise TakesError(f"{path}: not a readable takes file ({type(e).__name__})") from None
    try:
        index_text = str(data.pop("index"))
        if len(index_text) > MAX_INDEX_CHARS:
            raise ValueError("its index is too large")
        index = json.loads(index_text)
        takes = []
        for i, meta in enumerate(index):
            clips = []
            for k in range(int(meta["variations"])):
                prefix = f"t{i}_v{k}_"
                clips.append(MotionClip.from_arrays({name[len(prefix):]: v for name, v in data.items()
                                                     if name.startswith(prefix)}, f"{path} take {i + 1}"))
            chosen = int(meta["chosen"])
            if not clips or not 0 <= chosen < len(clips):
                raise ValueError(f"take {i + 1} has no variation {chosen + 1}")
            takes.append(Take(clips, int(meta["seed"]), dict(meta["settings"]), str(meta["source"]), chosen,
                              str(meta["created"])))
        return takes
    except ClipError as e:
        raise TakesError(str(e)) from None
    except (KeyError, TypeError, ValueError, json.JSONDecodeError) as e:
        raise TakesError(f"{path}: damaged takes file ({str(e).splitlines()[0] if str(e) else type(e).__name__})") from None

"""Write a synthesized dataset: N clip NPZ files plus index.json (file, scenario, seed per clip).

Clip i uses scenario `scenarios[i % len(scenarios)]` and seed `seed * 100003 + i`, so any clip
can be regenerated alone from the index.
"""
from __future__ import annotations

import json
from pathlib import Path

from ..atomic import write_text
from .assemble import SynthConfig, synthesize
from .scenarios import SCENARIOS


def write_dataset(out_dir: str | Path, clips: int, seed: int, scenarios: tuple[str, ...] = SCENARIOS,
                  fps: float = 20, seconds: float = 6.0, config: SynthConfig | None = None) -> Path:
    """Returns the path of index.json."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    entries = []
    for i in range(clips):
        scenario = scenarios[i % len(scenarios)]
        clip_seed = seed * 100003 + i
        name = f"{i:06d}_{scenario}.npz"
        synthesize(scenario, clip_seed, fps, seconds, config).save(out / name)
        entries.append({"file": name, "scenario": scenario, "seed": clip_seed})
    index = out / "index.json"
    write_text(index, json.dumps({"seed": seed, "fps": fps, "seconds": seconds,
                                 "scenarios": list(scenarios), "clips": entries}, indent=1))
    return index

"""Collect the stages' final EMA weights under runs/ into one model bundle."""
from __future__ import annotations

from pathlib import Path

from ..models.bundle import ModelBundle, ModelConfig, build_parts
from . import checkpoint
from .config import STAGES


def bundle_from_runs(runs: str | Path, config: ModelConfig) -> ModelBundle:
    """Every part found in runs/<stage>/final.pt (later stages win); trained=True only when all
    stages are there. Parts no stage trained keep fresh weights."""
    runs = Path(runs)
    parts = build_parts(config)
    done, metrics = [], {}
    for stage in STAGES:
        path = runs / stage / "final.pt"
        if not path.exists():
            continue
        final = checkpoint.load(path)
        for name, state in final["parts"].items():
            parts[name].load_state_dict(state)
        done.append(stage)
        metrics[stage] = final.get("metrics", {})
    return ModelBundle(config, parts, trained=len(done) == len(STAGES),
                       metadata={"stages": done, "metrics": metrics}).eval()

"""Collect the stages' final EMA weights under runs/ into one model bundle."""
from __future__ import annotations

from pathlib import Path

from ..models.bundle import ModelBundle, ModelConfig, build_parts
from . import checkpoint
from .config import OPTIONAL_STAGES, STAGE_PARTS, STAGES


def bundle_from_runs(runs: str | Path, config: ModelConfig | None = None) -> ModelBundle:
    """Every part found in runs/<stage>/final.pt (later stages win); trained=True only when all
    stages are there. Parts no stage trained keep fresh weights. `config`: the models' (default:
    the one the last stage trained with, e.g. with text)."""
    runs = Path(runs)
    if config is None:
        config = runs_model_config(runs)
    parts = build_parts(config)
    done, metrics, states = [], {}, {}
    for stage in STAGES:
        path = runs / stage / "final.pt"
        if not path.exists():
            continue
        final = checkpoint.load(path)
        states.update(final["parts"])        # an earlier stage's version (the encoders' conditioner) is not loaded
        done.append(stage)
        metrics[stage] = final.get("metrics", {})
    for name, state in states.items():
        parts[name].load_state_dict(state)
    absent = [name for stage, name in OPTIONAL_STAGES.items() if stage not in done]
    required = [stage for stage in STAGES if stage not in OPTIONAL_STAGES]
    return ModelBundle(config, parts, trained=all(stage in done for stage in required),
                       metadata={"stages": done, "metrics": metrics, "absent_parts": absent}).eval()


def runs_model_config(runs: str | Path) -> ModelConfig:
    """The model config of the last stage trained under runs/ (stages seeded from a bundle count
    only when none was trained there; ModelConfig() if none recorded one)."""
    recorded = []
    for stage in STAGES:
        path = Path(runs) / stage / "final.pt"
        if path.exists():
            final = checkpoint.load(path)
            if final.get("model_config"):
                recorded.append((not final.get("from_bundle", False), ModelConfig.from_dict(final["model_config"])))
    trained = [cfg for here, cfg in recorded if here] or [cfg for _, cfg in recorded]
    return trained[-1] if trained else ModelConfig()


def runs_from_bundle(bundle: ModelBundle, runs: str | Path) -> list[str]:
    """Write runs/<stage>/final.pt for each stage the bundle's parts came from and runs/ lacks, so
    that a later stage (the preview) can train on a shipped bundle whose runs are gone. -> the
    stages written."""
    written = []
    for stage, names in STAGE_PARTS.items():
        path = Path(runs) / stage / "final.pt"
        if path.exists() or not all(bundle.has_part(n) for n in names):
            continue
        checkpoint.save_atomic({"parts": {n: {k: v.float() if v.is_floating_point() else v
                                              for k, v in bundle.parts[n].state_dict().items()} for n in names},
                                "metrics": bundle.metadata.get("metrics", {}).get(stage, {}),
                                "model_config": bundle.config.to_dict(), "from_bundle": True}, path)
        written.append(stage)
    return written

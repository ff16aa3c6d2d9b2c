"""`sketch2colab train`: build the dataset from clip folders and run a stage (or all)."""
from __future__ import annotations

import json
from pathlib import Path

import torch.distributed as dist

from .checkpoint import CheckpointError
from .config import CONFIGS
from .loop import init_distributed_from_env, train
from .stages import StageUnavailable


class TrainError(ValueError):
    """Bad training input (no data, missing earlier stage, unreadable checkpoint): one line."""


def train_command(stage: str, config: str = "default", data: list[str] | None = None,
                  real: list[str] | None = None, steps: int | None = None, resume: bool = False,
                  runs: str = "runs", threads: int | None = None, from_bundle: str | None = None,
                  batch_size: int | None = None, lr: float | None = None, minutes: float | None = None,
                  workers: int | None = None, artist_share: float = 0.0, warm_start: bool = False,
                  text: bool = False, sparse_share: float = 0.0) -> dict:
    from ..dataset import DatasetConfig, StoryboardWindows, split_files
    cfg = CONFIGS[config]()
    if steps is not None:
        if steps < 1:
            raise TrainError(f"--steps must be positive, got {steps}")
        cfg.steps, cfg.stage_steps = steps, {}
    if threads is not None:
        cfg.threads = max(1, threads)
    for name, value in (("--batch-size", batch_size), ("--lr", lr), ("--minutes", minutes)):
        if value is not None and value <= 0:
            raise TrainError(f"{name} must be positive, got {value}")
    if batch_size is not None:
        cfg.batch_size = batch_size
    if lr is not None:
        cfg.lr, cfg.stage_lr = lr, {}
    if minutes is not None:
        cfg.stage_seconds = 60.0 * minutes
    if workers is not None:
        cfg.num_workers = max(0, workers)
    for name, share in (("--artist-share", artist_share), ("--sparse-share", sparse_share)):
        if not 0.0 <= share <= 1.0:
            raise TrainError(f"{name} must be between 0 and 1, got {share}")
    cfg.warm_start = warm_start
    if text:
        cfg.model = cfg.model.with_text()
    files = []
    for folder in data or []:
        if not Path(folder).is_dir():
            raise TrainError(f"{folder}: not a folder of clip NPZ files")
        files += split_files(synth_dir=folder).train
    for folder in real or []:
        if not Path(folder).is_dir():
            raise TrainError(f"{folder}: not a folder of clip NPZ files")
        files += split_files(real_dir=folder).train
    if not files:
        raise TrainError("no training clips: pass --data DIR (synthesized clips) and/or --real DIR (imported capture)")
    dataset = StoryboardWindows(files, DatasetConfig(seed=cfg.seed, artist_share=artist_share, sparse_share=sparse_share))
    if len(dataset) == 0:
        raise TrainError("the clip folders hold no clip long enough for a training window")
    if from_bundle is not None:
        from ..models.bundle import BundleError, load_bundle
        from .export import runs_from_bundle
        try:
            runs_from_bundle(load_bundle(from_bundle), runs)
        except BundleError as e:
            raise TrainError(str(e)) from None
    joined = init_distributed_from_env()
    try:
        results = train(stage, cfg, dataset, runs=runs, resume=resume)
    except (StageUnavailable, CheckpointError) as e:
        raise TrainError(str(e)) from None
    finally:
        if joined:
            dist.destroy_process_group()
    print(json.dumps(results, indent=1))
    return results

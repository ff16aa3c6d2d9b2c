"""Train the motion evaluator contrastively on the training split and write it with its model card.

    python -m engine.evaluation.train_evaluator --synth DATA/synth --real DATA/real \
        --out resources/evaluator.pt --steps 2500 --seed 0 [--config large] [--device cuda]

Files are split by engine.dataset.split_files (synthesized clips by seed; real takes of the
held-out salsa pair are test): training reads the train split, the figures in the card come
from the val split, and test files are never opened. Every training window is sketchified
`views` times (new camera, noise, keyframes; dataset epochs 0..views-1) once, up front, and the
features are cached in half precision: drawing storyboards costs far more than a training step.

Loss: symmetric InfoNCE between storyboard and motion embeddings of a batch; windows of the
same clip that overlap by more than half are not used as each other's negatives (they are
near duplicates). Everything is seeded: one seed gives the same weights on one machine.
"""
from __future__ import annotations

import argparse
import hashlib
import math
import subprocess
import sys
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Callable, Sequence

import numpy as np
import torch
import torch.nn.functional as F
from torch.utils.data import DataLoader

from ..atomic import write_text
from ..dataset import DatasetConfig, StoryboardWindows, split_files
from ..metrics import r_precision
from .evaluator import (R_PRECISION_BATCH, R_PRECISION_TOP_K, STD_FLOOR, EvaluatorConfig, MotionEvaluator,
                        embedding_fid, save_evaluator)
from .features import motion_features, story_features

REPO_ROOT = Path(__file__).resolve().parents[2]


@dataclass
class TrainConfig:
    model: EvaluatorConfig = field(default_factory=EvaluatorConfig)
    steps: int = 2500
    batch: int = 64
    lr: float = 1e-3
    weight_decay: float = 1e-4
    warmup: int = 100              # steps of linear learning-rate warm-up before the cosine decay
    temperature: float = 0.07      # InfoNCE temperature on cosine similarities
    views: int = 2                 # storyboards drawn per training window
    seed: int = 0
    log_every: int = 200
    workers: int = 0               # processes drawing storyboards for the cache (0 = this one)

    @classmethod
    def large(cls) -> "TrainConfig":
        """For a GPU: wider encoders, more steps and storyboard views."""
        return cls(model=EvaluatorConfig.large(), steps=20000, batch=128, views=8, lr=5e-4, workers=8)


CONFIGS = {"default": TrainConfig, "large": TrainConfig.large}


@dataclass
class FeatureCache:
    """Evaluator inputs of W windows, V storyboard views each (N frames per window)."""
    motion: torch.Tensor        # (W, N, MOTION_FEATURES) float16
    story: torch.Tensor         # (V, W, N, STORY_FEATURES) float16
    valid: torch.Tensor         # (W, N) float32
    clip: torch.Tensor          # (W,) int64 clip index, to find near-duplicate windows
    start: torch.Tensor         # (W,) int64 first frame of the window in its clip

    def __len__(self) -> int:
        return len(self.motion)

    def subset(self, index: torch.Tensor, views: int = 1) -> "FeatureCache":
        """The windows at `index` with their first `views` storyboard views."""
        return FeatureCache(self.motion[index], self.story[:views, index], self.valid[index], self.clip[index],
                            self.start[index])


def build_cache(files: Sequence[Path], model: EvaluatorConfig, views: int, seed: int,
                workers: int = 0, chunk: int = 64) -> FeatureCache:
    """Windows of `files` (dataset defaults, the model's window and fps), each sketchified in
    dataset epochs 0..views-1. Motion features come from epoch 0: they do not depend on the
    dataset's random yaw."""
    data = StoryboardWindows(files, DatasetConfig(window=model.window, fps=model.fps, seed=seed))
    if len(data) == 0:
        raise ValueError("no training windows: every clip is shorter than the dataset's min_frames")
    motion, story, valid = [], [[] for _ in range(views)], []
    for view in range(views):
        data.set_epoch(view)  # before the loader copies the dataset into its workers
        for batch in DataLoader(data, batch_size=chunk, num_workers=workers):
            story[view].append(story_features(batch, batch["valid"]).half())
            if view == 0:
                motion.append(motion_features(batch["joints"], batch["obj_pose"], batch["obj_present"],
                                              batch["valid"], model.fps).half())
                valid.append(batch["valid"])
    windows = torch.from_numpy(data.windows)
    return FeatureCache(torch.cat(motion), torch.stack([torch.cat(s) for s in story]), torch.cat(valid),
                        windows[:, 0].clone(), windows[:, 1].clone())


def standardise(evaluator: MotionEvaluator, cache: FeatureCache, windows: int = 4096, seed: int = 0) -> None:
    """Set both encoders' feature mean and std from the valid frames of a random subset of the
    cache's windows (view 0 for storyboards): all of a large cache would not fit in float32."""
    subset = torch.randperm(len(cache), generator=torch.Generator().manual_seed(seed))[:windows]
    mask = cache.valid[subset].bool()
    for encoder, feats in ((evaluator.motion_encoder, cache.motion[subset][mask]),
                           (evaluator.story_encoder, cache.story[0, subset][mask])):
        feats = feats.float()
        encoder.feature_mean.copy_(feats.mean(0))
        encoder.feature_std.copy_(feats.std(0).clamp_min(STD_FLOOR))


def near_duplicates(clip: torch.Tensor, start: torch.Tensor, window: int) -> torch.Tensor:
    """(B,) clip ids and window starts -> (B, B) bool, True off the diagonal for windows of one
    clip overlapping by more than half a window."""
    same = (clip[:, None] == clip[None]) & ((start[:, None] - start[None]).abs() < window // 2)
    return same & ~torch.eye(len(clip), dtype=torch.bool, device=clip.device)


def info_nce(story: torch.Tensor, motion: torch.Tensor, temperature: float,
             excluded: torch.Tensor | None = None) -> torch.Tensor:
    """Symmetric InfoNCE of matched unit embeddings (B, D), (B, D); `excluded` (B, B) bool
    marks pairs that are not negatives."""
    logits = story @ motion.T / temperature
    if excluded is not None:
        logits = logits.masked_fill(excluded, float("-inf"))
    target = torch.arange(len(story), device=story.device)
    return 0.5 * (F.cross_entropy(logits, target) + F.cross_entropy(logits.T, target))


def _embed(evaluator: MotionEvaluator, cache: FeatureCache, index: torch.Tensor, view: int,
           device) -> tuple[torch.Tensor, torch.Tensor]:
    valid = cache.valid[index].to(device)
    story = evaluator.story_encoder(cache.story[view, index].to(device).float(), valid)
    motion = evaluator.motion_encoder(cache.motion[index].to(device).float(), valid)
    return story, motion


def fit(evaluator: MotionEvaluator, train: FeatureCache, config: TrainConfig,
        log: Callable[[str], None] = print) -> list[float]:
    """Standardise features, then `config.steps` AdamW steps of InfoNCE on random batches of
    random views. Returns the training loss per step."""
    device = next(evaluator.parameters()).device
    torch.manual_seed(config.seed)
    standardise(evaluator, train, seed=config.seed)
    evaluator.train()
    optimiser = torch.optim.AdamW(evaluator.parameters(), lr=config.lr, weight_decay=config.weight_decay)

    def rate(step: int) -> float:
        if step < config.warmup:
            return (step + 1) / config.warmup
        return 0.5 * (1 + math.cos(math.pi * (step - config.warmup) / max(config.steps - config.warmup, 1)))

    schedule = torch.optim.lr_scheduler.LambdaLR(optimiser, rate)
    generator = torch.Generator().manual_seed(config.seed)
    batch = min(config.batch, len(train))
    order, cursor, losses = torch.randperm(len(train), generator=generator), 0, []
    for step in range(config.steps):
        if cursor + batch > len(order):  # a new pass over the windows
            order, cursor = torch.randperm(len(train), generator=generator), 0
        index = order[cursor:cursor + batch]
        cursor += batch
        view = int(torch.randint(train.story.shape[0], (1,), generator=generator))
        story, motion = _embed(evaluator, train, index, view, device)
        excluded = near_duplicates(train.clip[index], train.start[index], config.model.window).to(device)
        loss = info_nce(story, motion, config.temperature, excluded)
        optimiser.zero_grad(set_to_none=True)
        loss.backward()
        optimiser.step()
        schedule.step()
        losses.append(loss.item())
        if config.log_every and ((step + 1) % config.log_every == 0 or step + 1 == config.steps):
            log(f"step {step + 1}/{config.steps}  InfoNCE {np.mean(losses[-config.log_every:]):.3f}")
    evaluator.eval()
    return losses


@torch.no_grad()
def evaluate(evaluator: MotionEvaluator, cache: FeatureCache, config: TrainConfig,
             seed: int = 0) -> dict[str, float]:
    """On view 0 of the cache, in one fixed shuffled order: mean InfoNCE over batches of
    config.batch, R-precision top 3 in batches of 32, and the FID between the two halves of the
    motions (what a perfect generator would score on this many motions: the floor)."""
    evaluator.eval()
    device = next(evaluator.parameters()).device
    order = torch.from_numpy(np.random.default_rng(seed).permutation(len(cache)))
    story, motion, losses = [], [], []
    for lo in range(0, len(order), config.batch):
        index = order[lo:lo + config.batch]
        s, m = _embed(evaluator, cache, index, 0, device)
        if len(index) > 1:
            excluded = near_duplicates(cache.clip[index], cache.start[index], config.model.window).to(device)
            losses.append(float(info_nce(s, m, config.temperature, excluded)))
        story.append(s.double().cpu().numpy())
        motion.append(m.double().cpu().numpy())
    story, motion = np.concatenate(story), np.concatenate(motion)
    half = len(motion) // 2
    return {"infonce": float(np.mean(losses)) if losses else float("nan"),
            "r_precision_top3": r_precision(story, motion, R_PRECISION_TOP_K, R_PRECISION_BATCH),
            "fid_halves": embedding_fid(motion[:half], motion[half:]) if half >= 2 else float("nan"),
            "windows": len(cache)}


def git_commit() -> str:
    """HEAD of the repository, marked when the working tree has uncommitted changes."""
    def git(*args: str) -> str:
        return subprocess.run(["git", *args], cwd=REPO_ROOT, capture_output=True, text=True).stdout.strip()
    head = git("rev-parse", "HEAD") or "unknown"
    return head + (" (with uncommitted changes)" if git("status", "--porcelain", "--untracked-files=no") else "")


def _digest(paths: Sequence[Path]) -> str:
    h = hashlib.sha256()
    for p in paths:
        h.update(Path(p).read_bytes())
    return h.hexdigest()[:16]


def write_model_card(path: Path, card: dict, train_files: Sequence[Path], val_files: Sequence[Path]) -> None:
    chance = R_PRECISION_TOP_K / R_PRECISION_BATCH
    t, v = card["train"], card["val"]
    lines = [
        "# Motion evaluator (FID and storyboard-to-motion R-precision)", "",
        "Frozen evaluator for DESIGN.md section 4: engine/evaluation/evaluator.py, trained by "
        "engine/evaluation/train_evaluator.py. Never trained on the test split.", "",
        f"- weights: `{path.with_suffix('.pt').name}`, sha256 `{card['weights_sha256']}` (half precision)",
        f"- command: `{card['command']}`",
        f"- git commit: {card['git_commit']}",
        f"- seed: {card['seed']}; config: `{card['config']}`",
        f"- parameters: {card['parameters']:,}",
        f"- data: train split {len(train_files)} clips / {t['windows']} windows x {card['views']} storyboard "
        f"views; val split {len(val_files)} clips / {v['windows']} windows (engine.dataset.split_files; "
        f"test files not read); data digest (sha256 of the train + val files) `{card['data_sha256']}`",
        f"- data directories: {', '.join(card['data_dirs'])}",
        f"- wall time: {card['wall_s']:.0f} s on {card['device']} ({card['threads']} threads)", "",
        "| split | InfoNCE | R-precision top-3 (batches of 32) | FID real vs real (halves) |",
        "|---|---|---|---|",
        f"| train | {t['infonce']:.3f} | {t['r_precision_top3']:.3f} | {t['fid_halves']:.4f} |",
        f"| val | {v['infonce']:.3f} | {v['r_precision_top3']:.3f} | {v['fid_halves']:.4f} |", "",
        f"Chance R-precision top-3 is {chance:.3f}. The halves FID is the floor a generator matching "
        "the real distribution would reach with this many motions; train figures are measured on the "
        "first storyboard view of at most 2048 random training windows.", "",
        "## Files", "", "Train:", *[f"- {p}" for p in train_files], "", "Val:", *[f"- {p}" for p in val_files], ""]
    write_text(path.with_suffix(".md"), "\n".join(lines))


def train_evaluator(train_files: Sequence[Path], val_files: Sequence[Path], out: str | Path,
                    config: TrainConfig = TrainConfig(), command: str = "", config_name: str = "default",
                    data_dirs: Sequence[str] = (), device: str = "cpu",
                    log: Callable[[str], None] = print) -> dict:
    """Train on `train_files`, measure on `val_files`, write `out` (.pt) and its model card
    (.md beside it). Returns the card."""
    began = time.time()
    out = Path(out)
    torch.manual_seed(config.seed)
    log(f"caching {len(train_files)} train / {len(val_files)} val clips x {config.views} views ...")
    train = build_cache(train_files, config.model, config.views, config.seed, config.workers)
    val = build_cache(val_files, config.model, 1, config.seed + 1, config.workers) if val_files else None
    evaluator = MotionEvaluator(config.model).to(device)
    log(f"{len(train)} train windows, {len(val) if val else 0} val windows, "
        f"{evaluator.num_parameters():,} parameters, {time.time() - began:.0f} s")
    fit(evaluator, train, config, log)
    measured = torch.randperm(len(train), generator=torch.Generator().manual_seed(config.seed))[:2048]
    train_figures = {**evaluate(evaluator, train.subset(measured), config), "windows": len(train)}
    no_val = {"infonce": float("nan"), "r_precision_top3": float("nan"), "fid_halves": float("nan"), "windows": 0}
    card = {"command": command, "git_commit": git_commit(), "seed": config.seed, "config": config_name,
            "train_config": asdict(config), "parameters": evaluator.num_parameters(), "views": config.views,
            "data_dirs": list(data_dirs), "data_sha256": _digest([*train_files, *val_files]),
            "device": str(device), "threads": torch.get_num_threads(),
            "train": train_figures, "val": evaluate(evaluator, val, config) if val else no_val}
    card["wall_s"] = time.time() - began
    evaluator.card = card
    save_evaluator(evaluator, out)
    card["weights_sha256"] = hashlib.sha256(out.read_bytes()).hexdigest()[:16]
    write_model_card(out, card, train_files, val_files)
    log(f"wrote {out} and {out.with_suffix('.md')}: val InfoNCE {card['val']['infonce']:.3f}, "
        f"R-precision top-3 {card['val']['r_precision_top3']:.3f} (chance "
        f"{R_PRECISION_TOP_K / R_PRECISION_BATCH:.3f}), FID halves {card['val']['fid_halves']:.4f}")
    return card


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m engine.evaluation.train_evaluator",
                                     description=__doc__.split("\n")[0])
    parser.add_argument("--synth", action="append", default=[], help="directory of synthesized clips (repeatable)")
    parser.add_argument("--real", action="append", default=[], help="directory of imported real clips (repeatable)")
    parser.add_argument("--out", default=str(REPO_ROOT / "resources" / "evaluator.pt"))
    parser.add_argument("--config", choices=sorted(CONFIGS), default="default")
    parser.add_argument("--steps", type=int, help="training steps (default: the config's)")
    parser.add_argument("--views", type=int, help="storyboards drawn per training window (default: the config's)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--device", default="cuda" if torch.cuda.is_available() else "cpu")
    parser.add_argument("--threads", type=int, help="torch CPU threads (default: torch's)")
    parser.add_argument("--workers", type=int, help="processes drawing storyboards (default: the config's)")
    args = parser.parse_args(argv)
    if not args.synth and not args.real:
        parser.error("give at least one --synth or --real directory")
    if args.threads:
        torch.set_num_threads(args.threads)
    config = CONFIGS[args.config]()
    config.seed = args.seed
    config.steps = args.steps if args.steps is not None else config.steps
    config.views = args.views if args.views is not None else config.views
    config.workers = args.workers if args.workers is not None else config.workers
    train_files, val_files = [], []
    for synth_dir in args.synth:
        splits = split_files(synth_dir=synth_dir)
        train_files += splits.train
        val_files += splits.val
    for real_dir in args.real:
        splits = split_files(real_dir=real_dir)
        train_files += splits.train
        val_files += splits.val
    command = " ".join(["python -m engine.evaluation.train_evaluator", *sys.argv[1:]] if argv is None
                       else ["python -m engine.evaluation.train_evaluator", *argv])
    train_evaluator(train_files, val_files, args.out, config, command, args.config,
                    [*args.synth, *args.real], args.device)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""The training loop: AdamW + EMA, fixed seeds, resumable checkpoints, progress bar, and
DistributedDataParallel when launched by torchrun (or any initialised process group).

Determinism: the batch of step k is drawn by a generator seeded with (seed, k), and every random
draw inside the loss comes from a generator seeded with (seed, k, rank), so a run resumed from
a checkpoint continues exactly as the uninterrupted run would (the global RNG, used by codebook
restarts, is saved too). The learning rate warms up linearly and then stays constant, so the
schedule never depends on the total step count.
"""
from __future__ import annotations

import json
import os
import time
from pathlib import Path

import torch
import torch.distributed as dist
from torch import nn
from torch.nn.parallel import DistributedDataParallel
from torch.utils.data import DataLoader, Dataset
from tqdm import tqdm

from ..cpu import ThreadBudget
from . import checkpoint
from .config import STAGES, TrainConfig
from .ema import EMA
from .stages import StageTask, build_stage


class StepBatches:
    """Batch sampler: for steps start..steps-1, this rank's share of the step's random indices,
    as (epoch, index) pairs (the epoch re-draws the dataset's storyboards)."""

    def __init__(self, size: int, batch: int, steps: int, start: int, seed: int, rank: int = 0, world: int = 1):
        self.size, self.batch, self.steps, self.start = size, batch, steps, start
        self.seed, self.rank, self.world = seed, rank, world

    def __len__(self) -> int:
        return max(self.steps - self.start, 0)

    def __iter__(self):
        for step in range(self.start, self.steps):
            g = torch.Generator().manual_seed(self.seed * 1_000_003 + step)
            idx = torch.randint(self.size, (self.batch * self.world,), generator=g)
            epoch = step * self.batch * self.world // max(self.size, 1)
            yield [(epoch, int(i)) for i in idx[self.rank * self.batch:(self.rank + 1) * self.batch]]


class EpochView(Dataset):
    """dataset[(epoch, i)] = dataset.set_epoch(epoch); dataset[i] (works inside loader workers)."""

    def __init__(self, dataset: Dataset):
        self.dataset = dataset

    def __len__(self) -> int:
        return len(self.dataset)

    def __getitem__(self, key):
        epoch, index = key
        if hasattr(self.dataset, "set_epoch"):
            self.dataset.set_epoch(epoch)
        return self.dataset[index]


class _LossModule(nn.Module):
    """Holds the trainable parts so that DDP sees them; forward is the stage's loss."""

    def __init__(self, task: StageTask):
        super().__init__()
        self.trainable = task.trainable
        self._loss = task.loss

    def forward(self, batch: dict, generator: torch.Generator, step: int) -> dict:
        return self._loss(batch, generator, step)


def _dist_info() -> tuple[int, int]:
    if dist.is_available() and dist.is_initialized():
        return dist.get_rank(), dist.get_world_size()
    return 0, 1


def _all_agree(due: bool, world: int) -> bool:
    """Rank 0's decision on every rank: save() is a collective, so ranks whose clocks disagree
    about a time-based checkpoint would otherwise call different collectives and fail."""
    if world == 1:
        return due
    flag = torch.tensor([int(due)])
    dist.broadcast(flag, 0)
    return bool(flag.item())


def run_task(task: StageTask, dataset: Dataset, cfg: TrainConfig, run_dir: Path, resume: bool = False,
             progress: bool = True) -> dict:
    """Train task.trainable for cfg.steps_for(task.name) steps (fewer when cfg.stage_seconds runs
    out first: metrics["steps"] says how many were done); returns the final metrics.
    Writes run_dir/checkpoint.pt (resume state), run_dir/log.jsonl and run_dir/final.pt (EMA)."""
    rank, world = _dist_info()
    device = torch.device(f"cuda:{torch.cuda.current_device()}" if torch.cuda.is_available() else "cpu")
    run_dir = Path(run_dir)
    steps = cfg.steps_for(task.name)
    model = task.trainable.to(device)
    ckpt_path = run_dir / "checkpoint.pt"
    resuming = resume and ckpt_path.exists()
    if cfg.warm_start and not resuming and (run_dir / "final.pt").exists():   # fine-tune what the stage made
        made = checkpoint.load(run_dir / "final.pt")["parts"]
        for name, part in model.items():
            if name in made:   # layers the model gained since (text) start fresh; anything else must fit
                unexpected = part.load_state_dict(made[name], strict=False).unexpected_keys
                if unexpected:
                    raise checkpoint.CheckpointError(f"{run_dir / 'final.pt'}: {name} has weights this model lacks "
                                                     f"({unexpected[0]}, ...)")
    for frozen in task.frozen.values():
        frozen.to(device)
    module = _LossModule(task)
    wrapped = DistributedDataParallel(module, find_unused_parameters=True) if world > 1 else module
    lr = cfg.lr_for(task.name)
    opt = torch.optim.AdamW(model.parameters(), lr=lr, weight_decay=cfg.weight_decay)
    ema = EMA(model, cfg.ema_decay)
    torch.manual_seed(cfg.seed * 7919 + rank)
    start, elapsed_before = 0, 0.0
    if resuming:
        state = checkpoint.load(ckpt_path)
        model.load_state_dict(state["model"])
        opt.load_state_dict(state["optimizer"])
        ema.load_state_dict(state["ema"], int(state.get("ema_updates", 0)))
        torch.set_rng_state(state["rng"][rank] if rank < len(state["rng"]) else state["rng"][0])
        start = int(state["step"])
        elapsed_before = float(state.get("elapsed_s", 0.0))
    began = time.monotonic()

    def save(step: int) -> None:
        rngs = [torch.get_rng_state()]
        if world > 1:  # every rank's global RNG, so each resumes its own stream
            rngs = [None] * world
            dist.all_gather_object(rngs, torch.get_rng_state())
        if rank == 0:
            checkpoint.save_atomic({"model": model.state_dict(), "optimizer": opt.state_dict(), "ema": ema.state_dict(),
                                    "ema_updates": ema.updates,
                                    "step": step, "rng": rngs, "stage": task.name,
                                    "elapsed_s": elapsed_before + time.monotonic() - began}, ckpt_path)

    # Its own generator: a DataLoader otherwise draws its workers' base seed from the global RNG,
    # one draw per run, so a resumed run would shift the stream that dead-code restarts use.
    loader = DataLoader(EpochView(dataset), batch_sampler=StepBatches(len(dataset), cfg.batch_size, steps, start,
                                                                       cfg.seed, rank, world),
                        num_workers=cfg.num_workers, generator=torch.Generator().manual_seed(cfg.seed))
    bar = tqdm(total=steps, initial=start, desc=task.name, disable=not progress or rank != 0, dynamic_ncols=True)
    log = open(run_dir / "log.jsonl", "a") if rank == 0 else None
    last_save, terms, done = time.monotonic(), {}, start
    model.train()
    threads = ThreadBudget(cfg.threads, every_s=10.0)
    try:
        for step, batch in enumerate(loader, start):
            threads.adjust()
            for group in opt.param_groups:
                group["lr"] = lr * min(1.0, (step + 1) / max(cfg.warmup_steps, 1))
            g = torch.Generator(device).manual_seed((cfg.seed * 1_000_003 + step) * 64 + rank)
            terms = wrapped({k: v.to(device, non_blocking=True) for k, v in batch.items()}, g, step)
            opt.zero_grad(set_to_none=True)
            terms["loss"].backward()
            if cfg.grad_clip:
                nn.utils.clip_grad_norm_(model.parameters(), cfg.grad_clip)
            opt.step()
            ema.update(model)
            if rank == 0:
                bar.update(1)
                bar.set_postfix(loss=f"{terms['loss'].item():.4f}")
                if step % cfg.log_every == 0 or step == steps - 1:
                    log.write(json.dumps({"step": step, **{k: v.item() for k, v in terms.items()}}) + "\n")
                    log.flush()
            done = step + 1
            if _all_agree(cfg.stage_seconds is not None and time.monotonic() - began > cfg.stage_seconds, world):
                break
            if _all_agree(time.monotonic() - last_save > cfg.checkpoint_every_s, world):
                save(done)
                last_save = time.monotonic()
        save(done)
        metrics = {"stage": task.name, "steps": done, "wall_time_s": round(elapsed_before + time.monotonic() - began, 1),
                   **{k: v.item() for k, v in terms.items()}}
        if task.finish is not None:
            metrics.update(task.finish(ema.shadow, dataset))
        if rank == 0:
            checkpoint.save_atomic({"parts": {k: m.state_dict() for k, m in ema.shadow.items()},
                                    "metrics": metrics, "model_config": cfg.model.to_dict()}, run_dir / "final.pt")
            log.write(json.dumps({"final": metrics}) + "\n")
    finally:
        bar.close()
        if log is not None:
            log.close()
    if world > 1:
        dist.barrier()
    return metrics


def train(stage: str, cfg: TrainConfig, dataset: Dataset, runs: str | Path = "runs", resume: bool = False,
          progress: bool = True) -> dict:
    """Train one stage, or every stage in order for 'all'. Returns {stage: final metrics}."""
    runs = Path(runs)
    results = {}
    for name in (STAGES if stage == "all" else (stage,)):
        run_dir = runs / name
        run_dir.mkdir(parents=True, exist_ok=True)
        task = build_stage(name, cfg, runs, dataset)
        results[name] = run_task(task, dataset, cfg, run_dir, resume=resume, progress=progress)
    return results


def init_distributed_from_env() -> bool:
    """Join the process group torchrun describes (gloo on CPU, nccl on GPU). True when this call
    joined one (the caller then destroys it); False when not under torchrun or already joined."""
    if "WORLD_SIZE" not in os.environ or int(os.environ["WORLD_SIZE"]) < 2 or dist.is_initialized():
        return False
    if torch.cuda.is_available():
        torch.cuda.set_device(int(os.environ.get("LOCAL_RANK", 0)))
    dist.init_process_group("nccl" if torch.cuda.is_available() else "gloo")
    return True

"""`sketch2colab generate`: storyboard in, motion out, with progress and adherence figures.

Drives the same sampler generator as the app and the benchmark, prints a progress bar (or one
line per step with `log_steps`), writes the requested exports and returns the summary that the
command prints as its last line of JSON: wall time, time to the first step, network
evaluations and the storyboard's own adherence figures (engine.metrics.adherence).
"""
from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Generator, TextIO

import numpy as np

from .metrics import adherence
from .sampling.events import GenerationResult, StepEvent
from .storyboard import Storyboard

RETRIEVAL = "retrieval"


def run_generation(gen: Generator[StepEvent, None, GenerationResult], out: TextIO | None = None,
                   log_steps: bool = False) -> GenerationResult:
    """Drive a sampler generator to the end, reporting progress on `out` (None: silent)."""
    try:
        while True:
            event = next(gen)
            if out is not None:
                _progress(event, out, log_steps)
    except StopIteration as stop:
        if out is not None and not log_steps:
            out.write("\n")
        return stop.value


def _progress(event: StepEvent, out: TextIO, log_steps: bool) -> None:
    done = event.step + 1
    energy = event.energies.get("total")
    tail = f" energy {energy:.4f}" if energy is not None else ""
    if log_steps:
        out.write(f"step {done}/{event.num_steps} t={event.t:.3f}{tail}\n")
    else:
        width = 30
        filled = int(width * done / event.num_steps)
        out.write(f"\r[{'#' * filled}{'.' * (width - filled)}] {done}/{event.num_steps}{tail}")
    out.flush()


def retrieval_generator(storyboard: Storyboard, seed: int):
    from .baselines.retrieval import default_index, sample_retrieval
    index, _ = default_index()
    return sample_retrieval(index, storyboard, seed=seed)


def generate(storyboard: Storyboard, config, bundle=None, method: str = "student",
             quiet: bool = False, log_steps: bool = False) -> GenerationResult:
    """Generate with the sampler (`config`: SamplerConfig) or the retrieval baseline, reporting
    progress on the current sys.stderr unless quiet (looked up per call: it may be swapped)."""
    if method == RETRIEVAL:
        gen = retrieval_generator(storyboard, config.seed)
    else:
        from .models.bundle import load_default
        from .request import Request
        from .sampling.sampler import sample
        gen = sample(bundle or load_default(), Request.build(storyboard, config))
    return run_generation(gen, None if quiet else sys.stderr, log_steps)


def summary(result: GenerationResult, storyboard: Storyboard, method: str) -> dict:
    """The figures the command prints: timing and the first variation's adherence."""
    figures = adherence(result.clips[0], storyboard)
    return {"method": method, "wall_time_s": round(result.wall_time_s, 4),
            "first_step_s": round(result.first_step_s, 4), "network_evals": result.network_evals,
            "variations": len(result.clips),
            **{k: (round(float(v), 5) if np.isfinite(v) else None) for k, v in figures.items()}}


def write_outputs(result: GenerationResult, output: Path) -> list[Path]:
    """The first variation at `output`; further variations beside it as STEM_v2.npz, ..."""
    written = []
    for k, clip in enumerate(result.clips):
        path = output if k == 0 else output.with_name(f"{output.stem}_v{k + 1}{output.suffix}")
        clip.save(path)
        written.append(path)
    return written


def print_summary(figures: dict) -> None:
    """The command's last line: one JSON object."""
    print(json.dumps(figures))

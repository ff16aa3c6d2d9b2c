"""What the sampler streams. The GUI worker, the CLI and the benchmark all consume these.

`sample(...)` (sampler.py) is a generator: it yields one StepEvent per solver step and
returns (StopIteration.value) a GenerationResult. Closing the generator cancels between steps.
"""
from __future__ import annotations

import time
from contextlib import contextmanager
from dataclasses import dataclass, field
from functools import cached_property
from typing import Callable

import numpy as np

from ..clip import MotionClip


@dataclass
class StepEvent:
    step: int                    # 0-based index of the finished solver step
    num_steps: int
    t: float                     # solver time after this step (1 = noise, 0 = data)
    latent: np.ndarray           # (K, T_lat, V, d) current latent of all K variations (empty: from another process)
    decode: Callable[[], MotionClip] | None  # decodes the current motion, variation 0 (see preview);
                                             # None: not here (a step from another process not shown)
    phase: np.ndarray            # (N, 3) CTMC occupancy of approach / contact / carry per frame
    energies: dict[str, float] = field(default_factory=dict)  # energy name -> value at this step

    @cached_property
    def preview(self) -> MotionClip:
        """The decoded motion of this step, decoded on first access: a consumer that does not
        look (the command line, the benchmark) does not pay for it; the app's worker thread
        reads it before handing the event to the GUI."""
        return self.decode()

    @property
    def decoded(self) -> bool:
        """Whether `preview` has been read already (here, or where the event was made)."""
        return "preview" in self.__dict__


@dataclass
class GenerationResult:
    clips: list[MotionClip]      # one per variation, each with .phase filled
    wall_time_s: float
    first_step_s: float          # time from the call to the first StepEvent
    network_evals: int
    stage_s: dict[str, float] = field(default_factory=dict)   # where the time went (StageClock)
    notes: list[str] = field(default_factory=list)   # what finishing could not make exact, for the
                                                     # artist (engine.finishing.misses), variation 1


class StageClock:
    """Seconds one generation spends in each named stage: `with clock("network"): ...`."""

    def __init__(self):
        self.seconds: dict[str, float] = {}

    @contextmanager
    def __call__(self, stage: str):
        start = time.perf_counter()
        try:
            yield
        finally:
            self.seconds[stage] = self.seconds.get(stage, 0.0) + time.perf_counter() - start

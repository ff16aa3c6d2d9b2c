"""What the sampler streams. The GUI worker, the CLI and the benchmark all consume these.

`sample(...)` (sampler.py) is a generator: it yields one StepEvent per solver step and
returns (StopIteration.value) a GenerationResult. Closing the generator cancels between steps.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..clip import MotionClip


@dataclass
class StepEvent:
    step: int                    # 0-based index of the finished solver step
    num_steps: int
    t: float                     # solver time after this step (1 = noise, 0 = data)
    latent: np.ndarray           # (K, T_lat, V, d) current latent of all K variations
    preview: MotionClip          # decoded motion of the current latent, variation 0
    phase: np.ndarray            # (N, 3) CTMC occupancy of approach / contact / carry per frame
    energies: dict[str, float] = field(default_factory=dict)  # energy name -> value at this step


@dataclass
class GenerationResult:
    clips: list[MotionClip]      # one per variation, each with .phase filled
    wall_time_s: float
    first_step_s: float          # time from the call to the first StepEvent
    network_evals: int

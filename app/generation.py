"""The one place where the app reaches the sampler: settings in, a generator of StepEvents out.

`start_generation` is what the worker drives; tests hand the worker a fake with the same shape.
"""
from __future__ import annotations

from collections.abc import Generator
from dataclasses import dataclass
from functools import lru_cache

from engine.sampling.events import GenerationResult, StepEvent
from engine.storyboard import Storyboard


@dataclass(frozen=True)
class GenerationSettings:
    """What the properties panel edits; mirrors the sampler's SamplerConfig."""
    steps: int = 30
    seed: int = 0
    cfg: float = 1.6
    use_energy: bool = True
    use_ctmc: bool = True
    steady: bool = False            # damped guidance (SamplerConfig.guidance_max_rate)
    variations: int = 1


StepStream = Generator[StepEvent, None, GenerationResult]


@lru_cache(maxsize=1)
def _bundle():
    from engine.models.bundle import load_default
    return load_default()


def start_generation(storyboard: Storyboard, settings: GenerationSettings) -> StepStream:
    """Stream one generation. Nothing runs until the first next(), so the model loads on the
    worker thread, never on the GUI thread; closing the generator cancels between steps."""
    from engine.sampling.sampler import STEADY_GUIDANCE_RATE, SamplerConfig, sample
    config = SamplerConfig(steps=settings.steps, seed=settings.seed, cfg=settings.cfg,
                           use_energy=settings.use_energy, use_ctmc=settings.use_ctmc,
                           guidance_max_rate=STEADY_GUIDANCE_RATE if settings.steady else None,
                           variations=settings.variations)
    return (yield from sample(_bundle(), storyboard, config))

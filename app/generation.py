"""The one place where the app reaches the sampler: settings in, a generator of StepEvents out.

`start_generation` is what the worker drives; tests hand the worker a fake with the same shape.
`warm_up` readies the model while the artist starts sketching. In the app both run in the
generation process (app.engine_process); tests run them here.
"""
from __future__ import annotations

import sys
import threading
from collections.abc import Callable, Generator
from dataclasses import dataclass, fields, replace
from functools import lru_cache
from pathlib import Path

from engine.sampling.config import DEFAULT_STEPS
from engine.sampling.events import GenerationResult, StepEvent
from engine.storyboard import Storyboard


@dataclass(frozen=True)
class GenerationSettings:
    """What the properties panel edits; mirrors the sampler's SamplerConfig."""
    steps: int = DEFAULT_STEPS
    seed: int = 0
    cfg: float = 1.6
    text_cfg: float = 1.6           # the text's own guidance weight (SamplerConfig.text_cfg; as cfg: plain)
    use_energy: bool = True
    use_ctmc: bool = True
    steady: bool = False            # damped guidance (SamplerConfig.guidance_max_rate)
    variations: int = 1
    preview: bool = False           # the fast preview path (while a joint or an object is dragged)
    after_drag: bool = False        # the full generation a live-previewed drag's release starts
    # Of the machine, not the document: the window fills these in from its preferences.
    threads: int | None = None      # torch threads (None: the cores other programs leave free)
    reserve_cores: float = 0.0      # cores left to the viewport's drawing (software OpenGL)

    @property
    def streams_steps(self) -> bool:
        """Whether the run's steps are shown as it goes: a live preview's are not (its result
        comes within a tenth of a second, and its steps decoded and drawn took the cores from it)."""
        return not self.preview


STEP_INTERVAL_S = 0.1   # the least time between two steps handed to the views

# Settings of this machine or this moment, not of a take (left out of the takes kept).
MACHINE_SETTINGS = ("preview", "threads", "reserve_cores")


def settings_of(take_settings: dict, current: GenerationSettings) -> GenerationSettings:
    """The settings a take was generated with (its kept dict), on this machine's `current`
    ones: choosing a take makes the next generation reproduce it. Whether it came after a drag
    is the take's, not the next generation's."""
    kept = {}
    for f in fields(GenerationSettings):
        value, default = take_settings.get(f.name), getattr(current, f.name)
        # A takes file is read from disk: only values of the field's own kind (a float may be whole).
        if (f.name not in MACHINE_SETTINGS and f.name != "after_drag"
                and (type(value) is type(default) or (type(default) is float and type(value) is int))):
            kept[f.name] = type(default)(value)
    return replace(current, **kept)

StepStream = Generator[StepEvent, None, GenerationResult]


_LOADING = threading.Lock()


@lru_cache(maxsize=1)
def _load_bundle():
    from engine.models.bundle import load_default
    return load_default()


def _bundle():
    with _LOADING:  # the warm-up and the first Generate may both ask: load once
        return _load_bundle()


def start_generation(storyboard: Storyboard, settings: GenerationSettings,
                     checkpoint: Callable[[], None] = lambda: None) -> StepStream:
    """Stream one generation. Nothing runs until the first next(), so the model loads on the
    worker thread, never on the GUI thread; closing the generator cancels between steps, and
    what `checkpoint` raises between the finishing's stages stops it there."""
    from engine.request import Request
    from engine.sampling.config import sampler_config
    from engine.sampling.sampler import sample
    config = sampler_config(steps=settings.steps, seed=settings.seed, cfg=settings.cfg, variations=settings.variations,
                            energy=settings.use_energy, ctmc=settings.use_ctmc, steady=settings.steady,
                            preview=settings.preview, threads=settings.threads, reserve_cores=settings.reserve_cores,
                            text_cfg=None if settings.text_cfg == settings.cfg else settings.text_cfg)
    return (yield from sample(_bundle(), Request.build(drawn_cast(storyboard), config), checkpoint))


def drawn_cast(storyboard: Storyboard) -> Storyboard:
    """The storyboard without its last agents for whom nothing is drawn (no keypose, stroke or
    contact), unless nothing is drawn for anyone: a person the artist left alone is not in the
    scene (animated anyway, the document's second person wandered into a solo lift). The agents
    before a drawn one stay: a clip's people are the storyboard's first agents."""
    drawn = {k.agent for k in storyboard.keyposes} | {t.agent for t in storyboard.trajectories} \
        | {c.agent for c in storyboard.contacts} | {c.other_agent for c in storyboard.contacts}
    last = max((i for i, a in enumerate(storyboard.agents) if a.id in drawn), default=len(storyboard.agents) - 1)
    return replace(storyboard, agents=storyboard.agents[:last + 1])


def warm_up(storyboard_path: Path, settings: GenerationSettings = GenerationSettings(steps=2)) -> None:
    """Load the model and run a short generation (`settings`) of the storyboard at `storyboard_path`, so that
    the artist's first Generate runs at full speed: in a fresh process the first generation took
    1.8 s against 0.8 s for the next (loading, and every kernel's first call at these shapes).
    Runs on any thread; a failure is left to the first Generate, which reports it properly."""
    from engine.generate import run_generation
    try:
        run_generation(start_generation(Storyboard.load(storyboard_path), settings))
    except Exception as e:  # noqa: BLE001  the app must start whatever the model or the file does
        print(f"warm-up skipped: {type(e).__name__}: {e}", file=sys.stderr)

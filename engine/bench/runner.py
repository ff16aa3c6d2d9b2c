"""Run the benchmark's methods on a protocol's storyboards and score every sample.

Every method drives a generator with the sampler's streaming contract (engine.sampling.sampler
or the retrieval baseline), so timing, first-step latency and network evaluations are measured
the same way for all. Figures per sample come from engine.metrics.adherence (against the held-out
clip the storyboard was sketched from) plus contact timing against the synthesizer's per-hand
labels (engine.metrics.contact_f1 / expected_calibration_error / brier_score).
"""
from __future__ import annotations

import functools
from dataclasses import dataclass, field, replace
from typing import Callable

import numpy as np

from ..baselines.retrieval import RetrievalIndex, sample_retrieval
from ..baselines.sketch2anim import sample_sketch2anim
from ..clip import MotionClip
from ..generate import run_generation
from ..metrics import adherence, brier_score, contact_f1, diversity, expected_calibration_error
from ..request import Request
from ..sampling.config import STEADY_GUIDANCE_RATE, SamplerConfig, sampler_config
from ..sampling.sampler import sample
from ..storyboard import Storyboard
from .animator import animator_metrics
from .protocol import BenchItem, Protocol


@dataclass(frozen=True)
class Method:
    key: str                            # JSON key
    label: str                          # table row
    sampler: SamplerConfig | None       # None: the retrieval baseline
    untrained: bool = False             # run on freshly initialised weights (what finishing alone does)
    needs: str | None = None            # a baseline part the bundle must hold (load_baselines), else skipped
    generator: Callable | None = None   # (bundle, Request) -> the streaming generator; None: the sampler

    def available(self, bundle) -> bool:
        return self.needs is None or bundle.has_part(self.needs)


OURS = Method("ours", "Ours", SamplerConfig())
# The same with three times the steps: what the default's speed costs (engine.sampling.config).
OURS_30 = Method("ours_30", "Ours, 30 steps", SamplerConfig(steps=30))
# The same storyboards with their text left out (what the text adds, on the sketch+text protocol).
OURS_NO_TEXT = Method("ours_no_text", "Ours, text ignored", SamplerConfig(use_text=False))
# The paper's baseline as it is: the teacher's samples, without our finishing pass.
TEACHER_DDPM = Method("teacher_ddpm", "COLLAGE Teacher (DDPM-1000)", SamplerConfig(method="teacher-ddpm", finish=False))
TEACHER_DDIM = Method("teacher_ddim", "COLLAGE Teacher (DDIM-50)",
                      SamplerConfig(method="teacher-ddim", steps=50, finish=False))
# The fair comparison: the same finishing on the teacher, and on a model that learnt nothing.
TEACHER_DDPM_FINISHED = Method("teacher_ddpm_fin", "Teacher (DDPM-1000) + finishing", SamplerConfig(method="teacher-ddpm"))
TEACHER_DDIM_FINISHED = Method("teacher_ddim_fin", "Teacher (DDIM-50) + finishing",
                               SamplerConfig(method="teacher-ddim", steps=50))
UNTRAINED_FINISHED = Method("untrained_fin", "untrained + finishing", SamplerConfig(), untrained=True)
RETRIEV_ADAPT = Method("retrievadapt", "RetrievAdapt", None)
STEADY = Method("ours_steady", "Ours, steady", SamplerConfig(guidance_max_rate=STEADY_GUIDANCE_RATE))
ABLATIONS = (
    Method("wo_finishing", "w/o finishing", SamplerConfig(finish=False)),
    Method("wo_energy", "w/o Energy", SamplerConfig(use_energy=False)),
    Method("wo_ctmc", "w/o CTMC", SamplerConfig(use_ctmc=False)),
    Method("wo_latent", "w/o latent grounding", SamplerConfig(use_latent=False)),
    Method("wo_temporal_bias", "w/o temporal bias", SamplerConfig(use_temporal_bias=False)),
    Method("trajectory_only", "trajectory-only", SamplerConfig(trajectory_only=True)),
    # The storyboard through one ControlNet branch per condition type instead of the entity
    # conditioning: a student of its own, trained as ours (scripts/train_baselines.sh).
    Method("parallel_controlnets", "parallel ControlNets", SamplerConfig(student_part="controlnet_student"),
           needs="controlnet_student"),
)
# The paper's strongest baseline (engine.baselines.sketch2anim), with our finishing. Its CFG
# weight was chosen on the four bundled examples (not the benchmark's storyboards), raw motion
# before finishing, K2D / T2D: 1.0 0.45 / 0.27 m, 1.3 0.46 / 0.30, 1.6 0.51 / 0.33, 2.0 0.61 / 0.42
# (guidance extrapolated in raw frame features overshoots; at 5.0 people landed metres away).
SKETCH2ANIM = Method("sketch2anim_int", "Sketch2Anim-INT (DDIM-50) + finishing", SamplerConfig(steps=50, cfg=1.0),
                     needs="sketch2anim", generator=sample_sketch2anim)
# The few-step preview student: as an artist sees it while dragging, and with the full guidance
# and finishing (where quality holds, the way to a full generation at 20x the teacher).
PREVIEW = Method("ours_preview", "Ours, preview", sampler_config(preview=True))
FEW_STEP = Method("ours_few_step", "Ours, preview student + full guidance and finishing",
                  replace(sampler_config(), few_step=True, ctmc_every=1))
ALL_METHODS = (OURS, OURS_30, OURS_NO_TEXT, PREVIEW, FEW_STEP, STEADY, TEACHER_DDPM, TEACHER_DDIM, TEACHER_DDPM_FINISHED, TEACHER_DDIM_FINISHED,
               UNTRAINED_FINISHED, RETRIEV_ADAPT, SKETCH2ANIM) + ABLATIONS


@functools.lru_cache(maxsize=1)
def _untrained_bundle():
    from ..models.bundle import untrained_bundle
    return untrained_bundle()


def is_ddpm(method: Method) -> bool:
    return method.sampler is not None and method.sampler.method == "teacher-ddpm"


@dataclass
class Generation:
    """One generation: K clips and how long they took. `trace` holds (t, latent (K, T, V, d),
    energies) per streamed step when asked for (the diagnostics read it)."""
    clips: list[MotionClip]
    wall_time_s: float
    first_step_s: float
    network_evals: int
    trace: list[tuple[float, np.ndarray, dict[str, float]]] = field(default_factory=list)
    stage_s: dict[str, float] = field(default_factory=dict)   # GenerationResult.stage_s


@dataclass
class SampleResult:
    protocol: str
    item: str
    group: str
    noise: float
    method: str
    metrics: dict[str, float]
    wall_time_s: float
    network_evals: int
    clip: MotionClip                    # variation 0 (for FID / R-precision)
    storyboard: Storyboard


@dataclass
class RunnerConfig:
    seed: int = 0
    variations: int = 3                 # variations drawn for the diversity figure ...
    diversity_items: int = 4            # ... on the first this many items of a protocol
    ddpm_items: int = 10                # DDPM-1000 is slow: only the first this many items
    cfg: float | None = None            # guidance weight override (None: each method's default)


def generate(bundle, method: Method, storyboard: Storyboard, seed: int = 0, variations: int = 1,
             index: RetrievalIndex | None = None, trace: bool = False) -> Generation:
    """Run `method` on one storyboard. The retrieval baseline draws variations with seeds
    seed, seed + 1, ... (it makes one clip per call)."""
    if method.sampler is None:
        if index is None:
            raise ValueError("the retrieval baseline needs an index")
        runs = [run_generation(sample_retrieval(index, storyboard, seed=seed + k), None) for k in range(variations)]
        return Generation([r.clips[0] for r in runs], sum(r.wall_time_s for r in runs), runs[0].first_step_s, 0)
    bundle = _untrained_bundle() if method.untrained else bundle
    gen = (method.generator or sample)(bundle, Request.build(storyboard, replace(method.sampler, seed=seed,
                                                                                 variations=variations)))
    steps = []
    try:
        while True:
            event = next(gen)
            if trace:
                steps.append((event.t, event.latent, dict(event.energies)))
    except StopIteration as stop:
        result = stop.value
    return Generation(result.clips, result.wall_time_s, result.first_step_s, result.network_evals, steps,
                      result.stage_s)


def sample_metrics(clip: MotionClip, item: BenchItem) -> dict[str, float]:
    """adherence() against the held-out clip and what an animator looks at (bench.animator), with
    contact timing scored per hand against the synthesizer's labels (clip.contact probabilities
    vs reference.contact) where labels exist."""
    figures = {**adherence(clip, item.storyboard, item.reference),
               **animator_metrics(clip, item.storyboard, item.reference)}
    for key in ("ContactF1", "ECE", "Brier"):          # adherence's are against the storyboard's spans
        figures.pop(key, None)
    label = item.reference.contact
    if label is not None and clip.contact is not None:
        prob, truth = np.clip(clip.contact, 0.0, 1.0), label > 0.5
        figures["ContactF1"] = contact_f1(prob > 0.5, truth)
        figures["ECE"] = expected_calibration_error(prob, truth)
        figures["Brier"] = brier_score(prob, truth)
    return figures


def run_protocol(bundle, protocol: Protocol, methods: tuple[Method, ...], config: RunnerConfig = RunnerConfig(),
                 index: RetrievalIndex | None = None, log=None) -> list[SampleResult]:
    """Every method on every item of the protocol (DDPM on the first `ddpm_items` only)."""
    results = []
    for method in methods:
        if not method.available(bundle):
            continue
        items = protocol.items[:config.ddpm_items] if is_ddpm(method) else protocol.items
        if config.cfg is not None and method.sampler is not None:
            method = replace(method, sampler=replace(method.sampler, cfg=config.cfg))
        for n, item in enumerate(items):
            k = config.variations if n < config.diversity_items else 1
            g = generate(bundle, method, item.storyboard, config.seed, k, index)
            figures = sample_metrics(g.clips[0], item)
            if k > 1:
                figures["Diversity"] = diversity(np.stack([c.joints for c in g.clips]))
            results.append(SampleResult(protocol.name, item.id, item.group, item.noise, method.key, figures,
                                        g.wall_time_s / k, g.network_evals, g.clips[0], item.storyboard))
            if log:
                log(f"{protocol.name} {method.label} {item.id} noise {item.noise:g}: {g.wall_time_s:.1f} s")
    return results

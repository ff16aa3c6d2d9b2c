"""Sketch2Anim-INT: the paper's multi-entity adaptation of single-person Sketch2Anim (its strongest
baseline), as a method with the sampler's streaming contract.

Sketch2Anim's design: a motion diffusion model in raw motion space, a 2D-3D aligned sketch
encoder, and keypose and trajectory control branches (ControlNet-style) on the denoiser. Adapted
to two people and an object (engine.models.sketch2anim): the three entities' raw frame features
are the denoiser's tokens, with the same entity attention as our backbone, and an object branch
joins the keypose and trajectory branches. No VQ latent, no distillation, no energy guidance, no
phase planner: what the paper credits for the gap. It runs DDIM with classifier-free guidance,
and its clips go through the same finishing as ours.
"""
from __future__ import annotations

import time
from typing import Generator

import torch

from ..cpu import ThreadBudget
from ..models.vqvae import NUM_HUMANS
from ..request import Request
from ..sampling.cfg import ClassifierFreeGuidance
from ..sampling.events import GenerationResult, StepEvent
from ..sampling.output import Output
from ..sampling.solvers import ddim_step, ddim_times

# Bound on DDIM's clean estimate, in the features' standard deviations (DDPM's clip_denoised: the
# data's range; 99.9% of normalized training features lie within 7.8). Without it an estimate
# near pure noise, multiplied by up to 1 / sqrt(alpha_bar) = 150, threw people 100 m away.
RAW_CLIP = 10.0

def sample_sketch2anim(bundle, request: Request) -> Generator[StepEvent, None, GenerationResult]:
    """The sampler's streaming contract for Sketch2Anim-INT: DDIM over `request.config.steps`
    steps with CFG weight `request.config.cfg`, then the same output and finishing as ours.
    `bundle` holds the baseline as its part `sketch2anim` (engine.models.bundle.load_baselines)."""
    cfg, model, vqvae = request.config, bundle.sketch2anim, bundle.vqvae
    threads = ThreadBudget(cfg.threads, cfg.reserve_cores)
    threads.adjust()
    start = time.perf_counter()
    view = request.for_model(bundle.config.vqvae.time_factor)
    k = cfg.variations
    controls = {name: torch.as_tensor(v)[None].expand(k, *v.shape).contiguous() for name, v in view.fixed.items()}
    output = Output(request, view)
    uniform = output.phase(None, 0)
    generator = torch.Generator().manual_seed(cfg.seed)
    evals, first = 0, None
    with torch.no_grad():
        cond = model.condition(controls, view.length)
        guided = ClassifierFreeGuidance(model.denoiser.eps, cfg.cfg)

        def eps(x, tau):
            nonlocal evals
            evals += 1
            return guided(x, tau, cond)

        x = torch.randn((k, view.length, NUM_HUMANS + 1, model.feature_dim), generator=generator)
        taus = ddim_times(cfg.steps)
        for i in range(cfg.steps):
            x, x0 = ddim_step(eps, model.denoiser.schedule, x, taus[i], taus[i + 1], clip=RAW_CLIP)
            first = first or time.perf_counter() - start
            shown = x if i == cfg.steps - 1 else x0

            def decode(shown=shown):
                with torch.no_grad():
                    return output.clip(model.motion(vqvae, shown), 0, uniform)

            yield StepEvent(step=i, num_steps=cfg.steps, t=float(taus[i + 1]), latent=x.numpy().copy(),
                            decode=decode, phase=output.at_storyboard_rate(uniform), energies={})
            threads.adjust()
        clips = output.final_clips(model.motion(vqvae, x), None)
    return GenerationResult(clips=clips, wall_time_s=time.perf_counter() - start, first_step_s=first or 0.0,
                            network_evals=evals)


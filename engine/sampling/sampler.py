"""The guided streaming sampler (paper sections 3.2-3.4 and 4): one generator for every method.

    gen = sample(bundle, Request.build(storyboard, SamplerConfig(seed=0)))
    for event in gen:            # one StepEvent per solver step; gen.close() cancels
        ...
    result = <StopIteration.value>  (a GenerationResult)

This module only orchestrates; each part has its own home:
    engine.request       the storyboard read once, at the model's rate, with its controls
    solvers.py           Heun / DDPM / DDIM steps as functions of (field, z, t)
    cfg.py               classifier-free guidance of a field
    guidance.py          energy guidance on the clean-latent estimate
    output.py            decoding, clips at the storyboard's rate, finishing
    the bundle's planner the CTMC occupancy, re-planned here and passed to the field and the energies

Preview (few_step): the preview student's jumps, one conditional evaluation each (classifier-free
guidance distilled into it); otherwise as below.

Student (default): z_1 ~ N(0, I); a guided Heun ODE from t = 1 (noise) to t = 0 (data) on the
rectified-flow student, classifier-free guided (weight `cfg`, conditional and unconditional
passes in one batch), its S = 3 phase sub-fields mixed by the CTMC occupancy, re-planned every
`ctmc_every` steps (0: on the result only). After each step, guidance moves the clean estimate
z0_hat; the step keeps its noise estimate, so the correction enters the trajectory at the scale
(1 - t) it would have had at that time. An optional micro-Langevin pass with the teacher's score
sharpens the end, and the final clips go through engine.finishing (keyposes, paths, feet and
contacts made exact).

Teacher methods (DDPM 1000 steps, DDIM) run the frozen teacher unguided, as the "COLLAGE
Teacher" baseline. Ablations are flags of the same config.
"""
from __future__ import annotations

import time
from dataclasses import replace
from typing import Callable, Generator, Protocol

import torch

from ..cpu import ThreadBudget
from ..finishing.misses import missed_holds
from ..models.preview import preview_times
from ..request import Request
from .cfg import ClassifierFreeGuidance
from .config import SamplerError
from .energies import EnergyContext
from .events import GenerationResult, StageClock, StepEvent
from .guidance import EnergyGuidance
from .output import LatentDecoder, Output
from .solvers import (ddim_step, ddim_times, ddpm_step, ddpm_times, flow_clean_estimate, flow_renoise, flow_times,
                      heun_step)


class Bundle(Protocol):
    """What the sampler reads of engine.models.bundle.ModelBundle."""
    config: object                  # ModelConfig: .vqvae.latent_dim, .vqvae.time_factor
    metadata: dict                  # "stages": the training stages its weights went through
    vqvae: torch.nn.Module          # .decode(z), .decode_lowres(z)
    conditioner: torch.nn.Module    # .encode(controls, t_lat, v) -> SketchEncoding
    latent_head: torch.nn.Module    # f_gamma
    student: torch.nn.Module        # RectifiedFlowStudent
    preview: torch.nn.Module        # the few-step preview student (a RectifiedFlowStudent)
    trained: bool

    def has_part(self, name: str) -> bool: ...
    teacher: torch.nn.Module        # DiffusionTeacher
    planner: torch.nn.Module        # PhasePlanner
    surrogate: torch.nn.Module      # JacobianSurrogate


def sample(bundle: Bundle, request: Request,
           checkpoint: Callable[[], None] = lambda: None) -> Generator[StepEvent, None, GenerationResult]:
    """The request's generation, a step at a time (closing the generator stops it between steps);
    `checkpoint` runs between the stages of the finishing after the last step, and what it raises
    stops the run there."""
    config = request.config
    if config.few_step and bundle.trained and not bundle.has_part("preview"):
        raise SamplerError("this model bundle has no preview student (train it: sketch2colab train preview)")
    if config.student_part != "student" and not bundle.has_part(config.student_part):
        raise SamplerError(f"this model bundle has no trained {config.student_part!r} (see scripts/train_baselines.sh)")
    threads = ThreadBudget(config.threads, config.reserve_cores)
    threads.adjust()
    run = _Run(bundle, request, checkpoint)
    with torch.no_grad():
        steps = run.student() if config.method == "student" else run.teacher()
        try:
            while True:
                try:
                    event = next(steps)
                except StopIteration as done:
                    return done.value
                yield event
                threads.adjust()
        finally:
            steps.close()


class _Run:
    """One generation's state: the conditioning, the planner's occupancy, the clock."""

    def __init__(self, bundle: Bundle, request: Request, checkpoint: Callable[[], None]):
        self.bundle, self.cfg, self.checkpoint = bundle, request.config, checkpoint
        self.start = time.perf_counter()
        self.clock = StageClock()
        self.first_step: float | None = None
        self.evals = 0
        k = self.cfg.variations
        view = request.for_model(bundle.config.vqvae.time_factor)
        self.latent_shape = (k, view.length // bundle.config.vqvae.time_factor, 3, bundle.config.vqvae.latent_dim)
        self.generator = torch.Generator().manual_seed(self.cfg.seed)
        self.controls = {name: torch.as_tensor(v)[None].expand(k, *v.shape).contiguous()
                         for name, v in view.fixed.items()}
        with self.clock("conditioning"):
            enc = bundle.conditioner.encode(self.controls, self.latent_shape[1], 3)
        self.cond = enc.conditioning
        if not self.cfg.use_temporal_bias:
            self.cond = replace(self.cond, temporal_bias=torch.zeros_like(self.cond.temporal_bias))
        if not self.cfg.use_text:
            self.cond = self.cond.without_text(torch.ones(k, dtype=torch.bool))
        humans = len(request.storyboard.agents)
        energies = EnergyContext.from_controls(view.storyboard, view.controls, batch=k,
                                               K3D_hat=enc.lifted.keyposes[:, :, :humans],
                                               T3D_hat=enc.lifted.trajectories[:, :, :humans])
        self.decode = LatentDecoder(bundle.vqvae)
        self.output = Output(request, view)
        self.guidance = EnergyGuidance(bundle, self.cfg, energies, self.decode, self.output.storyboard_view,
                                       enc.s2d, enc.present)
        self.occupancy: torch.Tensor | None = None   # the planner's state: (K, N, 3), None before the first plan

    def _plan(self, z0: torch.Tensor) -> None:
        """Re-plan the CTMC occupancy (K, N, 3) from the clean estimate and its decode."""
        with self.clock("planning"):
            self.occupancy = self.bundle.planner(z0, self.decode(z0), self.controls["contact"]).occupancy

    def _event(self, step: int, num: int, t: float, z: torch.Tensor, z0: torch.Tensor,
               energies: dict[str, float]) -> StepEvent:
        if self.first_step is None:
            self.first_step = time.perf_counter() - self.start
        z0, phase, out = z0.clone(), self.output.phase(self.occupancy, 0), self.output

        def decode():  # the step's state is captured: it may run after later steps
            with torch.no_grad():
                return out.clip(self.decode(z0), 0, phase)

        return StepEvent(step=step, num_steps=num, t=t, latent=z.numpy().copy(), decode=decode,
                         phase=out.at_storyboard_rate(phase), energies=energies)

    def _result(self, z0: torch.Tensor) -> GenerationResult:
        self.checkpoint()
        with self.clock("decode"):
            motion = self.decode(z0)
        with self.clock("finishing"):
            clips = self.output.final_clips(motion, self.occupancy, self.checkpoint)
        notes = missed_holds(clips[0], self.output.storyboard) if self.cfg.finish else []
        return GenerationResult(clips=clips, wall_time_s=time.perf_counter() - self.start,
                                first_step_s=self.first_step or 0.0, network_evals=self.evals,
                                stage_s=dict(self.clock.seconds), notes=notes)

    # ---- student: guided Heun ODE, or the preview student's jumps ------------------------------
    def _velocity_field(self, entity_pos: torch.Tensor | None):
        """The student velocity (z, t) -> v at the current occupancy, its sub-fields mixed by it
        (uniform before the first plan and without CTMC); one network evaluation per call. The
        student is CFG-guided (cond and uncond as one batch, so the occupancy is repeated to
        match); the preview student has the guidance distilled in (one conditional pass)."""
        occupancy = self.occupancy
        network = self.bundle.preview if self.cfg.few_step else getattr(self.bundle, self.cfg.student_part)

        def student(z, time, cond, pos):
            occ = None if occupancy is None else occupancy.repeat(z.shape[0] // occupancy.shape[0], 1, 1)
            return network.velocity(z, time, cond, pos, occ)

        guided = ClassifierFreeGuidance(student, 1.0 if self.cfg.few_step else self.cfg.cfg, self.cfg.text_cfg)

        def field(z: torch.Tensor, t: float) -> torch.Tensor:
            self.evals += 1
            with torch.inference_mode(), self.clock("network"):  # inference_mode: ~10% faster than no_grad
                return guided(z, torch.full((z.shape[0],), t), self.cond, entity_pos)

        return field

    def student(self) -> Generator[StepEvent, None, GenerationResult]:
        cfg, guidance = self.cfg, self.guidance
        z = torch.randn(self.latent_shape, generator=self.generator)
        ts = preview_times(self.bundle.config.preview_steps) if cfg.few_step else flow_times(cfg.steps)
        steps = len(ts) - 1
        entity_pos, z0 = None, z
        for i in range(steps):
            t, t_next = ts[i], ts[i + 1]
            field = self._velocity_field(entity_pos)
            if cfg.few_step:         # one jump: the clean estimate and the noise it came from
                v = field(z, t)
                z0 = flow_clean_estimate(z, v, t)
                noise = z0 + v
            else:
                z_next, v_end = heun_step(field, z, t, t_next)
                z0 = flow_clean_estimate(z_next, v_end, t_next)
                noise = (z_next - (1 - t_next) * z0) / max(t_next, 1e-8)
            if cfg.use_ctmc and cfg.ctmc_every and i % cfg.ctmc_every == 0:
                self._plan(z0)
            energies = {}
            if guidance.active and t_next <= cfg.guidance_start:
                with self.clock("guidance"):
                    z0, energies = guidance.guide(z0, t_next, cfg.guidance_steps, self.occupancy,
                                                  cfg.guidance_max_rate)
            z = flow_renoise(z0, noise, t_next)
            with self.clock("decode"):
                entity_pos = self.bundle.vqvae.decode_lowres(z0)
            yield self._event(i, steps, t_next, z, z0, energies)
        if guidance.active:
            with self.clock("guidance"):
                z0, _ = guidance.guide(z0, 0.0, cfg.final_refine_steps, self.occupancy)
        with self.clock("network"):
            z0 = self._langevin(z0)
        if cfg.use_ctmc:
            self._plan(z0)
        return self._result(z0)

    def _langevin(self, z0: torch.Tensor) -> torch.Tensor:
        """Micro-Langevin with the teacher's score at its smallest noise level."""
        cfg = self.cfg
        if cfg.langevin_steps <= 0:
            return z0
        teacher = self.bundle.teacher
        tau = torch.full((z0.shape[0],), teacher.schedule.tau_min)
        sigma = float((1 - teacher.schedule.alpha_bar(tau[:1])).sqrt())
        for _ in range(cfg.langevin_steps):
            self.evals += 1
            score = -teacher.eps(z0, tau, self.cond) / sigma
            z0 = z0 + cfg.langevin_step_size * score + (2 * cfg.langevin_step_size) ** 0.5 * torch.randn(
                z0.shape, generator=self.generator)
        return z0

    # ---- teacher baselines --------------------------------------------------------------------
    def teacher(self) -> Generator[StepEvent, None, GenerationResult]:
        cfg, teacher = self.cfg, self.bundle.teacher
        guided = ClassifierFreeGuidance(teacher.eps, cfg.cfg)

        def field(z: torch.Tensor, tau: torch.Tensor) -> torch.Tensor:
            self.evals += 1
            with self.clock("network"):
                return guided(z, tau, self.cond)

        z = torch.randn(self.latent_shape, generator=self.generator)
        if cfg.method == "teacher-ddpm":
            taus, abar = ddpm_times(teacher.schedule)
            n = len(taus)
            for k, i in enumerate(reversed(range(n))):
                z, z0_hat, tau = ddpm_step(field, z, i, taus, abar, self.generator)
                yield self._event(k, n, tau, z, z if k == n - 1 else z0_hat, {})
        else:
            taus = ddim_times(cfg.steps)
            for k in range(cfg.steps):
                z, z0_hat = ddim_step(field, teacher.schedule, z, taus[k], taus[k + 1])
                yield self._event(k, cfg.steps, float(taus[k + 1]), z, z if k == cfg.steps - 1 else z0_hat, {})
        return self._result(z)

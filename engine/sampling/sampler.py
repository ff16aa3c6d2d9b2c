"""The guided streaming sampler (paper sections 3.2-3.4 and 4): one generator for every method.

    gen = sample(bundle, storyboard, SamplerConfig(steps=30, seed=0))
    for event in gen:            # one StepEvent per solver step; gen.close() cancels
        ...
    result = <StopIteration.value>  (a GenerationResult)

Student (default): z_1 ~ N(0, I); a guided Heun ODE from t = 1 (noise) to t = 0 (data) on the
rectified-flow student, classifier-free guided (weight `cfg`, conditional and unconditional
passes in one batch), its S = 3 phase sub-fields mixed by the CTMC occupancy, re-planned every
`ctmc_every` steps. Guidance acts on the clean-latent estimate z0_hat = z_t - t v (what the
current step predicts the final motion to be): the decoded motion's energies, routed to the
latent through the Jacobian surrogate B_rho (or exact autograd through the decoder when the
bundle's surrogate is untrained), plus the latent energy E_lat, move z0_hat; the step then keeps
its noise estimate, so the correction enters the trajectory at the scale (1 - t) it would have
had at that time. An optional micro-Langevin pass with the teacher's score sharpens the end, and
the final clips go through engine.finishing (keyposes, paths, feet and contacts made exact).

Teacher methods (DDPM 1000 steps, DDIM) run the frozen teacher unguided, as the
"COLLAGE Teacher" baseline. Ablations are flags of the same config.

The model works on fixed slots (2 humans, 1 object); storyboards with fewer are padded and the
output keeps only the storyboard's agents and objects. It animates at MODEL_FPS: a storyboard at
another rate is retimed to it, and the motion comes back at the storyboard's rate (previews,
phases and result), so that a walk at 30 fps is as fast as at 20.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, replace
from typing import Generator, Protocol

import numpy as np
import torch

from ..clip import MotionClip
from ..controls import build_controls
from ..cpu import ThreadBudget
from ..dataset import MODEL_FPS, NUM_HUMANS, fixed_controls
from ..finishing import finish
from ..io.resample import resample_clip, resample_linear
from ..models.encoders import latent_energy
from ..models.surrogate import exact_latent_gradient, flatten_motion
from ..models.teacher import ClassifierFreeGuidance, ddim_sample, ddpm_sample
from ..skeleton import HANDS
from ..storyboard import Storyboard
from .energies import ENERGIES, EnergyContext, EnergyWeights, total_energy
from .events import GenerationResult, StepEvent

METHODS = ("student", "teacher-ddpm", "teacher-ddim")
# guidance_max_rate of "steady" generation (the app's Steady checkbox, generate --steady);
# BENCHMARKS.md compares it with the default ("Ours, steady"; stroke-nudge stability).
STEADY_GUIDANCE_RATE = 5.0
TRAJECTORY_ONLY = {"trajectory"}


class SamplerError(ValueError):
    """A request the sampler cannot serve (one line, for the user)."""


@dataclass
class SamplerConfig:
    steps: int = 30                 # Heun steps (student) or DDIM steps (teacher-ddim)
    seed: int = 0
    cfg: float = 1.6                # classifier-free guidance weight
    method: str = "student"
    variations: int = 1             # K samples drawn at once (one batch)
    use_energy: bool = True         # raw-space energy guidance (ablation "w/o Energy")
    use_ctmc: bool = True           # CTMC mixing of sub-fields and contact gating ("w/o CTMC")
    use_latent: bool = True         # latent grounding E_lat ("w/o latent grounding")
    use_temporal_bias: bool = True  # trajectory attention bias ("w/o temporal bias")
    trajectory_only: bool = False   # only the trajectory energy ("trajectory-only")
    ctmc_every: int = 3
    guidance_steps: int = 1         # energy steps on z0_hat per solver step
    guidance_start: float = 0.7     # guide only once t <= this (near noise the network re-predicts
                                    # z0_hat almost regardless of z, so early guidance is mostly lost)
    guidance_alpha: float = 1.0     # damping of the Polyak step (1: the full linearised step)
    guidance_max_rms: float = 0.25  # cap on one step's RMS change, latent units
    guidance_max_rate: float | None = None  # cap on the Polyak rate E / |g|^2 during the ODE
                                    # (STEADY_GUIDANCE_RATE: steadier under edits, more foot skate)
    latent_weight: float = 0.01     # eta_lat, weight of E_lat against the raw energies (f_gamma's
                                    # regression pulls towards an average motion: at 0.05, K3D +0.4 cm)
    final_refine_steps: int = 4     # extra energy steps on the final latent (physics stage)
    langevin_steps: int = 0         # micro-Langevin with the teacher score (paper: 3)
    langevin_step_size: float = 1e-3
    finish: bool = True             # engine.finishing on the final clips ("w/o finishing")
    check_surrogate: bool = False   # also take the exact gradient through the decoder and report
                                    # its cosine to B_rho's as the energy "surrogate_cosine" (slower)
    threads: int | None = None      # torch threads (None: engine.cpu chooses from the free cores, and
                                    # re-chooses between steps as other programs' load changes)
    reserve_cores: float = 0.0      # cores to leave to the caller's own other work (the app's drawing)


class Bundle(Protocol):
    """What the sampler reads of engine.models.bundle.ModelBundle."""
    config: object                  # ModelConfig: .vqvae.latent_dim, .vqvae.time_factor
    metadata: dict                  # "stages": the training stages its weights went through
    vqvae: torch.nn.Module          # .decode(z), .decode_lowres(z)
    conditioner: torch.nn.Module    # .encode(controls, t_lat, v) -> SketchEncoding
    latent_head: torch.nn.Module    # f_gamma
    student: torch.nn.Module        # RectifiedFlowStudent
    teacher: torch.nn.Module        # DiffusionTeacher
    planner: torch.nn.Module        # PhasePlanner
    surrogate: torch.nn.Module      # JacobianSurrogate


def sample(bundle: Bundle, storyboard: Storyboard,
           config: SamplerConfig = SamplerConfig()) -> Generator[StepEvent, None, GenerationResult]:
    if config.method not in METHODS:
        raise SamplerError(f"unknown method {config.method!r}; choose one of {', '.join(METHODS)}")
    if config.steps < 1 or config.variations < 1:
        raise SamplerError("steps and variations must be at least 1")
    if len(storyboard.agents) > NUM_HUMANS or len(storyboard.objects) > 1:
        raise SamplerError(f"the model animates at most {NUM_HUMANS} people and 1 object; the storyboard has "
                           f"{len(storyboard.agents)} people and {len(storyboard.objects)} objects")
    threads = ThreadBudget(config.threads, config.reserve_cores)
    threads.adjust()
    run = _Run(bundle, storyboard, config)
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
    """State of one generation; methods are the per-method loops."""

    def __init__(self, bundle: Bundle, sb: Storyboard, cfg: SamplerConfig):
        self.bundle, self.sb, self.cfg = bundle, sb, cfg
        self.start = time.perf_counter()
        self.first_step: float | None = None
        self.evals = 0
        k = cfg.variations
        stride = bundle.config.vqvae.time_factor
        self.latent_dim = bundle.config.vqvae.latent_dim
        # An untrained surrogate routes garbage: fall back to exact gradients through the decoder.
        self.surrogate = bundle.surrogate if "surrogate" in bundle.metadata.get("stages", ()) else None
        model_sb = sb.retimed(MODEL_FPS)                  # frames at the model's rate from here on
        self.frames = model_sb.length
        self.padded = -(-self.frames // stride) * stride    # the decoder makes multiples of stride
        self.t_lat = self.padded // stride
        self.generator = torch.Generator().manual_seed(cfg.seed)
        controls = fixed_controls(build_controls(_padded_storyboard(model_sb, self.padded)))
        self.controls = {name: torch.as_tensor(v)[None].expand(k, *v.shape).contiguous()
                         for name, v in controls.items()}
        enc = bundle.conditioner.encode(self.controls, self.t_lat, 3)
        cond = enc.conditioning
        if not cfg.use_temporal_bias:
            cond = replace(cond, temporal_bias=torch.zeros_like(cond.temporal_bias))
        self.cond, self.s2d, self.present = cond, enc.s2d, enc.present
        n = self.padded
        self.energy_ctx = EnergyContext.from_storyboard(
            _padded_storyboard(model_sb, n), batch=k,
            K3D_hat=enc.lifted.keyposes[:, :, :len(sb.agents)],
            T3D_hat=enc.lifted.trajectories[:, :, :len(sb.agents)])
        self.enabled = TRAJECTORY_ONLY if cfg.trajectory_only else set(ENERGIES)
        self.weights = EnergyWeights()
        self.occupancy: torch.Tensor | None = None
        self._decoded: tuple[torch.Tensor | None, dict] = (None, {})
        self.guided_velocity = ClassifierFreeGuidance(self._student_field, cfg.cfg)

    # ---- shared pieces ---------------------------------------------------------------------
    def _decode(self, z: torch.Tensor) -> dict[str, torch.Tensor]:
        """VQ-VAE decode of z, remembered for the same tensor: planning, the first guidance step
        and the result often decode the latent the step before them did (the sampler never
        changes a latent in place). One read and one write of the pair: a StepEvent's decode may
        run on another thread."""
        last, motion = self._decoded
        if z is not last:
            motion = self.bundle.vqvae.decode(z)
            self._decoded = (z, motion)
        return motion

    def _storyboard_view(self, motion: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
        """The decoded slots that the storyboard uses (its agents, its objects)."""
        h, o = len(self.sb.agents), len(self.sb.objects)
        return {"joints": motion["joints"][:, :, :h], "rot6d": motion["rot6d"][:, :, :h],
                "obj_pose": motion["obj_pose"][:, :, :o], "obj_anchors": motion["obj_anchors"][:, :, :o]}

    def _plan(self, z0: torch.Tensor, motion: dict[str, torch.Tensor]) -> None:
        """Re-plan the CTMC occupancy (K, N, 3) from the clean estimate and its decode."""
        plan = self.bundle.planner(z0, motion, self.controls["contact"])
        self.occupancy = plan.occupancy
        self.energy_ctx.occupancy = plan.occupancy

    def _guide(self, z0: torch.Tensor, t: float, steps: int,
               max_rate: float | None = None) -> tuple[torch.Tensor, dict[str, float]]:
        """`steps` Polyak steps of the total energy on the clean latent z0 (K, T, V, d).

        A Polyak step moves along the gradient g by E / |g|^2, the length that would zero the
        energy if it were linear there; damped by `guidance_alpha` and capped at an RMS of
        `guidance_max_rms` latent units, so a far-off keyframe cannot throw the latent off the
        data manifold and a satisfied storyboard leaves it alone. The energy never reaches 0
        (sketches disagree with physics a little), so near its floor E / |g|^2 grows without
        bound and the steps overshoot back and forth: a micrometre change to a stroke then
        changes the motion by centimetres. `max_rate` caps the rate, which steadies the result
        and weakens the pull (see SamplerConfig.guidance_max_rate)."""
        cfg, values = self.cfg, {}
        for _ in range(steps):
            energy, grad = self._energy_and_gradient(z0, t, values)
            sq = grad.flatten(1).pow(2).sum(1).clamp_min(1e-12)
            rate = cfg.guidance_alpha * energy / sq
            if max_rate is not None:
                rate = rate.clamp(max=max_rate)
            step = rate[:, None, None, None] * grad
            rms = step.flatten(1).pow(2).mean(1).sqrt().clamp_min(1e-12)
            z0 = z0 - step * (cfg.guidance_max_rms / rms).clamp(max=1.0)[:, None, None, None]
        return z0, values

    def _energy_and_gradient(self, z0: torch.Tensor, t: float,
                             values: dict[str, float]) -> tuple[torch.Tensor, torch.Tensor]:
        """Total energy (K,) at z0 and its latent gradient (K, T, V, d); per-term means go to values.
        Raw-space terms reach the latent through B_rho (exact autograd when there is none)."""
        cfg, bundle = self.cfg, self.bundle
        energy, grad = z0.new_zeros(z0.shape[0]), torch.zeros_like(z0)
        with torch.enable_grad():
            if cfg.use_energy:
                zg = z0 if self.surrogate is not None else z0.detach().requires_grad_(True)
                motion = self._decode(zg)
                if self.surrogate is not None:   # stop at the motion, route through B_rho
                    motion = {k: v.detach().requires_grad_(True) for k, v in motion.items()}
                total, terms = total_energy(self._storyboard_view(motion), self.energy_ctx, t,
                                            self.weights, self.enabled)
                if self.surrogate is None:
                    grad = grad + torch.autograd.grad(total.sum(), zg)[0]
                else:
                    raw = torch.autograd.grad(total.sum(), list(motion.values()), allow_unused=True)
                    raw = {k: torch.zeros_like(v) if g is None else g for (k, v), g in zip(motion.items(), raw)}
                    routed = self.surrogate(raw)
                    grad = grad + routed
                    if cfg.check_surrogate:
                        exact = exact_latent_gradient(bundle.vqvae.decode, z0, flatten_motion(raw))
                        values["surrogate_cosine"] = float(
                            torch.nn.functional.cosine_similarity(routed.flatten(1), exact.flatten(1), 1).mean())
                energy = energy + total.detach()
                values.update({k: float(v.detach().mean()) for k, v in terms.items()})
            if cfg.use_latent:
                zl = z0.detach().requires_grad_(True)
                e_lat = cfg.latent_weight * latent_energy(bundle.latent_head, zl, self.s2d, self.present)
                grad = grad + torch.autograd.grad(e_lat.sum(), zl)[0]
                energy = energy + e_lat.detach()
                values["latent"] = float(e_lat.detach().mean())
        values["total"] = float(energy.mean())
        return energy, grad

    def _event(self, step: int, num: int, t: float, z: torch.Tensor, z0: torch.Tensor,
               energies: dict[str, float]) -> StepEvent:
        if self.first_step is None:
            self.first_step = time.perf_counter() - self.start
        z0, phase = z0.clone(), self._phase(0)

        def decode() -> MotionClip:  # the step's state is captured: it may run after later steps
            with torch.no_grad():
                return self._clip(self._decode(z0), 0, phase)

        return StepEvent(step=step, num_steps=num, t=t, latent=z.numpy().copy(), decode=decode,
                         phase=self._at_storyboard_rate(phase), energies=energies)

    def _at_storyboard_rate(self, per_frame: np.ndarray) -> np.ndarray:
        """(frames at MODEL_FPS, ...) -> (the storyboard's frames, ...), linearly in time."""
        if self.sb.fps == MODEL_FPS:
            return per_frame
        return resample_linear(per_frame, MODEL_FPS, self.sb.fps)[:self.sb.length].astype(per_frame.dtype)

    def _phase(self, k: int) -> np.ndarray:
        """Variation k's CTMC occupancy (frames at MODEL_FPS, 3); uniform before the first plan."""
        if self.occupancy is None:
            return np.full((self.frames, 3), 1.0 / 3.0, np.float32)
        return self.occupancy[k, :self.frames].numpy().astype(np.float32)

    def _clip(self, motion: dict[str, torch.Tensor], k: int, phase: np.ndarray | None = None) -> MotionClip:
        """Variation k of a decoded motion as a clip of the storyboard's agents and objects at
        the storyboard's frame rate (phase (N, 3) at MODEL_FPS: the occupancy to give it; None =
        the current plan's)."""
        n, h, o = self.frames, len(self.sb.agents), len(self.sb.objects)
        joints = motion["joints"][k, :n, :h].numpy()
        rot6d = motion["rot6d"][k, :n, :h].numpy()
        kw = {}
        if o:
            kw = dict(obj_pose=motion["obj_pose"][k, :n, :o].numpy(),
                      obj_anchors=motion["obj_anchors"][k, :n, :o].numpy(),
                      obj_type=np.array([ob.spec.type for ob in self.sb.objects]),
                      obj_size=np.array([ob.spec.size for ob in self.sb.objects], np.float32))
        phase = self._phase(k) if phase is None else phase
        clip = MotionClip(fps=MODEL_FPS, joints=_finite(joints), rot6d=_finite(rot6d), phase=phase,
                          scenario="generated", **{k2: _finite(v) if v.dtype.kind == "f" else v
                                                   for k2, v in kw.items()})
        if self.sb.fps != MODEL_FPS:
            clip = resample_clip(clip, self.sb.fps).slice(0, self.sb.length)
        return replace(clip, contact=_hand_contact(clip.joints, clip.obj_anchors, clip.phase))

    def _result(self, z0: torch.Tensor) -> GenerationResult:
        motion = self._decode(z0)
        clips = [self._clip(motion, k) for k in range(z0.shape[0])]
        if self.cfg.finish:
            clips = [self._finished(clip) for clip in clips]
        return GenerationResult(clips=clips, wall_time_s=time.perf_counter() - self.start,
                                first_step_s=self.first_step or 0.0, network_evals=self.evals)

    def _finished(self, clip: MotionClip) -> MotionClip:
        """The clip through engine.finishing, its hand contacts re-measured on the result."""
        clip = finish(clip, self.sb)
        contact = _hand_contact(clip.joints, clip.obj_anchors, clip.phase)
        return replace(clip, contact=contact)

    # ---- student: guided Heun ODE ------------------------------------------------------------
    def _student_field(self, z, t, cond, entity_pos):
        """The student's velocity, its sub-fields mixed by the current CTMC occupancy (uniform
        without CTMC); CFG stacks cond and uncond, so the occupancy is repeated to match."""
        occupancy = self.occupancy if self.cfg.use_ctmc else None
        if occupancy is not None:
            occupancy = occupancy.repeat(z.shape[0] // occupancy.shape[0], 1, 1)
        return self.bundle.student.velocity(z, t, cond, entity_pos, occupancy)

    def _velocity(self, z: torch.Tensor, t: float, entity_pos: torch.Tensor | None) -> torch.Tensor:
        """CFG-guided student velocity; one network evaluation (cond and uncond run as one batch).
        Inference mode: ~10% faster than no_grad, and its result only ever enters arithmetic."""
        self.evals += 1
        with torch.inference_mode():
            return self.guided_velocity(z, torch.full((z.shape[0],), t), self.cond, entity_pos)

    def student(self) -> Generator[StepEvent, None, GenerationResult]:
        cfg, b = self.cfg, self.bundle
        shape = (cfg.variations, self.t_lat, 3, self.latent_dim)
        z = torch.randn(shape, generator=self.generator)
        ts = torch.linspace(1.0, 0.0, cfg.steps + 1).tolist()
        entity_pos = None
        z0 = z
        for i in range(cfg.steps):
            t, t_next = ts[i], ts[i + 1]
            v1 = self._velocity(z, t, entity_pos)
            z_euler = z + (t_next - t) * v1
            v2 = self._velocity(z_euler, t_next, entity_pos)
            v = 0.5 * (v1 + v2)
            z_next = z + (t_next - t) * v
            z0 = z_next - t_next * v2 if t_next > 0 else z_next   # clean estimate at t_next
            noise = (z_next - (1 - t_next) * z0) / max(t_next, 1e-8)
            if cfg.use_ctmc and i % cfg.ctmc_every == 0:
                self._plan(z0, self._decode(z0))
            energies = {}
            if (cfg.use_energy or cfg.use_latent) and t_next <= cfg.guidance_start:
                z0, energies = self._guide(z0, t_next, cfg.guidance_steps, cfg.guidance_max_rate)
            z = (1 - t_next) * z0 + t_next * noise if t_next > 0 else z0
            entity_pos = b.vqvae.decode_lowres(z0)
            yield self._event(i, cfg.steps, t_next, z, z0, energies)
        if cfg.use_energy or cfg.use_latent:
            z0, _ = self._guide(z0, 0.0, cfg.final_refine_steps)
        z0 = self._langevin(z0)
        if cfg.use_ctmc:
            self._plan(z0, self._decode(z0))
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
        cfg, b = self.cfg, self.bundle
        shape = (cfg.variations, self.t_lat, 3, self.latent_dim)

        def counted(z, tau, cond, pos):
            self.evals += 1
            return b.teacher.eps(z, tau, cond, pos)

        eps = ClassifierFreeGuidance(counted, cfg.cfg)
        if cfg.method == "teacher-ddpm":
            steps = ddpm_sample(eps, b.teacher.schedule, shape, self.cond, generator=self.generator)
        else:
            steps = ddim_sample(eps, b.teacher.schedule, shape, cfg.steps, self.cond, generator=self.generator)
        z0 = None
        for step in steps:
            z0 = step.z if step.index == step.num_steps - 1 else step.z0_hat
            yield self._event(step.index, step.num_steps, step.tau, step.z, z0, {})
        return self._result(z0)


def _padded_storyboard(sb: Storyboard, length: int) -> Storyboard:
    """The same storyboard over `length` >= sb.length frames (the tail is unconstrained)."""
    return sb if length == sb.length else replace(sb, length=length)


def _hand_contact(joints: np.ndarray, anchors: np.ndarray | None, phase: np.ndarray,
                  reach: float = 0.08, softness: float = 0.02) -> np.ndarray:
    """Per-hand contact probability (N, H, 2): the CTMC's in-contact occupancy times how close
    the hand is to the nearest object anchor or other person's hand (1 within `reach` metres)."""
    hands = joints[:, :, list(HANDS)]                                   # (N, H, 2, 3)
    n, h = hands.shape[:2]
    targets = [hands.reshape(n, 1, h * 2, 3)]
    if anchors is not None:
        targets.append(anchors.reshape(n, 1, -1, 3))
    dist = np.linalg.norm(hands.reshape(n, h * 2, 1, 3) - np.concatenate(targets, 2), axis=-1)
    own = np.eye(h * 2, dtype=bool)                                     # a hand is not its own partner
    same_person = np.kron(np.eye(h, dtype=bool), np.ones((2, 2), bool))
    dist[:, :, :h * 2][:, own | same_person] = np.inf
    near = 0.5 * (1.0 - np.tanh((dist.min(-1) - reach) / (2 * softness)))  # a logistic that cannot overflow
    return (near.reshape(n, h, 2) * (phase[:, 1:].sum(-1))[:, None, None]).astype(np.float32)


def _finite(a: np.ndarray) -> np.ndarray:
    """Never hand out NaN: an untrained or diverged model's output is clamped to the scene's scale."""
    return np.nan_to_num(a, nan=0.0, posinf=10.0, neginf=-10.0).astype(np.float32)

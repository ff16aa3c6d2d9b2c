"""One task per training stage: which parts train, which are frozen (read from earlier stages'
runs/<stage>/final.pt), and the loss. The trainer (loop.py) only sees StageTask.

Order and dependencies:
  vqvae                       -> VQ-VAE (then latent_std calibrated on data)
  encoders                    -> sketch conditioner (L_align + lifting)
  teacher    (vqvae, encoders?) -> teacher + conditioner (epsilon loss, 10% condition dropout)
  student1   (vqvae, teacher)  -> student: L_RF + lambda_dist L_distill (phase 1)
  potential  (vqvae)           -> V_psi: OT warm-up for the first half, then contrastive divergence
  ctmc       (vqvae)           -> phase planner: L_CTMC on ground-truth motion features
  surrogate  (vqvae)           -> B_rho: closed-form init from decoder Jacobians, then regression
  student2   (all above)       -> student + planner + latent head: the full objective (phase 2)
  preview    (vqvae, teacher, student2) -> the few-step preview student, distilled from the
                               student's guided ODE (models/preview.py); optional in a bundle
Baselines (config.BASELINE_STAGES, for the benchmark):
  sketch2anim (vqvae, encoders?) -> Sketch2AnimINT: epsilon loss in raw motion space
  controlnet1 (vqvae, teacher)   -> the ControlNet ablation's student: student1's objective
  controlnet2 (all but preview, controlnet1) -> the same: student2's objective, with our planner
                               and latent head frozen (they do not read the storyboard's route)
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import torch
from torch import nn
from torch.utils.data import Dataset

from ..models import alignment, ctmc, encoders, potential, preview, student, surrogate
from ..models.bundle import BASELINE_PARTS, PARTS, build_parts
from ..models.conditioning import Conditioning
from ..models.vqvae import mean_joint_error
from ..sampling.cfg import ClassifierFreeGuidance
from ..sampling.config import SamplerConfig
from . import checkpoint
from .config import BASELINE_STAGES, STAGES, TrainConfig

LossFn = Callable[[dict, torch.Generator, int], dict]
PREVIEW_CFG = SamplerConfig().cfg   # the guidance weight the preview bakes in: the sampler's default
ENTITY_POS_DROP = 0.1   # share of steps trained without the entity-distance bias (first sampler step has none)
TEXT_DROP = 0.3         # share of storyboards trained without their text (sketch-only generation)


class StageUnavailable(RuntimeError):
    """A stage whose prerequisites (earlier stages or modules) are not there."""


@dataclass
class StageTask:
    name: str
    trainable: nn.ModuleDict
    loss: LossFn                          # (batch, generator, step) -> {'loss': total, other terms...}
    frozen: dict[str, nn.Module] = field(default_factory=dict)
    finish: Callable[[nn.ModuleDict, Dataset], dict] | None = None  # on the EMA weights after training


def sample_batch(dataset: Dataset, count: int) -> dict[str, torch.Tensor]:
    """Up to `count` items spread over the dataset, stacked (for normalizers and calibration)."""
    n = len(dataset)
    idx = sorted({int(i) for i in torch.linspace(0, n - 1, min(count, n))})
    items = [dataset[i] for i in idx]
    return {k: torch.stack([it[k] for it in items]) for k in items[0]}


def load_final(runs: Path, stage: str) -> dict[str, dict]:
    """{part name: state dict} of an earlier stage's final EMA weights."""
    return checkpoint.load(runs / stage / "final.pt")["parts"]


def _frozen(parts: dict, runs: Path, stage: str, names: tuple[str, ...], needed_by: str) -> None:
    if not (runs / stage / "final.pt").exists():
        raise StageUnavailable(f"stage '{needed_by}' needs stage '{stage}' trained first ({runs / stage / 'final.pt'} missing)")
    weights = load_final(runs, stage)
    for name in names:
        parts[name].load_state_dict(weights[name])
        parts[name].eval().requires_grad_(False)


def _on(batch: dict[str, torch.Tensor], device: torch.device) -> dict[str, torch.Tensor]:
    return {k: v.to(device) for k, v in batch.items()}


def _latent(vqvae, batch: dict, generator: torch.Generator):
    """Clean latent z0 (B, T_lat, V, d) and the entity positions for the distance bias (or None)."""
    with torch.no_grad():
        z0 = vqvae.encode(batch)
        drop = torch.rand((), generator=generator, device=generator.device) < ENTITY_POS_DROP
        pos = None if drop else vqvae.decode_lowres(z0)
    return z0, pos


def _text_dropped(cond: Conditioning, generator: torch.Generator) -> Conditioning:
    """The batch's conditioning with TEXT_DROP of the samples' text removed (a model without text
    conditioning ignores it anyway)."""
    if cond.text_mask is None:
        return cond
    return cond.without_text(torch.rand(cond.text_mask.shape[0], generator=generator,
                                        device=cond.text_mask.device) < TEXT_DROP)


def build_stage(stage: str, cfg: TrainConfig, runs: Path, dataset: Dataset) -> StageTask:
    if stage not in STAGES + BASELINE_STAGES:
        raise ValueError(f"unknown stage {stage!r}; expected one of {', '.join(STAGES + BASELINE_STAGES)} or all")
    torch.manual_seed(cfg.seed)  # the same initial weights on every rank and every run
    parts = build_parts(cfg.model, PARTS + (BASELINE_PARTS if stage in BASELINE_STAGES else ()))
    return _BUILDERS[stage](parts, cfg, Path(runs), dataset)


def _vqvae(parts, cfg, runs, dataset) -> StageTask:
    vq = parts["vqvae"]
    vq.fit_normalizer(sample_batch(dataset, 256))

    def finish(trained, data):
        device = next(trained.parameters()).device   # the model may be on a GPU, the data is not
        std = trained["vqvae"].calibrate_latent_scale(_on(sample_batch(data, 256), device))
        trained["vqvae"].eval()
        batch = _on(sample_batch(data, 64), device)
        with torch.no_grad():
            decoded = trained["vqvae"].decode(trained["vqvae"].encode(batch))
        return {"latent_std": std, "joint_error_m": float(mean_joint_error(decoded["joints"], batch["joints"]))}

    return StageTask("vqvae", nn.ModuleDict({"vqvae": vq}), lambda batch, g, step: vq.loss(batch), finish=finish)


def _encoders(parts, cfg, runs, dataset) -> StageTask:
    cond = parts["conditioner"]

    def loss(batch, g, step):
        s2d, s3d = cond.embed_2d(batch), cond.embed_3d(batch, batch)
        align, parts_a = alignment.alignment_loss(s2d, s3d, encoders.condition_presence(batch), cond.cfg)
        lift, parts_l = encoders.lift_loss(cond.lift(batch), batch, batch)
        return {"loss": align + lift, **{k: v.detach() for k, v in {**parts_a, **parts_l}.items()}}

    return StageTask("encoders", nn.ModuleDict({"conditioner": cond}), loss)


def _teacher(parts, cfg, runs, dataset) -> StageTask:
    _frozen(parts, runs, "vqvae", ("vqvae",), "teacher")
    vq, teacher, cond = parts["vqvae"], parts["teacher"], parts["conditioner"]
    _aligned_start(cond, runs)

    def loss(batch, g, step):
        z0, pos = _latent(vq, batch, g)
        return teacher.loss(z0, _text_dropped(cond(batch, z0.shape[1], z0.shape[2]), g), pos, generator=g)

    return StageTask("teacher", nn.ModuleDict({"teacher": teacher, "conditioner": cond}), loss,
                     frozen={"vqvae": vq})


def _aligned_start(conditioner: nn.Module, runs: Path) -> None:
    if (runs / "encoders" / "final.pt").exists():  # aligned encoders are a better start; optional
        conditioner.load_state_dict(load_final(runs, "encoders")["conditioner"], strict=False)   # text starts fresh


def _sketch2anim(parts, cfg, runs, dataset) -> StageTask:
    _frozen(parts, runs, "vqvae", ("vqvae",), "sketch2anim")
    vq, model = parts["vqvae"], parts["sketch2anim"]
    _aligned_start(model.conditioner, runs)
    return StageTask("sketch2anim", nn.ModuleDict({"sketch2anim": model}),
                     lambda batch, g, step: model.loss(vq, batch, g), frozen={"vqvae": vq})


def _occupancy_labels(batch: dict) -> torch.Tensor:
    """Phase labels (B, N, 3) where a clip has them, uniform elsewhere."""
    has = batch["has_labels"].reshape(-1, 1, 1) > 0.5
    return torch.where(has, batch["phase"], torch.full_like(batch["phase"], 1.0 / student.NUM_PHASES))


def _student1(parts, cfg, runs, dataset, name: str = "student1", part: str = "student") -> StageTask:
    _frozen(parts, runs, "vqvae", ("vqvae",), name)
    _frozen(parts, runs, "teacher", ("teacher", "conditioner"), name)
    vq, teacher, cond, stu = parts["vqvae"], parts["teacher"], parts["conditioner"], parts[part]

    def loss(batch, g, step):
        z0, pos = _latent(vq, batch, g)
        with torch.no_grad():
            c = _text_dropped(cond(batch, z0.shape[1], z0.shape[2]), g)
        terms, _, _ = student.phase1_losses(stu, teacher, z0, c, pos, _occupancy_labels(batch), g)
        return {"loss": student.combine_losses(terms),
                **{k: v.detach() for k, v in terms.items()}}

    return StageTask(name, nn.ModuleDict({part: stu}), loss,
                     frozen={"vqvae": vq, "teacher": teacher, "conditioner": cond})


def _potential(parts, cfg, runs, dataset) -> StageTask:
    _frozen(parts, runs, "vqvae", ("vqvae",), "potential")
    vq, pot = parts["vqvae"], parts["potential"]
    warmup = cfg.steps_for("potential") // 2

    def loss(batch, g, step):
        z0, _ = _latent(vq, batch, g)
        noise = torch.randn(z0.shape, generator=g, device=z0.device)
        if step < warmup:
            total, terms = potential.ot_warmup_loss(pot, z0, noise, generator=g)
        else:
            neg = potential.langevin_negatives(pot, 0.5 * z0 + 0.5 * noise, generator=g)
            total, terms = potential.contrastive_divergence_loss(pot, z0, neg)
        return {"loss": total, **terms}

    return StageTask("potential", nn.ModuleDict({"potential": pot}), loss, frozen={"vqvae": vq})


def _ctmc(parts, cfg, runs, dataset) -> StageTask:
    _frozen(parts, runs, "vqvae", ("vqvae",), "ctmc")
    vq, planner = parts["vqvae"], parts["planner"]

    def loss(batch, g, step):
        z0, _ = _latent(vq, batch, g)
        plan = planner(z0, batch, batch["contact"])
        total, terms = ctmc.ctmc_loss(plan, batch["phase"], batch["has_labels"], planner.cfg)
        return {"loss": total, **{k: v.detach() for k, v in terms.items()}}

    return StageTask("ctmc", nn.ModuleDict({"planner": planner}), loss, frozen={"vqvae": vq})


def _surrogate(parts, cfg, runs, dataset) -> StageTask:
    _frozen(parts, runs, "vqvae", ("vqvae",), "surrogate")
    vq, sur = parts["vqvae"], parts["surrogate"]
    with torch.no_grad():
        latents = vq.encode(sample_batch(dataset, cfg.surrogate_init_latents))
    surrogate.init_from_jacobians(sur, vq.decode, latents)

    def loss(batch, g, step):
        z0, _ = _latent(vq, batch, g)
        cot = surrogate.random_cotangents(z0.shape[0], frames=sur.cfg.frames, generator=g)
        total = surrogate.surrogate_loss(sur, vq.decode, z0, cot)
        return {"loss": total}

    return StageTask("surrogate", nn.ModuleDict({"surrogate": sur}), loss, frozen={"vqvae": vq})


def _student2(parts, cfg, runs, dataset) -> StageTask:
    for stage, name in (("student1", "student"), ("ctmc", "planner")):
        if not (runs / stage / "final.pt").exists():
            raise StageUnavailable(f"stage 'student2' needs stage '{stage}' trained first")
        parts[name].load_state_dict(load_final(runs, stage)[name])
    return _phase2("student2", parts, runs, "student", heads_train=True)


def _controlnet2(parts, cfg, runs, dataset) -> StageTask:
    _frozen(parts, runs, "student2", ("planner", "latent_head"), "controlnet2")
    if not (runs / "controlnet1" / "final.pt").exists():
        raise StageUnavailable("stage 'controlnet2' needs stage 'controlnet1' trained first")
    parts["controlnet_student"].load_state_dict(load_final(runs, "controlnet1")["controlnet_student"])
    return _phase2("controlnet2", parts, runs, "controlnet_student", heads_train=False)


def _phase2(name: str, parts: dict, runs: Path, part: str, heads_train: bool) -> StageTask:
    """The student's full objective (phase 2) on parts[part]; the planner and latent head train
    with it when `heads_train`, else they are frozen (and their own losses drop out)."""
    _frozen(parts, runs, "vqvae", ("vqvae",), name)
    _frozen(parts, runs, "teacher", ("teacher", "conditioner"), name)
    _frozen(parts, runs, "potential", ("potential",), name)
    vq, teacher, cond, stu = parts["vqvae"], parts["teacher"], parts["conditioner"], parts[part]
    planner, head, pot = parts["planner"], parts["latent_head"], parts["potential"]
    weights = student.LossWeights()

    def loss(batch, g, step):
        z0, pos = _latent(vq, batch, g)
        with torch.no_grad():
            enc = cond.encode(batch, z0.shape[1], z0.shape[2])
        plan = planner(z0, batch, batch["contact"])
        terms, sample, v = student.phase1_losses(stu, teacher, z0, _text_dropped(enc.conditioning, g), pos,
                                                 plan.occupancy.detach(), g)
        if heads_train:
            with torch.no_grad():
                s3d = cond.embed_3d(batch, batch)
            terms["ctmc"], _ = ctmc.ctmc_loss(plan, batch["phase"], batch["has_labels"], planner.cfg)
            terms["lat"], _ = alignment.latent_alignment_loss(head, z0, s3d, enc.present, cond.cfg)
        # Total potential V_psi + lambda_lat E_lat at the student's state; raw-space energies
        # join once they can be built from batched controls (see report).
        z = sample.z_t.detach().requires_grad_(True)
        with torch.enable_grad():
            total_v = pot(z) + weights.lat * alignment.latent_energy(head, z, enc.s2d, enc.present)
            (grad_v,) = torch.autograd.grad(total_v.sum(), z)
        terms["lyap"] = potential.lyapunov_loss(grad_v, -v, pot.cfg.kappa)
        terms["consist"] = student.consistency_loss(stu, sample, pos, plan.occupancy.detach(), v)
        return {"loss": student.combine_losses(terms, weights), **{k: t.detach() for k, t in terms.items()}}

    trainable = {part: stu, "planner": planner, "latent_head": head} if heads_train else {part: stu}
    frozen = {"vqvae": vq, "teacher": teacher, "conditioner": cond, "potential": pot}
    if not heads_train:
        frozen.update(planner=planner, latent_head=head)
    return StageTask(name, nn.ModuleDict(trainable), loss, frozen=frozen)


def _preview(parts, cfg, runs, dataset) -> StageTask:
    """The few-step preview student, distilled from the finished student's guided ODE."""
    _frozen(parts, runs, "vqvae", ("vqvae",), "preview")
    _frozen(parts, runs, "teacher", ("conditioner",), "preview")
    _frozen(parts, runs, "student2", ("student", "planner"), "preview")
    vq, cond, stu, planner, fast = (parts[n] for n in ("vqvae", "conditioner", "student", "planner", "preview"))
    fast.load_state_dict(stu.state_dict())                 # the student is the best start

    def field(z, t, c, pos, occ):
        """The sampler's guided student (conditional and unconditional passes as one batch of 2B)."""
        doubled = None if occ is None else occ.repeat(2, 1, 1)
        return ClassifierFreeGuidance(lambda z2, t2, c2, p2: stu.velocity(z2, t2, c2, p2, doubled), PREVIEW_CFG)(
            z, t, c, pos)

    def loss(batch, g, step):
        with torch.no_grad():
            z0 = vq.encode(batch)
            c = _text_dropped(cond(batch, z0.shape[1], z0.shape[2]), g)
            occupancy = planner(z0, batch, batch["contact"]).occupancy
            z1 = torch.randn(z0.shape, generator=g, device=z0.device)
            states, positions = preview.reference_path(field, vq.decode_lowres, z1, c, occupancy,
                                                       cfg.model.preview_steps)
        return preview.preview_loss(fast, states, positions, c, occupancy)

    return StageTask("preview", nn.ModuleDict({"preview": fast}), loss,
                     frozen={"vqvae": vq, "conditioner": cond, "student": stu, "planner": planner})


_BUILDERS = {"vqvae": _vqvae, "encoders": _encoders, "teacher": _teacher, "student1": _student1,
             "potential": _potential, "ctmc": _ctmc, "surrogate": _surrogate, "student2": _student2,
             "preview": _preview, "sketch2anim": _sketch2anim,
             "controlnet1": lambda *a: _student1(*a, name="controlnet1", part="controlnet_student"),
             "controlnet2": _controlnet2}

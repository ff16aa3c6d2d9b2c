"""Rectified-flow student: phase sub-fields mixed by the CTMC occupancy, L_RF, distillation of
the frozen teacher's probability-flow velocity through a time map, and the loss composition.

Path: z_t = (1 - t) z0 + t z1 with z1 ~ N(0, I) (t = 1 is noise, t = 0 data), velocity target
dz_t/dt = z1 - z0; the sampler integrates from t = 1 down to t = 0.

Time map tau = T(t) (the paper defers it to its supplement; this is our choice). The two paths
are the same family up to scale: z_t / (1 - t) = z0 + (t / (1 - t)) z1 and z_tau / alpha =
z0 + (sigma / alpha) eps. Matching the noise-to-signal ratio, sigma(tau) / alpha(tau) = t / (1 - t),
makes the distributions of z_tau and s(t) z_t identical, with s(t) = alpha(tau) / (1 - t) =
1 / sqrt((1 - t)^2 + t^2). So T is monotone (both ratios increase), closed-form for the linear
VP schedule, and exact: the teacher is evaluated at the state it was trained on, z_tau = s z_t,
and its velocity is carried to t-time by the chain rule,
    dz_t/dt = v_PF(s z_t, tau) * tau'(t) / s(t) - z_t * s'(t) / s(t).
For an exact teacher this equals the rectified-flow (marginal) velocity; tests check it on a
Gaussian toy distribution. The map is only used where tau lies in the teacher's trained range
[1/steps, 1], i.e. t in about [0.005, 0.9935]; distillation ignores samples outside.
"""
from __future__ import annotations

from dataclasses import dataclass, fields

import torch
import torch.nn.functional as F
from torch import nn

from .conditioning import Conditioning
from .teacher import DiffusionTeacher, Field, VPSchedule, broadcast, pf_velocity
from .unet import TemporalUNet

NUM_PHASES = 3


@dataclass
class LossWeights:
    """Weights of the student's total objective (paper eq. total_loss); rf is 1."""
    distill: float = 0.5    # lambda_dist
    lyap: float = 0.5       # lambda_Lyap
    ctmc: float = 0.1       # lambda_CTMC
    lat: float = 0.1        # lambda_lat
    energy: float = 0.1     # sum_r lambda_r L_E_r (supervised energy surrogates), as one weight
    consist: float = 0.1    # lambda_cons


def mix_subfields(subfields: torch.Tensor, occupancy: torch.Tensor | None = None) -> torch.Tensor:
    """v = sum_s pi(s) v^(s).  subfields (B, S, T_lat, V, d); occupancy (B, S) or (B, L, S)
    per step (L frames or latent steps; averaged to T_lat) or None (uniform). -> (B, T_lat, V, d)."""
    b, s, t = subfields.shape[:3]
    if occupancy is None:
        return subfields.mean(1)
    if occupancy.dim() == 2:
        weights = occupancy[:, :, None]
    else:
        if occupancy.shape[1] != t:
            occupancy = F.adaptive_avg_pool1d(occupancy.transpose(1, 2), t).transpose(1, 2)
        weights = occupancy.transpose(1, 2)                                  # (B, S, T)
    return (subfields * weights[..., None, None].to(subfields.dtype)).sum(1)


class RectifiedFlowStudent(nn.Module):
    def __init__(self, backbone: TemporalUNet):
        super().__init__()
        self.backbone = backbone

    def subfields(self, z: torch.Tensor, t: torch.Tensor, cond: Conditioning | None = None,
                  entity_pos: torch.Tensor | None = None) -> torch.Tensor:
        """Phase sub-fields (B, S, T_lat, V, d) at z_t (B, T_lat, V, d), t (B,)."""
        return self.backbone(z, t, cond, entity_pos)

    forward = subfields

    def velocity(self, z: torch.Tensor, t: torch.Tensor, cond: Conditioning | None = None,
                 entity_pos: torch.Tensor | None = None, occupancy: torch.Tensor | None = None) -> torch.Tensor:
        """v_phi (B, T_lat, V, d) mixed by `occupancy` (see mix_subfields)."""
        return mix_subfields(self.subfields(z, t, cond, entity_pos), occupancy)


# ---- the time map ---------------------------------------------------------------------------

def time_map(schedule: VPSchedule, t: torch.Tensor) -> torch.Tensor:
    """tau = T(t): sigma(tau) / alpha(tau) = t / (1 - t). t (B,) in (0, 1) -> tau (B,) (unclamped)."""
    ratio = t / (1 - t)
    return schedule.tau_from_log_alpha_bar(-torch.log1p(ratio ** 2))


def time_map_valid(schedule: VPSchedule, t: torch.Tensor) -> torch.Tensor:
    """(B,) bool: T(t) inside the teacher's trained range [tau_min, 1]."""
    tau = time_map(schedule, t.clamp(1e-6, 1 - 1e-6))
    return (tau >= schedule.tau_min) & (tau <= 1.0) & (t > 0) & (t < 1)


def teacher_velocity_in_t(eps_field: Field, schedule: VPSchedule, z_t: torch.Tensor, t: torch.Tensor,
                          cond: Conditioning | None = None, entity_pos: torch.Tensor | None = None) -> torch.Tensor:
    """The teacher's PF velocity at the student state z_t (B, T, V, d), expressed as dz_t/dt.
    t (B,) should satisfy time_map_valid (clamped into range otherwise)."""
    tau = time_map(schedule, t).clamp(schedule.tau_min, 1.0)
    norm2 = (1 - t) ** 2 + t ** 2
    scale = norm2.rsqrt()                                           # s(t)
    ds_over_s = -(2 * t - 1) / norm2                                # s'(t) / s(t)
    ratio = t / (1 - t)
    dtau_dt = 2 * ratio / (1 - t) ** 2 / ((1 + ratio ** 2) * schedule.beta(tau))
    v_tau = pf_velocity(eps_field, schedule, broadcast(scale, z_t) * z_t, tau, cond, entity_pos)
    return v_tau * broadcast(dtau_dt / scale, z_t) - z_t * broadcast(ds_over_s, z_t)


# ---- losses ---------------------------------------------------------------------------------

@dataclass
class FlowSample:
    """One draw of the rectified-flow path for a batch (shared by L_RF, L_distill, L_Lyap)."""
    z0: torch.Tensor     # (B, T, V, d) data latent
    z1: torch.Tensor     # (B, T, V, d) noise
    t: torch.Tensor      # (B,)
    z_t: torch.Tensor    # (B, T, V, d)
    cond: Conditioning | None   # with this batch's 10% condition dropout applied

    @property
    def target(self) -> torch.Tensor:
        return self.z1 - self.z0


def draw_flow_sample(z0: torch.Tensor, cond: Conditioning | None, generator: torch.Generator | None = None,
                     cond_drop: float = 0.1) -> FlowSample:
    b = z0.shape[0]
    t = torch.rand(b, generator=generator, device=z0.device)
    z1 = torch.randn(z0.shape, generator=generator, device=z0.device)
    tb = broadcast(t, z0)
    if cond is not None:
        cond = cond.dropped(torch.rand(b, generator=generator, device=z0.device) < cond_drop)
    return FlowSample(z0, z1, t, (1 - tb) * z0 + tb * z1, cond)


def rf_loss(v: torch.Tensor, sample: FlowSample) -> torch.Tensor:
    """L_RF = E ||v_phi(z_t, t) - (z1 - z0)||^2 (mean over elements)."""
    return (v - sample.target).pow(2).mean()


def distill_loss(v: torch.Tensor, teacher: DiffusionTeacher, sample: FlowSample,
                 entity_pos: torch.Tensor | None = None) -> torch.Tensor:
    """L_distill = E ||v_phi(z_t, t) - v_PF(z_t, T(t))||^2 against the frozen teacher, over the
    samples whose T(t) is inside the teacher's range."""
    valid = time_map_valid(teacher.schedule, sample.t)
    if not valid.any():
        return v.sum() * 0.0
    with torch.no_grad():
        target = teacher_velocity_in_t(teacher.eps, teacher.schedule, sample.z_t, sample.t, sample.cond, entity_pos)
    err = (v - target).pow(2).flatten(1).mean(1)
    return (err * valid).sum() / valid.sum()


def consistency_loss(student: RectifiedFlowStudent, sample: FlowSample, entity_pos: torch.Tensor | None,
                     occupancy: torch.Tensor | None, v_full: torch.Tensor, overlap: int = 10) -> torch.Tensor:
    """Segment-overlap consistency (COLLAGE-style, for long clips generated in windows): the
    velocity of a window that starts mid-sequence must agree, on its frames, with the velocity
    of the whole sequence. v_full (B, T, V, d) is the full-sequence velocity (target detached)."""
    t_lat = sample.z_t.shape[1]
    start = max(t_lat - (t_lat + overlap) // 2, 1)
    cond = None if sample.cond is None else sample.cond.from_step(start)
    pos = None if entity_pos is None else entity_pos[:, start:]
    occ = occupancy
    if occ is not None and occ.dim() == 3:
        occ = F.adaptive_avg_pool1d(occ.transpose(1, 2), t_lat).transpose(1, 2)[:, start:]
    v_window = student.velocity(sample.z_t[:, start:], sample.t, cond, pos, occ)
    return (v_window - v_full[:, start:].detach()).pow(2).mean()


def phase1_losses(student: RectifiedFlowStudent, teacher: DiffusionTeacher, z0: torch.Tensor,
                  cond: Conditioning | None, entity_pos: torch.Tensor | None = None,
                  occupancy: torch.Tensor | None = None, generator: torch.Generator | None = None,
                  cond_drop: float = 0.1) -> tuple[dict[str, torch.Tensor], FlowSample, torch.Tensor]:
    """Terms {'rf', 'distill'}, the flow sample and the student's velocity (for phase-2 terms).
    z0 (B, T_lat, V, d); occupancy as in mix_subfields."""
    sample = draw_flow_sample(z0, cond, generator, cond_drop)
    v = student.velocity(sample.z_t, sample.t, sample.cond, entity_pos, occupancy)
    return {"rf": rf_loss(v, sample), "distill": distill_loss(v, teacher, sample, entity_pos)}, sample, v


def combine_losses(terms: dict[str, torch.Tensor], weights: LossWeights = LossWeights()) -> torch.Tensor:
    """L = L_RF + sum_k lambda_k L_k over the terms present. Keys: 'rf' plus any field name of
    LossWeights ('distill', 'lyap', 'ctmc', 'lat', 'energy', 'consist'). Phase 1 passes rf and
    distill; phase 2 adds whatever the other modules provide. Unknown keys are an error (a
    misspelt term must not silently drop out of the objective)."""
    known = {f.name for f in fields(LossWeights)}
    unknown = set(terms) - known - {"rf"}
    if unknown:
        raise KeyError(f"unknown loss terms {sorted(unknown)}; expected 'rf' or one of {sorted(known)}")
    total = terms["rf"]
    for name, value in terms.items():
        if name != "rf":
            total = total + getattr(weights, name) * value
    return total


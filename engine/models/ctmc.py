"""CTMC phase planner (paper Sec. 3.4): occupancy of approach/withdraw, contact/release and
hold/carry over the motion's frames.

Our reading (DESIGN.md Sec. 3): the occupancy pi_n (one distribution per frame n) is a schedule
along the frames. Per-frame features h_n (latent features upsampled from T_lat to N and pooled
over entities, hand-to-anchor distances and object speed from a decoded motion, the storyboard's
contact flags) go through a temporal conv and an MLP to rates Q_eta(h_n) (S x S, off-diagonals
softplus >= 0, rows sum to zero). The Kolmogorov forward equation dpi/dn = pi Q is integrated
exactly per frame step, pi_{n+1} = pi_n expm(Q_n), so pi stays on the simplex; the products of
the per-step transition matrices are formed by a parallel prefix scan (log2 N batched matmuls)
rather than N sequential steps. pi_0 comes from the first frame's features.

For the trainer and the benchmark:
  ctmc_loss(plan, labels, has_labels, cfg) -> (loss, parts)    L_CTMC: Kolmogorov residual +
      weak phase-label cross-entropy + beta Var[rate entropy] + dwell-time penalty
  phase_accuracy(occupancy, labels, has_labels) -> float
  contact_timing_error(occupancy, labels, has_labels) -> float (frames)
labels are the dataset's `phase` (B, N, 3), has_labels (B,).
"""
from __future__ import annotations

from dataclasses import dataclass

import torch
import torch.nn.functional as F
from torch import nn

from ..clip import PHASES
from ..skeleton import HANDS

STATES = len(PHASES)            # approach, contact, carry
IN_CONTACT = (1, 2)             # states in which a hand holds something


@dataclass
class PhasePlannerConfig:
    latent_dim: int = 32          # d of the entity latent
    num_humans: int = 2
    frames_per_step: int = 4      # N / T_lat, used when no decoded motion gives N
    latent_features: int = 32     # per-token projection before pooling over entities
    hidden: int = 64
    context: int = 5              # temporal conv kernel over frames (sees onsets coming)
    distance_scale: float = 0.15  # metres: hand-anchor distance feature exp(-d / scale)
    speed_scale: float = 0.02     # metres per frame that count as clearly moving
    min_dwell: float = 2.0        # frames: exit rates above 1 / min_dwell are penalised
    kolmogorov_weight: float = 1.0
    label_weight: float = 1.0
    entropy_weight: float = 0.01  # beta
    dwell_weight: float = 0.1


@dataclass
class PhasePlan:
    occupancy: torch.Tensor   # (B, N, S) pi_n on the simplex
    rates: torch.Tensor       # (B, N, S, S) Q_n: off-diagonals >= 0, rows sum to 0


def generator_matrix(off_diagonal: torch.Tensor, states: int = STATES) -> torch.Tensor:
    """Non-negative off-diagonal rates (..., S*(S-1)) -> Q (..., S, S) with zero row sums."""
    eye = torch.eye(states, dtype=torch.bool, device=off_diagonal.device)
    q = off_diagonal.new_zeros(off_diagonal.shape[:-1] + (states, states))
    q[..., ~eye] = off_diagonal
    return q - torch.diag_embed(q.sum(-1))


def integrate_occupancy(pi0: torch.Tensor, rates: torch.Tensor) -> torch.Tensor:
    """pi0 (B, S), rates (B, N, S, S) -> occupancy (B, N, S) with pi_{n+1} = pi_n expm(Q_n)."""
    steps = torch.linalg.matrix_exp(rates[:, :-1].contiguous())  # (B, N-1, S, S) row-stochastic
    prefix = steps
    shift = 1
    while shift < prefix.shape[1]:                            # Hillis-Steele inclusive scan
        prefix = torch.cat([prefix[:, :shift], prefix[:, :-shift] @ prefix[:, shift:]], 1)
        shift *= 2
    later = torch.einsum("bs,bnst->bnt", pi0, prefix)
    pi = torch.cat([pi0[:, None], later], 1).clamp_min(0.0)   # remove rounding below zero
    return pi / pi.sum(-1, keepdim=True)


class PhasePlanner(nn.Module):
    """Q_eta and pi_0 from latent, decoded motion and storyboard contacts."""

    def __init__(self, cfg: PhasePlannerConfig | None = None):
        super().__init__()
        cfg = cfg or PhasePlannerConfig()
        self.cfg = cfg
        self.token = nn.Linear(cfg.latent_dim, cfg.latent_features)
        hands = 2 * cfg.num_humans
        # latent mean+max pool, per hand: closeness, distance change; object speed; motion flag;
        # storyboard contact per hand
        self.in_dim = 2 * cfg.latent_features + 2 * hands + 2 + hands
        self.temporal = nn.Conv1d(self.in_dim, cfg.hidden, cfg.context, padding=cfg.context // 2)
        self.rate_head = nn.Sequential(nn.SiLU(), nn.Linear(cfg.hidden, cfg.hidden), nn.SiLU(),
                                       nn.Linear(cfg.hidden, STATES * (STATES - 1)))
        self.start_head = nn.Linear(cfg.hidden, STATES)
        # Start with slow rates (softplus(-4) ~ 0.02 per frame): phases persist until told to switch.
        nn.init.constant_(self.rate_head[-1].bias, -4.0)

    def features(self, z: torch.Tensor, motion: dict[str, torch.Tensor] | None = None,
                 contact: torch.Tensor | None = None, num_frames: int | None = None) -> torch.Tensor:
        """Per-frame features (B, N, in_dim).

        z (B, T_lat, V, d); motion: decoded dict with joints (B, N, H, 22, 3), obj_pose
        (B, N, O, 7), obj_anchors (B, N, O, K, 3), or None (distance features zero, flag 0);
        contact: storyboard flags (B, N, H, 2) or None; num_frames: N when motion is None.
        """
        cfg = self.cfg
        b, t = z.shape[:2]
        n = motion["joints"].shape[1] if motion is not None else (num_frames or t * cfg.frames_per_step)
        tok = F.silu(self.token(z))                                       # (B, T, V, c)
        pooled = torch.cat([tok.mean(2), tok.amax(2)], -1).transpose(1, 2)
        lat = F.interpolate(pooled, size=n, mode="linear", align_corners=False).transpose(1, 2)
        hands = 2 * cfg.num_humans
        if motion is not None and motion.get("obj_anchors") is not None and motion["obj_anchors"].shape[2] > 0:
            hand = motion["joints"][:, :, :, list(HANDS)].reshape(b, n, hands, 1, 3)
            anchors = motion["obj_anchors"].reshape(b, n, 1, -1, 3)
            dist = (hand - anchors).norm(dim=-1).amin(-1)                 # (B, N, hands)
            change = torch.diff(dist, dim=1, prepend=dist[:, :1])
            root = motion["obj_pose"][..., :3]
            speed = torch.diff(root, dim=1, prepend=root[:, :1]).norm(dim=-1).amax(-1, keepdim=True)
            geo = torch.cat([torch.exp(-dist / cfg.distance_scale), torch.tanh(change / cfg.speed_scale),
                             torch.tanh(speed / cfg.speed_scale), torch.ones_like(speed)], -1)
        else:
            geo = z.new_zeros(b, n, 2 * hands + 2)
        flags = contact.reshape(b, n, hands).to(z.dtype) if contact is not None else z.new_zeros(b, n, hands)
        return torch.cat([lat, geo, flags], -1)

    def plan_from_features(self, h: torch.Tensor) -> PhasePlan:
        """h (B, N, in_dim) -> PhasePlan."""
        ctx = self.temporal(h.transpose(1, 2)).transpose(1, 2)           # (B, N, hidden)
        rates = generator_matrix(F.softplus(self.rate_head(ctx)))
        pi0 = torch.softmax(self.start_head(ctx[:, 0]), -1)
        return PhasePlan(integrate_occupancy(pi0, rates), rates)

    def forward(self, z: torch.Tensor, motion: dict[str, torch.Tensor] | None = None,
                contact: torch.Tensor | None = None, num_frames: int | None = None) -> PhasePlan:
        return self.plan_from_features(self.features(z, motion, contact, num_frames))


# ---- losses ------------------------------------------------------------------------------

def kolmogorov_residual(occupancy: torch.Tensor, rates: torch.Tensor) -> torch.Tensor:
    """||(pi_{n+1} - pi_n) - pi_n Q_n||^2 per frame step: (B, N, S), (B, N, S, S) -> (B, N-1)."""
    flow = torch.einsum("bns,bnst->bnt", occupancy[:, :-1], rates[:, :-1])
    return (occupancy[:, 1:] - occupancy[:, :-1] - flow).pow(2).sum(-1)


def rate_entropy(rates: torch.Tensor) -> torch.Tensor:
    """Entropy of the normalised off-diagonal rates per frame: (B, N, S, S) -> (B, N)."""
    s = rates.shape[-1]
    off = rates[..., ~torch.eye(s, dtype=torch.bool, device=rates.device)]
    p = off / off.sum(-1, keepdim=True).clamp_min(1e-8)
    return -(p * p.clamp_min(1e-8).log()).sum(-1)


def dwell_penalty(plan: PhasePlan, min_dwell: float) -> torch.Tensor:
    """Occupancy-weighted squared excess of exit rates over 1 / min_dwell: (B, N)."""
    exit_rate = -torch.diagonal(plan.rates, dim1=-2, dim2=-1)            # (B, N, S)
    return (plan.occupancy * F.relu(exit_rate - 1.0 / min_dwell).pow(2)).sum(-1)


def ctmc_loss(plan: PhasePlan, labels: torch.Tensor | None = None, has_labels: torch.Tensor | None = None,
              cfg: PhasePlannerConfig | None = None) -> tuple[torch.Tensor, dict]:
    """L_CTMC and its parts.

    The Kolmogorov residual is taken on the model's occupancy (consistency) and, where labels
    exist, on the label occupancy (fits Q to the observed transitions). labels (B, N, S) phase
    occupancy, has_labels (B,) 0/1."""
    cfg = cfg or PhasePlannerConfig()
    parts = {"kolmogorov": kolmogorov_residual(plan.occupancy, plan.rates).mean()}
    if labels is not None:
        w = torch.ones(labels.shape[0], device=labels.device) if has_labels is None else has_labels.float()
        denom = w.sum().clamp_min(1.0)
        label_res = kolmogorov_residual(labels, plan.rates).mean(1)
        parts["kolmogorov"] = parts["kolmogorov"] + (label_res * w).sum() / denom
        ce = -(labels * plan.occupancy.clamp_min(1e-8).log()).sum(-1).mean(1)
        parts["phase_ce"] = (ce * w).sum() / denom
    parts["rate_entropy_var"] = rate_entropy(plan.rates).var(1).mean()
    parts["dwell"] = dwell_penalty(plan, cfg.min_dwell).mean()
    loss = (cfg.kolmogorov_weight * parts["kolmogorov"] + cfg.entropy_weight * parts["rate_entropy_var"]
            + cfg.dwell_weight * parts["dwell"] + cfg.label_weight * parts.get("phase_ce", 0.0))
    return loss, parts


# ---- metrics -----------------------------------------------------------------------------

def _labelled(x: torch.Tensor, has_labels: torch.Tensor | None) -> torch.Tensor:
    return x if has_labels is None else x[has_labels > 0.5]


@torch.no_grad()
def phase_accuracy(occupancy: torch.Tensor, labels: torch.Tensor, has_labels: torch.Tensor | None = None) -> float:
    """Share of frames whose most occupied state is the label's: (B, N, S) x2 -> float (nan if
    no labelled sample)."""
    occ, lab = _labelled(occupancy, has_labels), _labelled(labels, has_labels)
    if occ.numel() == 0:
        return float("nan")
    return (occ.argmax(-1) == lab.argmax(-1)).float().mean().item()


def _contact_events(in_contact: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """(N,) bool -> frames of onsets (False -> True) and releases (True -> False)."""
    step = in_contact[1:].int() - in_contact[:-1].int()
    return torch.nonzero(step == 1)[:, 0] + 1, torch.nonzero(step == -1)[:, 0] + 1


@torch.no_grad()
def contact_timing_error(occupancy: torch.Tensor, labels: torch.Tensor,
                         has_labels: torch.Tensor | None = None) -> float:
    """Mean |frames| between each labelled contact onset/release and the nearest predicted event
    of the same kind (N frames when the prediction has none). "In contact" = most occupied state
    is contact or carry. (B, N, S) x2 -> float (nan when no labelled events)."""
    occ, lab = _labelled(occupancy, has_labels), _labelled(labels, has_labels)
    n = occ.shape[1]
    contact_states = torch.tensor(IN_CONTACT, device=occ.device)
    errors = []
    for p, l in zip(occ, lab):
        pred = _contact_events(torch.isin(p.argmax(-1), contact_states))
        true = _contact_events(torch.isin(l.argmax(-1), contact_states))
        for pe, te in zip(pred, true):
            for frame in te.tolist():
                errors.append(float(n) if pe.numel() == 0 else (pe - frame).abs().min().item())
    return sum(errors) / len(errors) if errors else float("nan")

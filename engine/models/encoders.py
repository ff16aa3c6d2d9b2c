"""Sketch encoders: storyboard controls -> Conditioning for the U-Net, and the shared 2D/3D
embedding space (paper Sec. 3, Eq. align_loss; lift-then-fuse in 3.1; f_gamma, L_lat, E_lat in
3.2-3.3).

Inputs. `controls` is a dict of batched tensors with the fields of engine.controls.Controls
(masks may be bool or 0/1 float):
  kp2d (B,N,H,22,2)  kp_mask (B,N,H,22)   tr2d (B,N,H,22,2)  tr_mask (B,N,H,22)
  obj2d (B,N,O,4)    obj_mask (B,N,O)     objpath2d (B,N,O,2) objpath_mask (B,N,O)
  contact (B,N,H,2)  camera (B,3,3) rows right/up/back   cam_target (B,3)
`motion` is the ground truth as the dataset yields it: joints (B,N,H,22,3), obj_pose (B,N,O,7),
obj_anchors (B,N,O,K,3).

Three condition types y: "kf" (keyposes), "tr" (joint trajectories), "o" (object boxes/paths).
Each has a 2D encoder (reads controls + camera) and a 3D encoder (reads the ground-truth motion
at the same constrained joints and frames, chi-masked). All embeddings are unit vectors in
R^{d_e}: with free norms the L2 term could be driven to zero by shrinking every embedding.

Losses the trainer calls (encoder stage, student stage) and the inference energy:
  alignment_loss(s2d, s3d, present, cfg) -> (loss, parts)      L_align, encoder stage
  lift_loss(lifted, controls, motion) -> (loss, parts)          L2 of K3D_hat / T3D_hat, encoder stage
  latent_alignment_loss(head, z, s3d, present, cfg) -> (loss, parts)   L_lat, student stage
  latent_energy(head, z, s2d, present) -> (B,)                  E_lat, an energy at inference
with s2d = conditioner.embed_2d(controls), s3d = conditioner.embed_3d(controls, motion),
present = condition_presence(controls).

Text (`EncoderConfig.text`): controls["text_ids"], ["text_mask"] (engine.text.tokenize) through
a TextEncoder (models/text.py) into Conditioning.text, which the U-Net's bottleneck reads.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import torch
import torch.nn.functional as F
from torch import nn

from ..skeleton import NUM_JOINTS, rest_pose
from .conditioning import CONDITION_TYPES, Conditioning
from .text import TextEncoder

TIME_FREQUENCIES = 4  # sinusoidal features of normalized time: 2 * 4 numbers


@dataclass
class EncoderConfig:
    d_e: int = 256                 # shared embedding width
    d_model: int = 128             # width of the residual the U-Net adds per entity
    hidden: int = 128              # width inside the encoders
    lift_hidden: int = 64          # width of the lifting networks (they run on every joint)
    num_humans: int = 2
    latent_dim: int = 32           # d of the entity latent z (f_gamma's input)
    keyframe_sigma: float = 0.03   # width of the keyframe time gate, in normalized time
    phase_dim: int = 16            # embedding of the along-path phase for the temporal bias
    temperature: float = 0.1       # InfoNCE temperature on cosine similarities
    lambda_nce: float = 1.0        # lambda_c in L_align and lambda_NCE in L_lat (smaller lets the L2 term collapse all embeddings together first)
    text: bool = False             # encode the storyboard's text (models/text.py)
    text_dim: int = 64             # its token features' width (UNetConfig.text_dim must match)


# ---- small helpers ------------------------------------------------------------------------

def _mlp(inp: int, hidden: int, out: int) -> nn.Sequential:
    return nn.Sequential(nn.Linear(inp, hidden), nn.SiLU(), nn.Linear(hidden, hidden), nn.SiLU(),
                         nn.Linear(hidden, out))


def _bool(mask: torch.Tensor) -> torch.Tensor:
    return mask > 0.5 if mask.dtype != torch.bool else mask


def _where_placed(net: nn.Module, x: torch.Tensor, rows: torch.Tensor) -> torch.Tensor:
    """net on the rows of x (..., F) that `rows` (...) bool marks, zero on the others: most of a
    storyboard's frames place nothing, so the network runs on the few that do."""
    out = x.new_zeros(rows.shape + (net[-1].out_features,))
    out[rows] = net(x[rows])
    return out


def time_features(t: torch.Tensor) -> torch.Tensor:
    """Normalized time (...) in [0, 1] -> (..., 2 * TIME_FREQUENCIES) sin/cos features."""
    freq = math.pi * 2.0 ** torch.arange(TIME_FREQUENCIES, dtype=t.dtype, device=t.device)
    ang = t[..., None] * freq
    return torch.cat([ang.sin(), ang.cos()], -1)


def frame_times(n: int, device=None) -> torch.Tensor:
    """(N,) frame n -> n / (N - 1), the normalized time of the paper's k / N."""
    return torch.linspace(0.0, 1.0, n, device=device)


def frames_to_latent(x: torch.Tensor, t_lat: int) -> torch.Tensor:
    """Average frames into latent steps: (B, N, ...) -> (B, T_lat, ...); step q covers frames
    with floor(n T_lat / N) == q (the decoder's temporal stride)."""
    n = x.shape[1]
    step = torch.div(torch.arange(n, device=x.device) * t_lat, n, rounding_mode="floor")
    weights = F.one_hot(step, t_lat).to(x.dtype)            # (N, T_lat)
    weights = weights / weights.sum(0, keepdim=True).clamp_min(1.0)
    return torch.einsum("bn...,nq->bq...", x, weights)


def condition_presence(controls: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
    """Which samples carry each condition type: {y: (B,) bool}."""
    b = controls["kp_mask"].shape[0]
    return {"kf": _bool(controls["kp_mask"]).reshape(b, -1).any(1),
            "tr": _bool(controls["tr_mask"]).reshape(b, -1).any(1),
            "o": (_bool(controls["obj_mask"]) | _bool(controls["objpath_mask"])).reshape(b, -1).any(1)}


# ---- set encoders into the shared space --------------------------------------------------

class MaskedSetEncoder(nn.Module):
    """A set of tokens (B, L, F) with a mask (B, L) -> unit embedding (B, d_e).

    Per-token MLP, masked mean and max pooling, LayerNorm, MLP. An empty set maps to a learned
    unit vector (the "no constraint of this type" embedding). The LayerNorm matters: constant
    inputs (masks, time, camera) otherwise swamp the per-sample signal and every embedding
    starts out identical, which the L2 term of L_align rewards.
    """

    def __init__(self, in_dim: int, hidden: int, d_e: int):
        super().__init__()
        self.token = _mlp(in_dim, hidden, hidden)
        self.out = nn.Sequential(nn.LayerNorm(2 * hidden), _mlp(2 * hidden, hidden, d_e))
        self.empty = nn.Parameter(torch.randn(d_e))

    def forward(self, tokens: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        x = _where_placed(self.token, tokens, mask)
        m = mask[..., None].to(x.dtype)
        count = m.sum(1)
        mean = (x * m).sum(1) / count.clamp_min(1.0)
        peak = x.masked_fill(~mask[..., None], -1e4).amax(1)
        has = count > 0
        out = self.out(torch.cat([mean, torch.where(has, peak, torch.zeros_like(peak))], -1))
        return F.normalize(torch.where(has, out, self.empty.expand_as(out)), dim=-1)


def _frame_human_context(controls: dict, b: int, n: int, h: int) -> torch.Tensor:
    """Time + human one-hot per (frame, human) token: (B, N*H, 8 + H)."""
    t = time_features(frame_times(n, controls["kp2d"].device))[None, :, None].expand(b, n, h, -1)
    who = torch.eye(h, device=t.device)[None, None].expand(b, n, h, h)
    return torch.cat([t, who], -1).reshape(b, n * h, -1)


def _camera_tokens(controls: dict, count: int) -> torch.Tensor:
    cam = controls["camera"].reshape(-1, 1, 9)
    return cam.expand(-1, count, 9)


def keypose_tokens_2d(controls: dict) -> tuple[torch.Tensor, torch.Tensor]:
    """(B, N*H, 22*2 + 22 + 8 + H + 9) tokens and (B, N*H) mask, one per (frame, human)."""
    kp, m = controls["kp2d"], _bool(controls["kp_mask"])
    b, n, h = m.shape[:3]
    x = torch.cat([(kp * m[..., None]).reshape(b, n * h, -1), m.reshape(b, n * h, -1).float(),
                   _frame_human_context(controls, b, n, h), _camera_tokens(controls, n * h)], -1)
    return x, m.reshape(b, n * h, -1).any(-1)


def keypose_tokens_3d(controls: dict, motion: dict) -> tuple[torch.Tensor, torch.Tensor]:
    """Ground-truth joints at the keypose joints/frames: (B, N*H, 22*3 + 22 + 8 + H), mask."""
    return _joint_tokens_3d(controls, motion, _bool(controls["kp_mask"]))


def trajectory_tokens_2d(controls: dict) -> tuple[torch.Tensor, torch.Tensor]:
    tr, m = controls["tr2d"], _bool(controls["tr_mask"])
    b, n, h = m.shape[:3]
    x = torch.cat([(tr * m[..., None]).reshape(b, n * h, -1), m.reshape(b, n * h, -1).float(),
                   _frame_human_context(controls, b, n, h), _camera_tokens(controls, n * h)], -1)
    return x, m.reshape(b, n * h, -1).any(-1)


def trajectory_tokens_3d(controls: dict, motion: dict) -> tuple[torch.Tensor, torch.Tensor]:
    return _joint_tokens_3d(controls, motion, _bool(controls["tr_mask"]))


def _joint_tokens_3d(controls: dict, motion: dict, m: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    b, n, h = m.shape[:3]
    rel = motion["joints"] - controls["cam_target"][:, None, None, None]
    x = torch.cat([(rel * m[..., None]).reshape(b, n * h, -1), m.reshape(b, n * h, -1).float(),
                   _frame_human_context(controls, b, n, h)], -1)
    return x, m.reshape(b, n * h, -1).any(-1)


def object_tokens_2d(controls: dict) -> tuple[torch.Tensor, torch.Tensor]:
    """One token per (frame, object): box, path point, their masks, time, camera."""
    box, bm = controls["obj2d"], _bool(controls["obj_mask"])
    path, pm = controls["objpath2d"], _bool(controls["objpath_mask"])
    b, n, o = bm.shape
    t = time_features(frame_times(n, box.device))[None, :, None].expand(b, n, o, -1)
    x = torch.cat([box * bm[..., None], bm[..., None].float(), path * pm[..., None], pm[..., None].float(),
                   t], -1).reshape(b, n * o, -1)
    return torch.cat([x, _camera_tokens(controls, n * o)], -1), (bm | pm).reshape(b, n * o)


def object_tokens_3d(controls: dict, motion: dict) -> tuple[torch.Tensor, torch.Tensor]:
    """Object root, orientation and anchor extent at the storyboarded frames (boxes give the
    pose and extent, paths the root only)."""
    bm, pm = _bool(controls["obj_mask"]), _bool(controls["objpath_mask"])
    b, n, o = bm.shape
    pose, anchors = motion["obj_pose"], motion["obj_anchors"]
    root = pose[..., :3] - controls["cam_target"][:, None, None]
    extent = (anchors - pose[..., None, :3]).abs().amax(-2)    # (B, N, O, 3) K-agnostic size cue
    t = time_features(frame_times(n, pose.device))[None, :, None].expand(b, n, o, -1)
    x = torch.cat([root * (bm | pm)[..., None], pose[..., 3:] * bm[..., None], extent * bm[..., None],
                   bm[..., None].float(), pm[..., None].float(), t], -1)
    return x.reshape(b, n * o, -1), (bm | pm).reshape(b, n * o)


# ---- lifting 2D controls to 3D proxies -----------------------------------------------------

class JointLifter(nn.Module):
    """2D joints + camera -> 3D joints, by predicting each joint's depth along the view direction.

    Orthographic back-projection: p = target + u right + v up - depth back. The prior depth puts
    joint j at its rest-pose height (where the ray through (u, v) crosses y = h_j); a network
    reading the whole pose (or the frame's trajectory points), the camera and that prior adds a
    residual. Output-layer weights start at zero, so an untrained lifter is the geometric prior.
    """

    LEVEL_CAMERA = 0.1  # |back_y| below this (elevation < ~6 deg) leaves depth to the network

    def __init__(self, hidden: int):
        super().__init__()
        self.register_buffer("rest_height", torch.as_tensor(rest_pose()[:, 1], dtype=torch.float32))
        self.joint_embed = nn.Parameter(0.1 * torch.randn(NUM_JOINTS, 8))
        point_in = 2 + 2 + 1 + 1 + 8 + 9
        self.context = nn.Sequential(nn.Linear(point_in, hidden), nn.SiLU(), nn.Linear(hidden, hidden))
        self.head = _mlp(point_in + hidden, hidden, 1)
        nn.init.zeros_(self.head[-1].weight)
        nn.init.zeros_(self.head[-1].bias)

    def forward(self, uv: torch.Tensor, mask: torch.Tensor, camera: torch.Tensor,
                target: torch.Tensor) -> torch.Tensor:
        """One group of joints (a pose, or the trajectory points of one frame) per row:
        uv (G, 22, 2), mask (G, 22) bool, camera (G, 3, 3), target (G, 3) -> (G, 22, 3), zero
        where mask is False. Only the P placed joints are computed (a frame's path is one or two
        of its 22: the dense pass spent 90% of the lifting on joints masked out after)."""
        group, joint = torch.nonzero(mask, as_tuple=True)                       # (P,), (P,)
        uv_p, cam = uv[group, joint], camera[group]                             # (P, 2), (P, 3, 3)
        right, up, back = cam[:, 0], cam[:, 1], cam[:, 2]                       # (P, 3)
        origin_y = target[group, 1] + uv_p[:, 0] * right[:, 1] + uv_p[:, 1] * up[:, 1]
        # Regularized solve of origin_y - depth * back_y = rest height: exact for a tilted
        # camera, fading to the target's depth for a level one (where height says nothing).
        prior = (origin_y - self.rest_height[joint]) * back[:, 1] / (back[:, 1] ** 2 + self.LEVEL_CAMERA ** 2)
        count = torch.bincount(group, minlength=uv.shape[0]).clamp_min(1).to(uv.dtype)[:, None]   # (G, 1)

        def group_mean(x: torch.Tensor) -> torch.Tensor:   # (P, C) -> each point's group's mean (P, C)
            return (x.new_zeros(uv.shape[0], x.shape[1]).index_add_(0, group, x) / count)[group]

        point = torch.cat([uv_p, uv_p - group_mean(uv_p), prior[:, None] * 0.1, torch.ones_like(prior[:, None]),
                           self.joint_embed[joint], cam.reshape(-1, 9)], -1)
        depth = prior + self.head(torch.cat([point, group_mean(self.context(point))], -1))[:, 0]
        out = uv.new_zeros(mask.shape + (3,))
        out[group, joint] = target[group] + uv_p[:, :1] * right + uv_p[:, 1:] * up - depth[:, None] * back
        return out


@dataclass
class LiftedControls:
    keyposes: torch.Tensor     # K3D_hat (B, N, H, 22, 3), zero where kp_mask is False
    trajectories: torch.Tensor  # T3D_hat (B, N, H, 22, 3), zero where tr_mask is False


def lift_loss(lifted: LiftedControls, controls: dict, motion: dict) -> tuple[torch.Tensor, dict]:
    """Mean squared 3D error (m^2) of the lifted proxies at constrained joints -> (loss, parts)."""
    parts = {}
    for name, pred, key in (("lift_kf", lifted.keyposes, "kp_mask"), ("lift_tr", lifted.trajectories, "tr_mask")):
        m = _bool(controls[key]).to(pred.dtype)
        err = ((pred - motion["joints"]) ** 2).sum(-1) * m
        parts[name] = err.sum() / m.sum().clamp_min(1.0)
    return parts["lift_kf"] + parts["lift_tr"], parts


# ---- along-path phase and the conditioning paths -------------------------------------------

def path_phase(points: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """Along-path phase phi = (s, s_dot, curvature) of per-joint trajectories.

    points (B, N, H, 22, C), mask (B, N, H, 22) bool -> (B, N, H, 22, 3): s in [0, 1] is the
    normalized arc length, s_dot the speed along the path in metres per frame, curvature the
    turning angle per metre. Zero where mask is False. Strokes may have gaps: segments are
    counted only between consecutive constrained frames.
    """
    both = (mask[:, 1:] & mask[:, :-1]).to(points.dtype)                  # (B, N-1, H, 22)
    seg = points[:, 1:] - points[:, :-1]
    ds = seg.norm(dim=-1) * both
    arc = torch.cat([torch.zeros_like(ds[:, :1]), ds.cumsum(1)], 1)
    total = ds.sum(1, keepdim=True)
    s = arc / total.clamp_min(1e-6)
    speed = torch.zeros_like(arc)
    speed[:, 1:] += ds
    speed[:, :-1] += ds
    hits = torch.zeros_like(arc)
    hits[:, 1:] += both
    hits[:, :-1] += both
    speed = speed / hits.clamp_min(1.0)
    unit = F.normalize(seg, dim=-1) * both[..., None]
    cos = (unit[:, 1:] * unit[:, :-1]).sum(-1).clamp(-1.0, 1.0)
    turn = torch.acos(cos * (1 - 1e-6)) * both[:, 1:] * both[:, :-1]
    curv = torch.zeros_like(arc)
    curv[:, 1:-1] = turn / (0.5 * (ds[:, 1:] + ds[:, :-1])).clamp_min(1e-3)
    return torch.stack([s, speed, curv.clamp(max=50.0) / 50.0], -1) * mask[..., None]


def keyframe_gate(num_frames: int, t_lat: int, sigma: float, device=None) -> torch.Tensor:
    """delta_sigma((q)/(T_lat-1) - n/(N-1)) for all latent steps q and frames n: (T_lat, N),
    a Gaussian bump of peak 1 (0-based indices; the paper's (q-1)/(T_lat-1) - k/N)."""
    q = torch.linspace(0.0, 1.0, t_lat, device=device)[:, None]
    n = frame_times(num_frames, device)[None]
    return torch.exp(-0.5 * ((q - n) / sigma) ** 2)


class TrajectoryPath(nn.Module):
    """T3D_hat + along-path phase + contact flags -> per-human residuals (B, T_lat, H, d_model)
    and the temporal attention bias (B, T_lat, T_lat)."""

    def __init__(self, cfg: EncoderConfig):
        super().__init__()
        feat = NUM_JOINTS * 3 + NUM_JOINTS + 3 + 2
        self.frame = _mlp(feat, cfg.hidden, cfg.d_model)
        self.phase = nn.Linear(4 * cfg.num_humans, cfg.phase_dim)
        self.bias_scale = nn.Parameter(torch.tensor(-2.0))  # softplus(-2) ~ 0.13: a gentle start

    def forward(self, t3d: torch.Tensor, controls: dict, t_lat: int) -> tuple[torch.Tensor, torch.Tensor]:
        m = _bool(controls["tr_mask"])
        b, n, h = m.shape[:3]
        phi = path_phase(t3d, m)                                            # (B, N, H, 22, 3)
        mf = m.to(t3d.dtype)
        count = mf.sum(-1)                                                  # (B, N, H)
        phi_frame = phi.sum(-2) / count[..., None].clamp_min(1.0)           # (B, N, H, 3)
        on_path = (count > 0).to(t3d.dtype)
        contact = controls["contact"].to(t3d.dtype)
        rel = (t3d - controls["cam_target"][:, None, None, None]) * mf[..., None]
        feat = torch.cat([rel.flatten(-2), mf, phi_frame, contact], -1)
        placed = (on_path > 0) | (contact.amax(-1) > 0)                     # zero residual when unconstrained
        residual = frames_to_latent(_where_placed(self.frame, feat, placed), t_lat)   # (B, T_lat, H, d_model)

        phi_q = frames_to_latent(torch.cat([phi_frame, on_path[..., None]], -1), t_lat)  # (B, T_lat, H, 4)
        present = (phi_q[..., 3].amax(-1) > 0).to(t3d.dtype)               # (B, T_lat)
        e = self.phase(phi_q.reshape(b, t_lat, -1))
        dist = (e[:, :, None] - e[:, None, :]).pow(2).sum(-1)
        bias = -F.softplus(self.bias_scale) * dist * present[:, :, None] * present[:, None, :]
        return residual, bias


class KeyframeAdapter(nn.Module):
    """Time-gated keyframe adapter: r_kf(q) = sum_k delta_sigma(q/(T_lat-1) - k/(N-1)) F(K3D_hat[k]).

    F reads the pose relative to its centroid, the centroid (relative to the camera target) and
    the joint mask. Each human's keyposes feed only that human's residual."""

    def __init__(self, cfg: EncoderConfig):
        super().__init__()
        self.sigma = cfg.keyframe_sigma
        self.pose = _mlp(NUM_JOINTS * 3 + 3 + NUM_JOINTS, cfg.hidden, cfg.d_model)

    def forward(self, k3d: torch.Tensor, controls: dict, t_lat: int) -> torch.Tensor:
        """k3d (B, N, H, 22, 3) -> (B, T_lat, H, d_model)."""
        m = _bool(controls["kp_mask"])
        mf = m.to(k3d.dtype)
        count = mf.sum(-1, keepdim=True)
        centre = (k3d * mf[..., None]).sum(-2) / count.clamp_min(1.0)           # (B, N, H, 3)
        local = (k3d - centre[..., None, :]) * mf[..., None]
        feat = torch.cat([local.flatten(-2), centre - controls["cam_target"][:, None, None], mf], -1)
        f = _where_placed(self.pose, feat, count[..., 0] > 0)                     # (B, N, H, d_model)
        gate = keyframe_gate(m.shape[1], t_lat, self.sigma, k3d.device)          # (T_lat, N)
        return torch.einsum("qn,bnhc->bqhc", gate, f)


class ObjectBranch(nn.Module):
    """Object boxes and paths (+ the ground point under the path, + contact flags) -> residual
    for the object entity slots (B, T_lat, O, d_model)."""

    def __init__(self, cfg: EncoderConfig):
        super().__init__()
        self.frame = _mlp(4 + 1 + 2 + 1 + 3 + 2 * cfg.num_humans, cfg.hidden, cfg.d_model)

    def forward(self, controls: dict, t_lat: int) -> torch.Tensor:
        box, bm = controls["obj2d"], _bool(controls["obj_mask"])
        path, pm = controls["objpath2d"], _bool(controls["objpath_mask"])
        b, n, o = bm.shape
        cam = controls["camera"]
        # Ray through the path point down to the floor: where an object resting on it would be.
        back_y = cam[:, 2, 1, None, None]
        origin = (path[..., :1] * cam[:, None, None, 0] + path[..., 1:] * cam[:, None, None, 1])
        depth = ((controls["cam_target"][:, 1, None, None] + origin[..., 1]) * back_y
                 / (back_y ** 2 + JointLifter.LEVEL_CAMERA ** 2))
        ground = (origin - depth[..., None] * cam[:, None, None, 2]) * pm[..., None]
        contact = controls["contact"].to(box.dtype).reshape(b, n, 1, -1).expand(b, n, o, -1)
        feat = torch.cat([box * bm[..., None], bm[..., None].float(), path * pm[..., None],
                          pm[..., None].float(), ground, contact], -1)
        return frames_to_latent(_where_placed(self.frame, feat, bm | pm | (contact.amax(-1) > 0)), t_lat)


# ---- the conditioner ----------------------------------------------------------------------

@dataclass
class SketchEncoding:
    """Everything the sampler needs from one pass over the storyboard."""
    conditioning: Conditioning
    s2d: dict[str, torch.Tensor]      # {y: (B, d_e)} unit storyboard embeddings (for E_lat)
    present: dict[str, torch.Tensor]  # {y: (B,)} bool
    lifted: LiftedControls            # K3D_hat, T3D_hat (for the 3D energies)


class SketchConditioner(nn.Module):
    """Storyboard controls -> Conditioning (lift-then-fuse), plus the paired 2D/3D encoders."""

    def __init__(self, cfg: EncoderConfig | None = None):
        super().__init__()
        cfg = cfg or EncoderConfig()
        self.cfg = cfg
        if cfg.text:
            self.text = TextEncoder(cfg.text_dim)
        h, j = cfg.num_humans, NUM_JOINTS
        ctx2d, ctx3d = 8 + h + 9, 8 + h
        self.enc2d = nn.ModuleDict({"kf": MaskedSetEncoder(j * 3 + ctx2d, cfg.hidden, cfg.d_e),
                                    "tr": MaskedSetEncoder(j * 3 + ctx2d, cfg.hidden, cfg.d_e),
                                    "o": MaskedSetEncoder(4 + 1 + 2 + 1 + 8 + 9, cfg.hidden, cfg.d_e)})
        self.enc3d = nn.ModuleDict({"kf": MaskedSetEncoder(j * 4 + ctx3d, cfg.hidden, cfg.d_e),
                                    "tr": MaskedSetEncoder(j * 4 + ctx3d, cfg.hidden, cfg.d_e),
                                    "o": MaskedSetEncoder(3 + 4 + 3 + 1 + 1 + 8, cfg.hidden, cfg.d_e)})
        self.lift_kf = JointLifter(cfg.lift_hidden)
        self.lift_tr = JointLifter(cfg.lift_hidden)
        self.trajectory = TrajectoryPath(cfg)
        self.keyframes = KeyframeAdapter(cfg)
        self.objects = ObjectBranch(cfg)
        self.pool = nn.Linear(len(CONDITION_TYPES) * cfg.d_e, cfg.d_e)

    def embed_2d(self, controls: dict) -> dict[str, torch.Tensor]:
        """{y: (B, d_e)} from the storyboard alone (what inference has)."""
        return {"kf": self.enc2d["kf"](*keypose_tokens_2d(controls)),
                "tr": self.enc2d["tr"](*trajectory_tokens_2d(controls)),
                "o": self.enc2d["o"](*object_tokens_2d(controls))}

    def embed_3d(self, controls: dict, motion: dict) -> dict[str, torch.Tensor]:
        """{y: (B, d_e)} from the ground-truth motion at the storyboard's constrained entries."""
        return {"kf": self.enc3d["kf"](*keypose_tokens_3d(controls, motion)),
                "tr": self.enc3d["tr"](*trajectory_tokens_3d(controls, motion)),
                "o": self.enc3d["o"](*object_tokens_3d(controls, motion))}

    def lift(self, controls: dict) -> LiftedControls:
        cam, target = controls["camera"], controls["cam_target"]

        def run(lifter: JointLifter, uv: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
            # Lift only the (sample, frame, human) groups that carry a constraint: a few percent.
            mask = _bool(mask)
            out = uv.new_zeros(mask.shape + (3,))
            b, n, h = torch.nonzero(mask.any(-1), as_tuple=True)
            out[b, n, h] = lifter(uv[b, n, h], mask[b, n, h], cam[b], target[b])
            return out

        return LiftedControls(run(self.lift_kf, controls["kp2d"], controls["kp_mask"]),
                              run(self.lift_tr, controls["tr2d"], controls["tr_mask"]))

    def encode(self, controls: dict, t_lat: int, v: int = 3) -> SketchEncoding:
        lifted = self.lift(controls)
        tr_res, bias = self.trajectory(lifted.trajectories, controls, t_lat)
        kf_res = self.keyframes(lifted.keyposes, controls, t_lat)              # (B, T_lat, H, d)
        obj = self.objects(controls, t_lat)                                    # (B, T_lat, O, d)
        none_h, none_o = torch.zeros_like(tr_res), torch.zeros_like(obj)
        residual = self._slots(tr_res + kf_res, obj, v)
        by_type = torch.stack([self._slots(kf_res, none_o, v), self._slots(tr_res, none_o, v),
                               self._slots(none_h, obj, v)], 3)
        s2d = self.embed_2d(controls)
        embed = self.pool(torch.cat([s2d[y] for y in CONDITION_TYPES], -1))
        text = text_mask = None
        if self.cfg.text and "text_ids" in controls:
            text_mask = controls["text_mask"].to(residual.dtype)
            text = self.text(controls["text_ids"], text_mask)
        return SketchEncoding(Conditioning(residual=residual, temporal_bias=bias, embed=embed, by_type=by_type,
                                           text=text, text_mask=text_mask), s2d, condition_presence(controls), lifted)

    def _slots(self, human: torch.Tensor, obj: torch.Tensor, v: int) -> torch.Tensor:
        """Per-entity features (B, T_lat, V, d): the humans', the objects' up to V, zero slots after."""
        slots = [human, obj[:, :, :max(v - self.cfg.num_humans, 0)]]
        spare = v - self.cfg.num_humans - slots[1].shape[2]
        if spare > 0:
            slots.append(human.new_zeros(human.shape[0], human.shape[1], spare, self.cfg.d_model))
        return torch.cat(slots, 2)

    def forward(self, controls: dict[str, torch.Tensor], T_lat: int, V: int = 3) -> Conditioning:
        return self.encode(controls, T_lat, V).conditioning

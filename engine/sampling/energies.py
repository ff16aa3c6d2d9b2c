"""Differentiable guidance energies on decoded motion (paper section 3.3), and their schedule.

Every energy is `(motion, ctx) -> (B,)` where `motion` is the decoder's dict
    joints (B, N, H, 22, 3)  rot6d (B, N, H, 22, 6)  obj_pose (B, N, O, 7)  obj_anchors (B, N, O, K, 3)
and `ctx` an EnergyContext. Each value is a mean over that energy's active constraints (so that
doubling the constraints does not change it), 0 when none is active, never NaN, and its gradient
is finite everywhere (norms are taken with a small epsilon, soft gates carry no gradient).
Units: metres (world and sketch plane), seconds for speeds; squared errors unless stated.

`total_energy` sums the enabled terms with base weights times a schedule over solver time
t in [0, 1] (t = 1 noise, t = 0 data): keyframe-like terms early, interaction mid, physics late.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, fields

import numpy as np
import torch
from torch import Tensor

from ..controls import build_controls, resample_polyline
from ..metrics import BONES, JOINT_RADII
from ..objects import TABLE_LEG, TABLE_TOP, ObjectSpec
from ..skeleton import FEET, HANDS, JOINT_INDEX, NUM_JOINTS
from ..storyboard import HANDS as HAND_NAMES
from ..storyboard import Storyboard

_EPS = 1e-12


@dataclass
class EnergyConfig:
    """Shapes of the individual energies (thresholds, margins, temperatures)."""
    key_weight_3d: float = 1.0        # 3D proxy term inside the keyframe energy
    key_weight_2d: float = 1.0        # 2D projected term
    key_time_sigma: float = 0.75      # frames; 2D keypose penalty spreads to nearby frames (g_time)
    quality_sigma: float = 0.1        # m; keypoints whose 2D target is this far off the proxy's
                                      # projection get weight exp(-1/2) (g_qual)
    traj_weight_3d: float = 1.0
    traj_weight_2d: float = 1.0
    softmin_temperature: float = 0.05 ** 2   # m^2; soft closest-point temperature on squared distance
    proxy_window: int = 8             # frames searched on the lifted 3D path around each frame
    contact_margin: float = 0.03      # m; a hand within this of its anchor is in contact
    hand_margin: float = 0.08         # m; wrist-to-wrist distance of two holding hands
    huber_delta: float = 0.1          # m
    min_spacing: float = 0.45         # m; horizontal pelvis distance below which people crowd
    stance_height: float = 0.05       # m above the foot's lowest point in the clip
    stance_height_softness: float = 0.01
    stance_speed: float = 0.2         # m/s vertical foot speed
    stance_speed_softness: float = 0.05
    foot_height: float = 0.02         # m; foot joint height when standing (rest skeleton)
    rot_smooth_weight: float = 0.1    # rotations vs positions in the smoothness energy


@dataclass
class EnergyContext:
    """Everything the energies read besides the motion, batched over B (the K variations).

    Control tensors follow engine/controls.py with a leading batch dimension. Trajectory strokes
    are the storyboard's polylines, padded by repeating their last point (a zero-length segment
    adds nothing to a closest-point distance), S strokes of L points.
    """
    kp2d: Tensor               # (B, N, H, 22, 2)
    kp_mask: Tensor            # (B, N, H, 22) bool
    tr2d: Tensor               # (B, N, H, 22, 2) per-frame resampled stroke targets
    tr_mask: Tensor            # (B, N, H, 22) bool
    strokes: Tensor            # (B, S, L, 2) raw trajectory polylines in the sketch plane
    stroke_joint: Tensor       # (B, S) long, flat index h * 22 + j of the stroke's joint
    stroke_frames: Tensor      # (B, S, N) bool, the stroke's frame span
    obj2d: Tensor              # (B, N, O, 4) object box centre u, v, width, height at keys
    obj_mask: Tensor           # (B, N, O) bool
    objpath2d: Tensor          # (B, N, O, 2)
    objpath_mask: Tensor       # (B, N, O) bool
    contact: Tensor            # (B, N, H, 2) bool, hand told to hold something
    contact_anchor: Tensor     # (B, N, H, 2) long, flat anchor o * K + k, -1 none
    hand_partner: Tensor       # (B, N, H, 2) long, flat hand h' * 2 + side' held, -1 none
    camera: Tensor             # (B, 3, 3) rows right, up, back
    cam_target: Tensor         # (B, 3)
    objects: tuple[ObjectSpec, ...] = ()
    fps: float = 20.0
    occupancy: Tensor | None = None    # (B, N, 3) CTMC approach / contact / carry
    K3D_hat: Tensor | None = None      # (B, N, H, 22, 3) lifted keypose proxies
    T3D_hat: Tensor | None = None      # (B, N, H, 22, 3) lifted trajectory proxies
    kp_quality: Tensor | None = None   # (B, N, H, 22) in [0, 1]; None = from the proxy (or 1)
    tr_quality: Tensor | None = None   # (B, N, H, 22)
    path_gate: Tensor | None = None    # (B, N, H, 22) in [0, 1]; None = 1 on the stroke span
    config: EnergyConfig = field(default_factory=EnergyConfig)

    @classmethod
    def from_storyboard(cls, sb: Storyboard, batch: int = 1, *, max_stroke_points: int = 64,
                        dtype: torch.dtype = torch.float32, device: str | torch.device = "cpu",
                        **extra) -> "EnergyContext":
        """Context for `batch` variations of one storyboard; `extra` sets the optional fields
        (occupancy, K3D_hat, T3D_hat, quality gates, config) as given."""
        c = build_controls(sb)
        n, h = sb.length, len(sb.agents)
        strokes = [resample_polyline(t.points, max_stroke_points) if len(t.points) > max_stroke_points
                   else np.asarray(t.points, float) for t in sb.trajectories]
        length = max([len(s) for s in strokes] + [2])
        padded = np.zeros((len(strokes), length, 2))
        frames = np.zeros((len(strokes), n), bool)
        joint = np.zeros(len(strokes), np.int64)
        for i, (t, pts) in enumerate(zip(sb.trajectories, strokes)):
            padded[i, :len(pts)] = pts
            padded[i, len(pts):] = pts[-1]
            frames[i, t.start:t.end + 1] = True
            joint[i] = sb.agent_index(t.agent) * NUM_JOINTS + JOINT_INDEX[t.joint]
        partner = np.full((n, h, 2), -1, np.int64)
        for ct in sb.contacts:
            if ct.other_agent is not None:
                partner[ct.start:ct.end + 1, sb.agent_index(ct.agent), HAND_NAMES.index(ct.hand)] = (
                    sb.agent_index(ct.other_agent) * 2 + HAND_NAMES.index(ct.other_hand))

        def tensor(a):
            a = np.asarray(a)
            kind = dtype if a.dtype.kind == "f" else None
            t = torch.as_tensor(a, dtype=kind, device=device)
            return t.unsqueeze(0).expand(batch, *t.shape).contiguous()

        return cls(kp2d=tensor(c.kp2d), kp_mask=tensor(c.kp_mask), tr2d=tensor(c.tr2d),
                   tr_mask=tensor(c.tr_mask), strokes=tensor(padded), stroke_joint=tensor(joint),
                   stroke_frames=tensor(frames), obj2d=tensor(c.obj2d), obj_mask=tensor(c.obj_mask),
                   objpath2d=tensor(c.objpath2d), objpath_mask=tensor(c.objpath_mask),
                   contact=tensor(c.contact), contact_anchor=tensor(c.contact_anchor),
                   hand_partner=tensor(partner), camera=tensor(c.camera),
                   cam_target=tensor(c.cam_target), objects=tuple(o.spec for o in sb.objects),
                   fps=float(sb.fps), **extra)


# ---- geometry helpers ---------------------------------------------------------------------

def safe_norm(v: Tensor) -> Tensor:
    """Euclidean norm over the last axis with a finite gradient at 0. (..., D) -> (...)."""
    return torch.sqrt((v * v).sum(-1) + _EPS)


def project(points: Tensor, ctx: EnergyContext) -> Tensor:
    """World points (B, ..., 3) -> sketch-plane points (B, ..., 2) through the storyboard camera."""
    b = points.shape[0]
    flat = points.reshape(b, -1, 3) - ctx.cam_target[:, None]
    uv = flat @ ctx.camera[:, :2].transpose(1, 2)
    return uv.reshape(*points.shape[:-1], 2)


def quat_to_matrix(q: Tensor) -> Tensor:
    """(..., 4) wxyz, normalised here -> (..., 3, 3)."""
    w, x, y, z = (q / safe_norm(q)[..., None]).unbind(-1)
    return torch.stack([
        1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
        2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
        2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y),
    ], -1).reshape(*q.shape[:-1], 3, 3)


def world_to_local(points: Tensor, pose: Tensor) -> Tensor:
    """World points (..., P, 3) into the frame of pose (..., 7: xyz + wxyz) -> (..., P, 3)."""
    R = quat_to_matrix(pose[..., 3:])
    return (points - pose[..., None, :3]) @ R


def _box_sdf(q: Tensor, half: Tensor) -> Tensor:
    """Signed distance to boxes centred at 0: q (..., 3), half (..., 3) broadcastable -> (...)."""
    d = q.abs() - half
    return safe_norm(d.clamp_min(0)) + d.max(-1).values.clamp_max(0)


def object_sdf(spec: ObjectSpec, p: Tensor) -> Tensor:
    """Signed distance (negative inside) of local points (..., 3) to the primitive -> (...).
    The torch twin of ObjectSpec.sdf_local (the tests check they agree)."""
    w, h, d = spec.size
    new = lambda *v: p.new_tensor(v)
    if spec.type == "box":
        return _box_sdf(p - new(0, h / 2, 0), new(w / 2, h / 2, d / 2))
    if spec.type == "canister":
        q = p - new(0, h / 2, 0)
        radial = safe_norm(q[..., [0, 2]]) - min(w, d) / 2
        vertical = q[..., 1].abs() - h / 2
        outside = safe_norm(torch.stack([radial.clamp_min(0), vertical.clamp_min(0)], -1))
        return outside + torch.maximum(radial, vertical).clamp_max(0)
    # table: top plus four legs, as one stack of boxes
    leg_h = (h - TABLE_TOP) / 2
    centres = [(0, h - TABLE_TOP / 2, 0)] + [(sx * (w / 2 - TABLE_LEG), leg_h, sz * (d / 2 - TABLE_LEG))
                                             for sx in (-1, 1) for sz in (-1, 1)]
    halves = [(w / 2, TABLE_TOP / 2, d / 2)] + [(TABLE_LEG / 2, leg_h, TABLE_LEG / 2)] * 4
    q = p[..., None, :] - p.new_tensor(centres)
    return _box_sdf(q, p.new_tensor(halves)).min(-1).values


def body_points(joints: Tensor) -> tuple[Tensor, Tensor]:
    """The capsule proxy of a body as spheres: joints and bone midpoints (see metrics.BONES).
    joints (..., 22, 3) -> points (..., 43, 3), radii (43,)."""
    parent, child = BONES[:, 0], BONES[:, 1]
    mids = 0.5 * (joints[..., parent, :] + joints[..., child, :])
    radii = np.concatenate([JOINT_RADII, 0.5 * (JOINT_RADII[parent] + JOINT_RADII[child])])
    return torch.cat([joints, mids], -2), joints.new_tensor(radii)


def segment_sq_distance(points: Tensor, a: Tensor, b: Tensor) -> Tensor:
    """Squared distance of points to segments [a, b], all (..., D) broadcastable -> (...).
    A zero-length segment is its point."""
    seg, rel = b - a, points - a
    t = ((rel * seg).sum(-1) / ((seg * seg).sum(-1) + _EPS)).clamp(0, 1)
    diff = rel - t[..., None] * seg
    return (diff * diff).sum(-1)


def soft_min_mean(d2: Tensor, temperature: float, valid: Tensor | None = None) -> Tensor:
    """Softmin over the last axis of squared distances (..., S) -> (...), valid (..., S) bool.

    The value is the mean of d2 under weights softmax(-d2 / temperature) held constant: so it is
    >= 0, equals the minimum when one entry is clearly smallest, and its gradient is the
    log-sum-exp softmin's (a blend of pulls towards each entry), which does not jump where
    the nearest entry changes."""
    logits = -d2.detach() / temperature
    if valid is not None:
        logits = logits - 1e9 * (~valid).to(logits.dtype)
    return (torch.softmax(logits, -1) * d2).sum(-1)


def soft_polyline_sq_distance(points: Tensor, polyline: Tensor, temperature: float) -> Tensor:
    """Soft squared closest-point distance of points (..., P, D) to a polyline (..., L, D),
    L >= 2 -> (..., P): the softmin (soft_min_mean) over the polyline's segments.

    Written with matrix products so that no (P, L, D) tensor is formed (the energies' hot spot);
    coordinates are taken relative to the polyline's first point to keep the expansion exact."""
    origin = polyline[..., :1, :]
    q, poly = points - origin, polyline - origin
    a, seg = poly[..., :-1, :], poly[..., 1:, :] - poly[..., :-1, :]          # (..., L-1, D)
    qa, qs = q @ a.transpose(-1, -2), q @ seg.transpose(-1, -2)              # (..., P, L-1)
    rel_seg = qs - (a * seg).sum(-1)[..., None, :]
    rel2 = (q * q).sum(-1)[..., :, None] - 2 * qa + (a * a).sum(-1)[..., None, :]
    seg2 = (seg * seg).sum(-1)[..., None, :]
    t = (rel_seg / (seg2 + _EPS)).clamp(0, 1)
    d2 = (rel2 - 2 * t * rel_seg + t * t * seg2).clamp_min(0)
    return soft_min_mean(d2, temperature)


def _per_constraint(total: Tensor, count: Tensor) -> Tensor:
    """Sum over constraints -> mean per constraint; 0 where there is none."""
    return total / count.clamp_min(1.0)


def _huber(x: Tensor, delta: float) -> Tensor:
    ax = x.abs()
    return torch.where(ax < delta, 0.5 * x * x, delta * (ax - 0.5 * delta))


def _interaction_gate(ctx: EnergyContext, like: Tensor) -> Tensor:
    """(B, N) occupancy of contact + carry: contact terms follow the CTMC phase (1 without one)."""
    if ctx.occupancy is None:
        return like.new_ones(like.shape[:2])
    return ctx.occupancy[..., 1] + ctx.occupancy[..., 2]


def _proxy_quality(target2d: Tensor, proxy3d: Tensor | None, ctx: EnergyContext) -> Tensor | float:
    """g_qual: down-weight 2D targets (B, N, H, 22, 2) that disagree with the projection of the
    lifted 3D proxy (B, N, H, 22, 3). -> (B, N, H, 22), or 1.0 without a proxy."""
    if proxy3d is None:
        return 1.0
    err = ((project(proxy3d, ctx) - target2d) ** 2).sum(-1)
    return torch.exp(-0.5 * err / ctx.config.quality_sigma ** 2).detach()


def _stance(feet: Tensor, fps: float, cfg: EnergyConfig) -> Tensor:
    """Soft stance weight of feet (B, N, H, 2, 3) per frame -> (B, N, H, 2), no gradient.
    Stance = low (height over the foot's lowest point in the clip) and slow vertically."""
    with torch.no_grad():
        y = feet[..., 1]
        height = y - y.min(1, keepdim=True).values
        vy = torch.zeros_like(y)
        vy[:, :-1] = (y[:, 1:] - y[:, :-1]) * fps
        vy[:, -1:] = vy[:, -2:-1] if y.shape[1] > 1 else 0.0
        low = torch.sigmoid((cfg.stance_height - height) / cfg.stance_height_softness)
        still = torch.sigmoid((cfg.stance_speed - vy.abs()) / cfg.stance_speed_softness)
        return low * still


# ---- the energies ---------------------------------------------------------------------------

def keyframe_energy(motion: dict[str, Tensor], ctx: EnergyContext) -> Tensor:
    """E_key = E_3D (to the lifted proxy K3D_hat, if any) + E_2D (projected, to the sketched
    keypose). The 2D penalty of a keypose at frame k also applies at frames k +- d with the time
    gate g_time(d) = exp(-d^2 / 2 sigma^2), and is scaled by the quality gate g_qual.
    Normalised by the number of sketched keypoints. -> (B,)"""
    cfg = ctx.config
    joints = motion["joints"]
    n = joints.shape[1]
    mask = ctx.kp_mask.to(joints.dtype)                                      # (B, N, H, J)
    count = mask.sum((1, 2, 3))
    e3d = joints.new_zeros(joints.shape[0])
    if ctx.K3D_hat is not None:
        e3d = _per_constraint((((joints - ctx.K3D_hat) ** 2).sum(-1) * mask).sum((1, 2, 3)), count)
    quality = ctx.kp_quality if ctx.kp_quality is not None else _proxy_quality(ctx.kp2d, ctx.K3D_hat, ctx)
    weight = mask * quality
    keys = ctx.kp_mask.flatten(2).any(-1).any(0).nonzero()[:, 0]             # (F,) keyframes
    radius = math.ceil(2 * cfg.key_time_sigma)
    offsets = torch.arange(-radius, radius + 1, device=joints.device)
    gate = torch.exp(-0.5 * offsets.to(joints.dtype) ** 2 / max(cfg.key_time_sigma, 1e-6) ** 2)
    frames = keys[None] + offsets[:, None]                                   # (D, F)
    gate = gate[:, None] * ((frames >= 0) & (frames < n)).to(joints.dtype)
    uv = project(joints[:, frames.clamp(0, n - 1)], ctx)                     # (B, D, F, H, J, 2)
    err = ((uv - ctx.kp2d[:, keys][:, None]) ** 2).sum(-1)                   # (B, D, F, H, J)
    e2d = _per_constraint((err * gate[None, :, :, None, None] * weight[:, keys][:, None]).sum((1, 2, 3, 4)),
                          count)
    return cfg.key_weight_3d * e3d + cfg.key_weight_2d * e2d


def trajectory_energy(motion: dict[str, Tensor], ctx: EnergyContext) -> Tensor:
    """E_tr = E_3D (soft distance to the lifted path T3D_hat over the stroke's frames, if any)
    + E_2D (soft distance of the projected joint to the sketched polyline, weighted by the path
    gate and the quality gate), over the stroke's frames; per constrained (frame, stroke). -> (B,)"""
    cfg = ctx.config
    joints = motion["joints"]
    b, n = joints.shape[:2]
    s = ctx.stroke_joint.shape[1]
    if s == 0:
        return joints.new_zeros(b)
    frames = ctx.stroke_frames.to(joints.dtype)                              # (B, S, N)
    count = frames.sum((1, 2))
    index = ctx.stroke_joint[:, None, :].expand(b, n, s)                     # (B, N, S)

    def per_stroke(x: Tensor) -> Tensor:  # (B, N, H, J, ...) -> (B, S, N, ...)
        flat = x.reshape(b, n, -1, *x.shape[4:])
        idx = index.reshape(b, n, s, *([1] * (flat.dim() - 3))).expand(b, n, s, *flat.shape[3:])
        return flat.gather(2, idx).transpose(1, 2)

    p = per_stroke(joints)                                                   # (B, S, N, 3)
    e3d = joints.new_zeros(b)
    if ctx.T3D_hat is not None:
        # The lifted path is timed, so frame n looks for its closest point only among the
        # path's segments that start within +- proxy_window frames of n.
        path = per_stroke(ctx.T3D_hat)                                       # (B, S, N, 3)
        w = cfg.proxy_window
        start = torch.arange(n, device=joints.device)[:, None] + torch.arange(-w, w + 1, device=joints.device)
        inside = (start >= 0) & (start < n)                                  # (N, 2w+1)
        start = start.clamp(0, n - 1)
        on = ctx.stroke_frames
        end = torch.where(on[:, :, (start + 1).clamp(max=n - 1)], (start + 1).clamp(max=n - 1), start)
        valid = inside & on[:, :, start]                                     # (B, S, N, 2w+1)
        a = path[:, :, start]
        b_end = path.gather(2, end.flatten(2)[..., None].expand(-1, -1, -1, 3)).reshape(a.shape)
        d2 = soft_min_mean(segment_sq_distance(p[..., None, :], a, b_end), cfg.softmin_temperature, valid)
        e3d = _per_constraint((d2 * frames).sum((1, 2)), count)
    d2 = soft_polyline_sq_distance(project(p, ctx), ctx.strokes, cfg.softmin_temperature)
    weight = frames
    quality = ctx.tr_quality if ctx.tr_quality is not None else _proxy_quality(ctx.tr2d, ctx.T3D_hat, ctx)
    for gate in (ctx.path_gate, quality):
        if isinstance(gate, Tensor):
            weight = weight * per_stroke(gate)
    e2d = _per_constraint((d2 * weight).sum((1, 2)), count)
    return cfg.traj_weight_3d * e3d + cfg.traj_weight_2d * e2d


def object_energy(motion: dict[str, Tensor], ctx: EnergyContext) -> Tensor:
    """Projected object centre (the middle of its bounding box) vs the sketched silhouette's
    centre at object keys and vs the object path on its frames; per constrained (frame, object).
    -> (B,)"""
    pose = motion.get("obj_pose")
    b = motion["joints"].shape[0]
    if pose is None or not ctx.objects:
        return motion["joints"].new_zeros(b)
    half_height = pose.new_tensor([[0.0, spec.size[1] / 2, 0.0] for spec in ctx.objects])   # (O, 3)
    centre = pose[..., :3] + (quat_to_matrix(pose[..., 3:]) @ half_height[..., None])[..., 0]
    uv = project(centre, ctx)                                                # (B, N, O, 2)
    key, path = ctx.obj_mask.to(uv.dtype), ctx.objpath_mask.to(uv.dtype)
    total = ((((uv - ctx.obj2d[..., :2]) ** 2).sum(-1) * key).sum((1, 2))
             + (((uv - ctx.objpath2d) ** 2).sum(-1) * path).sum((1, 2)))
    return _per_constraint(total, key.sum((1, 2)) + path.sum((1, 2)))


def contact_energy(motion: dict[str, Tensor], ctx: EnergyContext) -> Tensor:
    """Huber(max(0, |hand - anchor| - margin)) on storyboard object contacts, weighted by the
    CTMC occupancy of contact + carry; per active (frame, hand). -> (B,)"""
    joints = motion["joints"]
    b, n, h = joints.shape[:3]
    anchors = motion.get("obj_anchors")
    active = ctx.contact & (ctx.contact_anchor >= 0)                         # (B, N, H, 2)
    if anchors is None or anchors.shape[2] == 0:
        return joints.new_zeros(b)
    anchors = anchors.reshape(b, n, -1, 3)
    idx = ctx.contact_anchor.clamp_min(0).reshape(b, n, h * 2, 1).expand(b, n, h * 2, 3)
    target = anchors.gather(2, idx).reshape(b, n, h, 2, 3)
    gap = (safe_norm(joints[:, :, :, list(HANDS)] - target) - ctx.config.contact_margin).clamp_min(0)
    weight = active.to(joints.dtype) * _interaction_gate(ctx, joints)[:, :, None, None]
    return _per_constraint((_huber(gap, ctx.config.huber_delta) * weight).sum((1, 2, 3)),
                           active.sum((1, 2, 3)).to(joints.dtype))


def hand_contact_energy(motion: dict[str, Tensor], ctx: EnergyContext) -> Tensor:
    """Like contact_energy for a hand holding another person's hand (wrist to wrist). -> (B,)"""
    joints = motion["joints"]
    b, n, h = joints.shape[:3]
    hands = joints[:, :, :, list(HANDS)].reshape(b, n, h * 2, 3)
    active = ctx.hand_partner >= 0
    idx = ctx.hand_partner.clamp_min(0).reshape(b, n, h * 2, 1).expand(b, n, h * 2, 3)
    partner = hands.gather(2, idx).reshape(b, n, h, 2, 3)
    gap = (safe_norm(joints[:, :, :, list(HANDS)] - partner) - ctx.config.hand_margin).clamp_min(0)
    weight = active.to(joints.dtype) * _interaction_gate(ctx, joints)[:, :, None, None]
    return _per_constraint((_huber(gap, ctx.config.huber_delta) * weight).sum((1, 2, 3)),
                           active.sum((1, 2, 3)).to(joints.dtype))


def spacing_energy(motion: dict[str, Tensor], ctx: EnergyContext) -> Tensor:
    """max(0, d_min - horizontal pelvis distance)^2 for each pair of people on frames without a
    storyboard contact (weighted by the CTMC approach occupancy); per (frame, pair). -> (B,)"""
    joints = motion["joints"]
    b, n, h = joints.shape[:3]
    if h < 2:
        return joints.new_zeros(b)
    i, j = torch.triu_indices(h, h, 1, device=joints.device)
    pelvis = joints[:, :, :, 0][..., [0, 2]]                                 # (B, N, H, 2)
    dist = safe_norm(pelvis[:, :, i] - pelvis[:, :, j])                      # (B, N, P)
    free = (~ctx.contact.flatten(2).any(-1)).to(joints.dtype)                # (B, N)
    gate = free if ctx.occupancy is None else free * ctx.occupancy[..., 0]
    crowd = (ctx.config.min_spacing - dist).clamp_min(0) ** 2
    return _per_constraint((crowd * gate[..., None]).sum((1, 2)), free.sum(1) * len(i))


def foot_skate_energy(motion: dict[str, Tensor], ctx: EnergyContext) -> Tensor:
    """Squared horizontal foot speed (m/s)^2 weighted by the soft stance of the foot; normalised
    by the total stance weight. -> (B,)"""
    feet = motion["joints"][:, :, :, list(FEET)]                             # (B, N, H, 2, 3)
    if feet.shape[1] < 2:
        return feet.new_zeros(feet.shape[0])
    stance = _stance(feet, ctx.fps, ctx.config)[:, :-1]
    vel = (feet[:, 1:] - feet[:, :-1])[..., [0, 2]] * ctx.fps
    return _per_constraint(((vel * vel).sum(-1) * stance).sum((1, 2, 3)), stance.sum((1, 2, 3)))


def ground_energy(motion: dict[str, Tensor], ctx: EnergyContext) -> Tensor:
    """Depth^2 of joints below the ground (per joint below) + (foot height - standing height)^2
    of feet in stance (per unit stance weight). -> (B,)"""
    joints = motion["joints"]
    below = (-joints[..., 1]).clamp_min(0)
    sunk = _per_constraint((below ** 2).sum((1, 2, 3)), (below > 0).sum((1, 2, 3)).to(joints.dtype))
    feet = joints[:, :, :, list(FEET)]
    stance = _stance(feet, ctx.fps, ctx.config)
    lift = (feet[..., 1] - ctx.config.foot_height) ** 2
    return sunk + _per_constraint((lift * stance).sum((1, 2, 3)), stance.sum((1, 2, 3)))


def smoothness_energy(motion: dict[str, Tensor], ctx: EnergyContext) -> Tensor:
    """Mean squared second difference (per frame^2) of joint positions, plus that of the 6D
    rotations times rot_smooth_weight. -> (B,)"""
    def accel(x: Tensor) -> Tensor:
        if x.shape[1] < 3:
            return x.new_zeros(x.shape[0])
        a = x[:, 2:] - 2 * x[:, 1:-1] + x[:, :-2]
        return (a * a).sum(-1).flatten(1).mean(1)

    out = accel(motion["joints"])
    if "rot6d" in motion:
        out = out + ctx.config.rot_smooth_weight * accel(motion["rot6d"])
    return out


def penetration_energy(motion: dict[str, Tensor], ctx: EnergyContext) -> Tensor:
    """Depth^2 of the body's capsule spheres inside objects (analytic SDF at the object's pose)
    and inside the other people's spheres; per penetrating (sphere, obstacle). -> (B,)

    Penetrating pairs are found without autograd first; only those few get a differentiable
    recomputation, which keeps the cost independent of the (mostly empty) pair count."""
    joints = motion["joints"]
    b, n, h = joints.shape[:3]
    points, radii = body_points(joints)                                      # (B, N, H, P, 3)
    p = points.shape[3]
    depth, owner = [joints.new_zeros(0)], [torch.zeros(0, dtype=torch.long)]
    pose = motion.get("obj_pose")
    flat = points.reshape(b, n, h * p, 3)
    flat_radii = radii.repeat(h)
    rotation = None if pose is None else quat_to_matrix(pose[..., 3:])      # (B, N, O, 3, 3)
    for o, spec in enumerate(ctx.objects if pose is not None else ()):
        with torch.no_grad():  # bounding box grown by the largest radius, then the SDF inside it
            w, hgt, d = spec.size
            local = (flat - pose[:, :, o, None, :3]) @ rotation[:, :, o]     # (B, N, H*P, 3)
            centred = (local - local.new_tensor([0.0, hgt / 2, 0.0])).abs()
            bound = local.new_tensor([w / 2, hgt / 2, d / 2]) + float(radii.max())
            bi, ni, ki = (centred < bound).all(-1).nonzero(as_tuple=True)
            inside = flat_radii[ki] - object_sdf(spec, local[bi, ni, ki]) > 0
            bi, ni, ki = bi[inside], ni[inside], ki[inside]
        rel = flat[bi, ni, ki] - pose[bi, ni, o, :3]
        local = (rel[:, None] @ rotation[bi, ni, o])[:, 0]
        depth.append(flat_radii[ki] - object_sdf(spec, local))
        owner.append(bi)
    reach = radii[:, None] + radii[None]                                     # (P, P)
    for i, j in zip(*torch.triu_indices(h, h, 1).tolist()):
        with torch.no_grad():
            dist = torch.cdist(points[:, :, i], points[:, :, j])              # (B, N, P, P)
            bi, ni, pi, pj = (reach - dist > 0).nonzero(as_tuple=True)
        gap = safe_norm(points[bi, ni, i, pi] - points[bi, ni, j, pj])
        depth.append(reach[pi, pj] - gap)
        owner.append(bi)
    depth, owner = torch.cat(depth).clamp_min(0), torch.cat(owner)
    total = joints.new_zeros(b).index_add(0, owner, depth ** 2)
    count = joints.new_zeros(b).index_add(0, owner, (depth > 0).to(depth.dtype))
    return _per_constraint(total, count)


ENERGIES = {
    "keyframe": keyframe_energy, "trajectory": trajectory_energy, "object": object_energy,
    "contact": contact_energy, "hand_contact": hand_contact_energy, "spacing": spacing_energy,
    "penetration": penetration_energy,
    "foot_skate": foot_skate_energy, "ground": ground_energy, "smoothness": smoothness_energy,
}
# Which schedule bump each energy follows.
STAGE = {"keyframe": "early", "trajectory": "early", "object": "early",
         "contact": "mid", "hand_contact": "mid", "spacing": "mid", "penetration": "mid",
         "foot_skate": "late", "ground": "late", "smoothness": "late"}


# ---- schedule and total -----------------------------------------------------------------------

@dataclass
class EnergySchedule:
    """Smooth bumps over solver time t (1 = noise, 0 = data): a stage's factor is
    floor + (1 - floor) exp(-(t - centre)^2 / 2 width^2), so 1 at its centre and never off.
    Keyframes peak early (near noise, when the global layout forms), interaction mid, physics
    late (near data, when detail forms), which keeps the terms from fighting all at once."""
    early: float = 0.8
    mid: float = 0.5
    late: float = 0.15
    width: float = 0.2
    floor: float = 0.15

    def factor(self, stage: str, t: float) -> float:
        centre = getattr(self, stage)
        return self.floor + (1 - self.floor) * math.exp(-0.5 * ((t - centre) / self.width) ** 2)


@dataclass
class EnergyWeights:
    """Base weight lambda_r of each energy, chosen so that typical violations (5-10 cm off a
    target, 0.5 m/s foot slide, 2 cm penetration) contribute comparably."""
    keyframe: float = 1.0
    trajectory: float = 1.0
    object: float = 1.0
    contact: float = 1.0
    hand_contact: float = 1.0
    spacing: float = 1.0
    penetration: float = 10.0
    foot_skate: float = 0.05
    ground: float = 10.0
    smoothness: float = 20.0
    schedule: EnergySchedule = field(default_factory=EnergySchedule)

    def at(self, t: float) -> dict[str, float]:
        """lambda_r(t) for every energy name."""
        return {f.name: getattr(self, f.name) * self.schedule.factor(STAGE[f.name], t)
                for f in fields(self) if f.name in ENERGIES}


def total_energy(motion: dict[str, Tensor], ctx: EnergyContext, t: float,
                 weights: EnergyWeights | None = None,
                 enabled: set[str] | None = None) -> tuple[Tensor, dict[str, Tensor]]:
    """sum_r lambda_r(t) E_r over the enabled energies (None = all).
    Returns total (B,) and the unweighted E_r (B,) by name, for display."""
    weights = weights or EnergyWeights()
    unknown = set(enabled or ()) - set(ENERGIES)
    if unknown:
        raise ValueError(f"unknown energies {sorted(unknown)}; known: {list(ENERGIES)}")
    names = ENERGIES if enabled is None else [n for n in ENERGIES if n in enabled]
    lam = weights.at(t)
    terms = {name: ENERGIES[name](motion, ctx) for name in names}
    total = motion["joints"].new_zeros(motion["joints"].shape[0])
    for name, value in terms.items():
        total = total + lam[name] * value
    return total, terms

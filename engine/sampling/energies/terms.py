"""The sketch terms: keyposes, paths, the object's keys and path, contacts, and spacing.

Speed: the sampler evaluates value + gradient about 26 times per generation on small tensors, so
the cost is mostly the number of torch ops (forward and backward), not flops. Everything that
depends only on the storyboard (index tensors, masks, targets, gates, normalisers) is built once
per context (`_constants`); each energy's per-call part is a short chain of batched ops without
Python loops over people, strokes or keys.
"""
from __future__ import annotations

import math
from types import SimpleNamespace

import torch
from torch import Tensor

from ...geometry.rotations_torch import quat_to_matrix, safe_norm
from .context import _EPS, _HAND_JOINTS, EnergyContext, _constants
from .geometry import (_huber, _invalid_bias, _pairs, _polyline_segments, _soft_polyline_sq_distance,
                       _soft_segments_sq_distance, project)


def _interaction_gate(occupancy: Tensor | None, like: Tensor) -> Tensor:
    """(B, N) occupancy of contact + carry: contact terms follow the CTMC phase (1 without one)."""
    if occupancy is None:
        return like.new_ones(like.shape[:2])
    return occupancy[..., 1] + occupancy[..., 2]


def _proxy_quality(target2d: Tensor, proxy3d: Tensor | None, ctx: EnergyContext) -> Tensor | float:
    """g_qual: down-weight 2D targets (B, N, H, 22, 2) that disagree with the projection of the
    lifted 3D proxy (B, N, H, 22, 3). -> (B, N, H, 22), or 1.0 without a proxy."""
    if proxy3d is None:
        return 1.0
    err = ((project(proxy3d, ctx) - target2d) ** 2).sum(-1)
    return torch.exp(-0.5 * err / ctx.config.quality_sigma ** 2).detach()



# ---- the energies ---------------------------------------------------------------------------

def _keyframe_constants(ctx: EnergyContext) -> SimpleNamespace:
    """Keyframe energy constants at the frames within the time gate's reach of a keyframe
    (F keyframes, D offsets, DF = D * F frames, offset-major so that the keyframes themselves
    are the slice `at_keys`):
        frames (DF,) long    target (B, DF, H, J, 2)    weight2 (B, DF, H, J, 1) = g_time g_qual mask
        proxy3 (B, F, H, J, 3), mask3 (B, F, H, J, 1): the 3D term at the keyframes, or None
    weights already scaled by their term weight over the number of sketched keypoints (only
    keyframes have any, so the 3D term needs no other frame)."""
    cfg = ctx.config
    n = ctx.kp_mask.shape[1]
    mask = ctx.kp_mask.to(ctx.kp2d.dtype)                                    # (B, N, H, J)
    scale = 1.0 / mask.sum((1, 2, 3)).clamp_min(1.0)                         # (B,)
    quality = ctx.kp_quality if ctx.kp_quality is not None else _proxy_quality(ctx.kp2d, ctx.K3D_hat, ctx)
    weight = mask * quality
    keys = ctx.kp_mask.flatten(2).any(-1).any(0).nonzero()[:, 0]             # (F,) keyframes
    radius = math.ceil(2 * cfg.key_time_sigma)
    offsets = torch.arange(-radius, radius + 1, device=mask.device)
    gate = torch.exp(-0.5 * offsets.to(mask.dtype) ** 2 / max(cfg.key_time_sigma, 1e-6) ** 2)
    frames = keys[None] + offsets[:, None]                                   # (D, F)
    gate = gate[:, None] * ((frames >= 0) & (frames < n)).to(mask.dtype)
    weight2 = (cfg.key_weight_2d * scale[:, None, None, None, None] * gate[None, :, :, None, None]
               * weight[:, keys][:, None])                                   # (B, D, F, H, J)
    b, d, f = weight2.shape[:3]
    target = ctx.kp2d[:, keys][:, None].expand(b, d, *ctx.kp2d[:, keys].shape[1:])
    proxy3 = mask3 = None
    if ctx.K3D_hat is not None:
        proxy3 = ctx.K3D_hat[:, keys]
        mask3 = (cfg.key_weight_3d * mask[:, keys] * scale[:, None, None, None])[..., None]
    return SimpleNamespace(frames=frames.clamp(0, n - 1).flatten(),
                           at_keys=slice(radius * f, (radius + 1) * f),
                           target=target.reshape(b, d * f, *target.shape[3:]),
                           weight2=weight2.reshape(b, d * f, *weight2.shape[3:], 1),
                           proxy3=proxy3, mask3=mask3)


def keyframe_energy(motion: dict[str, Tensor], ctx: EnergyContext, occupancy: Tensor | None = None) -> Tensor:
    """E_key = E_3D (to the lifted proxy K3D_hat, if any) + E_2D (projected, to the sketched
    keypose). The 2D penalty of a keypose at frame k also applies at frames k +- d with the time
    gate g_time(d) = exp(-d^2 / 2 sigma^2), and is scaled by the quality gate g_qual.
    Normalised by the number of sketched keypoints. -> (B,)"""
    c = _constants(ctx, _keyframe_constants)
    joints = motion["joints"]
    if not len(c.frames):
        return joints.new_zeros(joints.shape[0])
    near = joints.index_select(1, c.frames)                                  # (B, DF, H, J, 3)
    err = project(near, ctx) - c.target                                      # (B, DF, H, J, 2)
    out = (err * err * c.weight2).sum((1, 2, 3, 4))
    if c.proxy3 is not None:
        d = near[:, c.at_keys] - c.proxy3                                    # (B, F, H, J, 3)
        out = out + (d * d * c.mask3).sum((1, 2, 3, 4))
    return out


def _per_stroke_index(ctx: EnergyContext) -> Tensor:
    """(B, S * N) flat index into (N, H * 22) of each stroke's joint at every frame."""
    b, n, h, j = ctx.kp_mask.shape
    frames = torch.arange(n, device=ctx.stroke_joint.device)
    return (frames[None, None] * (h * j) + ctx.stroke_joint[:, :, None]).flatten(1)


def _per_stroke(x: Tensor, index: Tensor) -> Tensor:
    """The stroke joints' values: x (B, N, H, J, ...) -> (B, S, N, ...), index from _per_stroke_index."""
    b, n = x.shape[:2]
    flat = x.reshape(b, -1, *x.shape[4:])                                    # (B, N*H*J, ...)
    idx = index.reshape(b, -1, *([1] * (flat.dim() - 2))).expand(b, -1, *flat.shape[2:])
    return flat.gather(1, idx).reshape(b, -1, n, *flat.shape[2:])


def _trajectory_constants(ctx: EnergyContext) -> SimpleNamespace:
    """Trajectory energy constants (S strokes, N frames, W = 2 proxy_window + 1 path segments):
        index (B, S*N, 3)     gather index of the stroke joints in joints.reshape(B, -1, 3)
        path3d: a, seg (3, B, S, N, W) coordinate-first, seg_sq (B, S, N, W), bias (B, S, N, W)
                logit offset of the invalid segments, weight (B, S, N); None without T3D_hat
        poly: the strokes' polyline constants (_polyline_segments)
        weight2 (B, S, N) = path gate * g_qual on the stroke's frames
    weights already scaled by their term weight over the number of constrained (frame, stroke)."""
    cfg = ctx.config
    b, s, n = ctx.stroke_frames.shape
    index = _per_stroke_index(ctx)
    frames = ctx.stroke_frames.to(ctx.strokes.dtype)                         # (B, S, N)
    frames = frames / frames.sum((1, 2)).clamp_min(1.0)[:, None, None]
    path3d = None
    if ctx.T3D_hat is not None:
        # The lifted path is timed, so frame n looks for its closest point only among the
        # path's segments that start within +- proxy_window frames of n.
        path = _per_stroke(ctx.T3D_hat, index)                               # (B, S, N, 3)
        w, a_device = cfg.proxy_window, path.device
        start = torch.arange(n, device=a_device)[:, None] + torch.arange(-w, w + 1, device=a_device)  # (N, W)
        inside = (start >= 0) & (start < n)
        start = start.clamp(0, n - 1)
        on = ctx.stroke_frames
        end = torch.where(on[:, :, (start + 1).clamp(max=n - 1)], (start + 1).clamp(max=n - 1), start)
        valid = inside & on[:, :, start]                                     # (B, S, N, W)
        a = path[:, :, start]
        seg = path.gather(2, end.flatten(2)[..., None].expand(-1, -1, -1, 3)).reshape(a.shape) - a
        path3d = SimpleNamespace(a=a.movedim(-1, 0).contiguous(), seg=seg.movedim(-1, 0).contiguous(),
                                 seg_sq=(seg * seg).sum(-1) + _EPS,
                                 bias=_invalid_bias(valid, a.dtype), weight=cfg.traj_weight_3d * frames)
    weight2 = cfg.traj_weight_2d * frames
    quality = ctx.tr_quality if ctx.tr_quality is not None else _proxy_quality(ctx.tr2d, ctx.T3D_hat, ctx)
    for gate in (ctx.path_gate, quality):
        if isinstance(gate, Tensor):
            weight2 = weight2 * _per_stroke(gate, index)
    return SimpleNamespace(index=index[..., None].expand(b, s * n, 3), path3d=path3d,
                           poly=_polyline_segments(ctx.strokes), weight2=weight2)


def trajectory_energy(motion: dict[str, Tensor], ctx: EnergyContext, occupancy: Tensor | None = None) -> Tensor:
    """E_tr = E_3D (soft distance to the lifted path T3D_hat over the stroke's frames, if any)
    + E_2D (soft distance of the projected joint to the sketched polyline, weighted by the path
    gate and the quality gate), over the stroke's frames; per constrained (frame, stroke). -> (B,)"""
    joints = motion["joints"]
    b, n = joints.shape[:2]
    s = ctx.stroke_joint.shape[1]
    if s == 0:
        return joints.new_zeros(b)
    c = _constants(ctx, _trajectory_constants)
    temperature = ctx.config.softmin_temperature
    p = joints.reshape(b, -1, 3).gather(1, c.index).view(b, s, n, 3)        # (B, S, N, 3)
    d2 = _soft_polyline_sq_distance(project(p, ctx), c.poly, temperature)   # (B, S, N)
    out = (d2 * c.weight2).sum((1, 2))
    if c.path3d is not None:
        path = c.path3d
        d2 = _soft_segments_sq_distance(p, path.a, path.seg, path.seg_sq, temperature, path.bias)
        out = out + (d2 * path.weight).sum((1, 2))
    return out


def _object_constants(ctx: EnergyContext) -> SimpleNamespace:
    """Object energy constants: targets (B, N, O, 2, 2) (silhouette centre at keys, path point)
    and weights (B, N, O, 2, 1) (key, path masks over the number of constraints); `any` is False
    when nothing constrains an object, lift (O, 2, 1): how far above its pose each target's point
    is, half the object's height for the silhouette's centre, none for the path's base."""
    key, path = ctx.obj_mask.to(ctx.obj2d.dtype), ctx.objpath_mask.to(ctx.obj2d.dtype)
    weights = torch.stack([key, path], -1)
    count = weights.sum((1, 2, 3))
    return SimpleNamespace(targets=torch.stack([ctx.obj2d[..., :2], ctx.objpath2d], -2),
                           weights=(weights / count.clamp_min(1.0)[:, None, None, None])[..., None],
                           any=bool(count.any()),
                           lift=ctx.obj2d.new_tensor([[[spec.size[1] / 2], [0.0]] for spec in ctx.objects]))


def object_energy(motion: dict[str, Tensor], ctx: EnergyContext, occupancy: Tensor | None = None) -> Tensor:
    """Projected object centre (the middle of its bounding box) vs the sketched silhouette's
    centre at object keys, and its base (the pose's origin, which an object path traces:
    engine.sketchify, docs/storyboard.md) vs the path on its frames; per constrained (frame,
    object). -> (B,)"""
    pose = motion.get("obj_pose")
    b = motion["joints"].shape[0]
    if pose is None or not ctx.objects:
        return motion["joints"].new_zeros(b)
    c = _constants(ctx, _object_constants)
    if not c.any:
        return motion["joints"].new_zeros(b)
    up = quat_to_matrix(pose[..., 3:])[..., 1]                              # (B, N, O, 3) rotated y axis
    points = pose[..., None, :3] + up[..., None, :] * c.lift                # (B, N, O, 2, 3) centre, base
    err = project(points, ctx) - c.targets                                  # (B, N, O, 2, 2)
    return (err * err * c.weights).sum((1, 2, 3, 4))


def _contact_constants(ctx: EnergyContext) -> SimpleNamespace:
    """Contact constants: index (B, N, H*2, 3) of each hand's anchor in anchors.reshape(B, N, -1, 3),
    weight (B, N, H, 2): the active hands over their count; `any`: some hand is active."""
    b, n, h = ctx.contact.shape[:3]
    active = (ctx.contact & (ctx.contact_anchor >= 0)).to(ctx.kp2d.dtype)   # (B, N, H, 2)
    count = active.sum((1, 2, 3)).clamp_min(1.0)
    index = ctx.contact_anchor.clamp_min(0).reshape(b, n, h * 2, 1).expand(b, n, h * 2, 3)
    return SimpleNamespace(index=index, weight=active / count[:, None, None, None], any=bool(active.any()))


def contact_energy(motion: dict[str, Tensor], ctx: EnergyContext, occupancy: Tensor | None = None) -> Tensor:
    """Huber(max(0, |hand - anchor| - margin)) on storyboard object contacts, weighted by the
    CTMC occupancy of contact + carry; per active (frame, hand). -> (B,)"""
    joints = motion["joints"]
    b, n, h = joints.shape[:3]
    anchors = motion.get("obj_anchors")
    if anchors is None or anchors.shape[2] == 0:
        return joints.new_zeros(b)
    c = _constants(ctx, _contact_constants)
    if not c.any:
        return joints.new_zeros(b)
    target = anchors.reshape(b, n, -1, 3).gather(2, c.index).view(b, n, h, 2, 3)
    gap = (safe_norm(joints[:, :, :, _HAND_JOINTS] - target) - ctx.config.contact_margin).clamp_min(0)
    weight = c.weight * _interaction_gate(occupancy, joints)[:, :, None, None]
    return (_huber(gap, ctx.config.huber_delta) * weight).sum((1, 2, 3))


def _hand_contact_constants(ctx: EnergyContext) -> SimpleNamespace:
    """Hand-holding constants: index (B, N, H*2, 3) of each hand's partner among the (H*2) hands,
    weight (B, N, H, 2): the holding hands over their count; `any`: some hand holds one."""
    b, n, h = ctx.hand_partner.shape[:3]
    active = (ctx.hand_partner >= 0).to(ctx.kp2d.dtype)
    count = active.sum((1, 2, 3)).clamp_min(1.0)
    index = ctx.hand_partner.clamp_min(0).reshape(b, n, h * 2, 1).expand(b, n, h * 2, 3)
    return SimpleNamespace(index=index, weight=active / count[:, None, None, None], any=bool(active.any()))


def hand_contact_energy(motion: dict[str, Tensor], ctx: EnergyContext, occupancy: Tensor | None = None) -> Tensor:
    """Like contact_energy for a hand holding another person's hand (wrist to wrist). -> (B,)"""
    joints = motion["joints"]
    b, n, h = joints.shape[:3]
    c = _constants(ctx, _hand_contact_constants)
    if not c.any:
        return joints.new_zeros(b)
    hands = joints[:, :, :, _HAND_JOINTS]                                    # (B, N, H, 2, 3)
    partner = hands.reshape(b, n, h * 2, 3).gather(2, c.index).view(b, n, h, 2, 3)
    gap = (safe_norm(hands - partner) - ctx.config.hand_margin).clamp_min(0)
    weight = c.weight * _interaction_gate(occupancy, joints)[:, :, None, None]
    return (_huber(gap, ctx.config.huber_delta) * weight).sum((1, 2, 3))


def _spacing_constants(ctx: EnergyContext) -> SimpleNamespace:
    """Spacing constants: the pairs (P,) i < j of people, and weight (B, N): the frames without a
    storyboard contact over the number of (frame, pair) constraints."""
    h = ctx.contact.shape[2]
    i, j = _pairs(h, ctx.contact.device)
    free = (~ctx.contact.flatten(2).any(-1)).to(ctx.kp2d.dtype)             # (B, N)
    return SimpleNamespace(i=i, j=j, weight=free / (free.sum(1) * len(i)).clamp_min(1.0)[:, None])


def spacing_energy(motion: dict[str, Tensor], ctx: EnergyContext, occupancy: Tensor | None = None) -> Tensor:
    """max(0, d_min - horizontal pelvis distance)^2 for each pair of people on frames without a
    storyboard contact (weighted by the CTMC approach occupancy); per (frame, pair). -> (B,)"""
    joints = motion["joints"]
    b, n, h = joints.shape[:3]
    if h < 2:
        return joints.new_zeros(b)
    c = _constants(ctx, _spacing_constants)
    pelvis = joints[:, :, :, 0, ::2]                                         # (B, N, H, 2) x, z
    dist = safe_norm(pelvis.index_select(2, c.i) - pelvis.index_select(2, c.j))   # (B, N, P)
    crowd = (ctx.config.min_spacing - dist).clamp_min(0) ** 2
    weight = c.weight if occupancy is None else c.weight * occupancy[..., 0]
    return (crowd * weight[..., None]).sum((1, 2))


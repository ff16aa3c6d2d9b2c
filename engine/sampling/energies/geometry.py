"""Torch geometry for the energies: norms, the sketch camera, rotations, signed distances,
body spheres and soft closest-point distances to polylines (with their closed-form gradients)."""
from __future__ import annotations

import functools
from types import SimpleNamespace

import torch
from torch import Tensor

from ...body import BONES, SPHERE_RADII
from ...geometry.rotations_torch import safe_norm
from ...objects import ObjectSpec
from ...skeleton import NUM_JOINTS
from .context import _EPS, _TABLES, EnergyContext, _const


def project(points: Tensor, ctx: EnergyContext) -> Tensor:
    """World points (B, ..., 3) -> sketch-plane points (B, ..., 2) through the storyboard camera."""
    b = points.shape[0]
    flat = points.reshape(b, -1, 3) - ctx.cam_target[:, None]
    uv = torch.bmm(flat, ctx.camera[:, :2].transpose(1, 2))
    return uv.reshape(*points.shape[:-1], 2)


def _box_sdf(q: Tensor, half: Tensor) -> Tensor:
    """Signed distance to boxes centred at 0: q (..., 3), half (..., 3) broadcastable -> (...)."""
    d = q.abs() - half
    return safe_norm(d.clamp_min(0)) + d.max(-1).values.clamp_max(0)


def object_sdf(spec: ObjectSpec, p: Tensor) -> Tensor:
    """Signed distance (negative inside) of local points (..., 3) to the primitive -> (...).
    The torch twin of ObjectSpec.sdf_local (the tests check they agree)."""
    w, h, d = spec.size
    new = lambda *v: _const(tuple(float(x) for x in v), p)
    if spec.type == "box":
        return _box_sdf(p - new(0, h / 2, 0), new(w / 2, h / 2, d / 2))
    if spec.type == "canister":
        q = p - new(0, h / 2, 0)
        radial = safe_norm(q[..., [0, 2]]) - min(w, d) / 2
        vertical = q[..., 1].abs() - h / 2
        outside = safe_norm(torch.stack([radial.clamp_min(0), vertical.clamp_min(0)], -1))
        return outside + torch.maximum(radial, vertical).clamp_max(0)
    centres, halves = (tuple(map(tuple, a.tolist())) for a in spec.table_boxes())   # top plus four legs
    return _box_sdf(p[..., None, :] - _const(centres, p), _const(halves, p)).min(-1).values


_BONE_ENDS = torch.as_tensor(BONES, dtype=torch.long)                                   # (21, 2)
# sphere k is the midpoint of joints _SPHERE_ENDS[k] (a joint sphere: of itself and itself)
_SPHERE_ENDS = torch.cat([torch.arange(NUM_JOINTS)[:, None].expand(-1, 2), _BONE_ENDS])   # (43, 2)
_TABLES["sphere_radii"] = SPHERE_RADII


def body_points(joints: Tensor) -> tuple[Tensor, Tensor]:
    """The capsule proxy of a body as spheres: joints and bone midpoints (see metrics.BONES).
    joints (..., 22, 3) -> points (..., 43, 3), radii (43,)."""
    return _sphere_centres_all(joints), joints.new_tensor(SPHERE_RADII)


def _sphere_centres_all(joints: Tensor) -> Tensor:
    """body_points' points: joints (..., 22, 3) -> (..., 43, 3)."""
    parent, child = _BONE_ENDS.to(joints.device).unbind(1)
    mids = 0.5 * (joints.index_select(-2, parent) + joints.index_select(-2, child))
    return torch.cat([joints, mids], -2)


def _invalid_bias(valid: Tensor, dtype: torch.dtype) -> Tensor:
    """Logit offset that removes invalid entries from a softmax: 0 where valid, -1e9 elsewhere."""
    return -1e9 * (~valid).to(dtype)


def _softmin_weights(d2: Tensor, temperature: float, bias: Tensor | None = None) -> Tensor:
    """softmax(-d2 / temperature + bias) over the last axis, without gradient.

    The soft distances are the mean of d2 under these weights held constant: >= 0, the minimum
    when one entry is clearly smallest, and with the log-sum-exp softmin's gradient (a blend of
    pulls towards each entry), which does not jump where the nearest entry changes."""
    logits = d2.detach() / -temperature
    if bias is not None:
        logits = logits + bias
    # Weights below e^-50 of the largest are raised to that (2e-22, invisible in float32): this
    # keeps exp out of subnormal numbers, which make the softmax and its users ~5x slower on CPU.
    logits = logits.clamp_min(logits.amax(-1, keepdim=True) - 50.0)
    return torch.softmax(logits, -1)


class _SoftDistance(torch.autograd.Function):
    """Attaches its gradient to a soft squared distance computed without autograd.

    For value = sum_i w_i |q - c_i|^2 with the softmin weights w held constant (_softmin_weights)
    and c_i the closest point of candidate segment i, the gradient in q is
    2 sum_i w_i (q - c_i) = 2 pull: the closest point's own motion along its segment changes
    the distance only to second order (up to the eps in its parameter). Backward is then one
    op instead of the distance computation's dozen."""

    @staticmethod
    def forward(ctx, points: Tensor, value: Tensor, pull: Tensor) -> Tensor:
        """points (..., D) -> value (...), given pull (..., D)."""
        ctx.save_for_backward(pull)
        return value

    @staticmethod
    @torch.autograd.function.once_differentiable
    def backward(ctx, grad: Tensor):
        (pull,) = ctx.saved_tensors
        return 2 * grad[..., None] * pull, None, None


def _polyline_segments(polyline: Tensor) -> SimpleNamespace:
    """Constants of polylines (..., L, D), L >= 2, for _soft_polyline_sq_distance.

    Coordinates are taken relative to the polyline's first point (origin). For segment i with
    start a_i and direction s_i, and a point q, the three quantities the closest-point distance
    needs are affine in the features f = [q, 1, |q|^2]:
        |q - a_i|^2 = |q|^2 - 2 q.a_i + |a_i|^2
        -2 (q - a_i).s_i,    (q - a_i).s_i / (|s_i|^2 + eps)   (the unclamped closest-point parameter)
    so one matmul f @ basis, basis (..., D + 2, 3 (L-1)), gives all three for every segment;
    a, seg (..., L-1, D) serve the closest points."""
    origin = polyline[..., :1, :]
    poly = polyline - origin
    a, seg = poly[..., :-1, :], poly[..., 1:, :] - poly[..., :-1, :]           # (..., L-1, D)
    a_seg, seg_sq = (a * seg).sum(-1), (seg * seg).sum(-1)                   # (..., L-1)
    den = seg_sq + _EPS
    ones, zeros = torch.ones_like(a_seg), torch.zeros_like(a_seg)
    rows = [torch.cat([-2 * a[..., k], -2 * seg[..., k], seg[..., k] / den], -1) for k in range(a.shape[-1])]
    rows.append(torch.cat([(a * a).sum(-1), 2 * a_seg, -a_seg / den], -1))  # the constant feature 1
    rows.append(torch.cat([ones, zeros, zeros], -1))                         # the feature |q|^2
    return SimpleNamespace(origin=origin, basis=torch.stack(rows, -2), seg_sq=seg_sq[..., None, :],
                           segments=a.shape[-2], a=a, seg=seg)


def _soft_polyline_sq_distance(points: Tensor, poly: SimpleNamespace, temperature: float) -> Tensor:
    """Soft squared closest-point distance of points (..., P, D) to the polylines whose
    constants are `poly` (_polyline_segments) -> (..., P); see soft_polyline_sq_distance."""
    with torch.no_grad():
        q = points - poly.origin
        features = torch.cat([q, torch.ones_like(q[..., :1]), (q * q).sum(-1, keepdim=True)], -1)
        rel2, minus_2rs, t = (features @ poly.basis).split(poly.segments, -1)   # each (..., P, L-1)
        t = t.clamp(0, 1)
        # |q - a - t s|^2 = |q - a|^2 + t (t |s|^2 - 2 (q - a).s), as two fused multiply-adds
        d2 = torch.addcmul(rel2, t, torch.addcmul(minus_2rs, t, poly.seg_sq)).clamp_min(0)
        w = _softmin_weights(d2, temperature)
        value, pull = (w * d2).sum(-1), q - (w @ poly.a + (w * t) @ poly.seg)   # sum_i w_i (q - c_i)
    return _SoftDistance.apply(points, value, pull)


def soft_polyline_sq_distance(points: Tensor, polyline: Tensor, temperature: float) -> Tensor:
    """Soft squared closest-point distance of points (..., P, D) to a polyline (..., L, D),
    L >= 2 -> (..., P): the softmin (_softmin_weights) over the polyline's segments.

    Written with matrix products so that no (P, L, D) tensor is formed (the energies' hot spot);
    coordinates are taken relative to the polyline's first point to keep the expansion exact."""
    return _soft_polyline_sq_distance(points, _polyline_segments(polyline), temperature)


def _soft_segments_sq_distance(points: Tensor, a: Tensor, seg: Tensor, seg_sq: Tensor,
                               temperature: float, bias: Tensor | None = None) -> Tensor:
    """Soft squared distance (_softmin_weights) of points (..., D) to their own K candidate segments
    a + [0, 1] seg -> (...). The segments come coordinate-first, a and seg (D, ..., K): sums
    over a short last axis are slow on CPU, sums of D slabs are not. seg_sq = |seg|^2 + eps
    (..., K); bias: the softmax's logit offset (..., K), or None."""
    with torch.no_grad():
        rel = points.detach().movedim(-1, 0).contiguous()[..., None] - a     # (D, ..., K)
        t = ((rel * seg).sum(0) / seg_sq).clamp(0, 1)
        diff = torch.addcmul(rel, t, seg, value=-1)                         # q - c_i = rel - t seg
        d2 = (diff * diff).sum(0)
        w = _softmin_weights(d2, temperature, bias)
        value, pull = (w * d2).sum(-1), (w * diff).sum(-1).movedim(0, -1)   # pull (..., D)
    return _SoftDistance.apply(points, value, pull)


def _per_constraint(total: Tensor, count: Tensor) -> Tensor:
    """Sum over constraints -> mean per constraint; 0 where there is none."""
    return total / count.clamp_min(1.0)


def _huber(x: Tensor, delta: float) -> Tensor:
    """Huber loss of x >= 0 (gaps): 0.5 x^2 below delta, delta (x - 0.5 delta) above, written
    as m (x - 0.5 m) with m = min(x, delta) (the same values, in four ops instead of six)."""
    m = x.clamp_max(delta)
    return m * (x - 0.5 * m)


@functools.lru_cache(maxsize=16)
def _pairs(h: int, device: torch.device) -> tuple[Tensor, Tensor]:
    """The index pairs i < j of h people, (P,) each."""
    return tuple(torch.triu_indices(h, h, 1, device=device))

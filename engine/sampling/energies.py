"""Differentiable guidance energies on decoded motion (paper section 3.3), and their schedule.

Every energy is `(motion, ctx) -> (B,)` where `motion` is the decoder's dict
    joints (B, N, H, 22, 3)  rot6d (B, N, H, 22, 6)  obj_pose (B, N, O, 7)  obj_anchors (B, N, O, K, 3)
and `ctx` an EnergyContext. Each value is a mean over that energy's active constraints (so that
doubling the constraints does not change it), 0 when none is active, never NaN, and its gradient
is finite everywhere (norms are taken with a small epsilon, soft gates carry no gradient).
Units: metres (world and sketch plane), seconds for speeds; squared errors unless stated.

Speed: the sampler evaluates value + gradient about 26 times per generation on small tensors, so
the cost is mostly the number of torch ops (forward and backward), not flops. Hence:
everything that depends only on the storyboard (index tensors, masks, targets, gates,
normalisers) is built once per context (`_constants`); each energy's per-call part is a short
chain of batched ops without Python loops over people, strokes or keys; the soft closest-point
distances run without autograd and attach their closed-form gradient (`_SoftDistance`);
penetration searches its candidate pairs without autograd; and sums over xyz of big tensors are
taken coordinate-first (a reduction over a last axis of 2 or 3 is slow on CPU).

`total_energy` sums the enabled terms with base weights times a schedule over solver time
t in [0, 1] (t = 1 noise, t = 0 data): keyframe-like terms early, interaction mid, physics late.
"""
from __future__ import annotations

import functools
import math
import weakref
from dataclasses import dataclass, field, fields
from types import SimpleNamespace
from typing import Callable

import numpy as np
import torch
from torch import Tensor

from ..controls import build_controls, resample_polyline
from ..metrics import BONES, JOINT_RADII
from ..objects import ObjectSpec
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
    traj_weight_3d: float = 2.0       # the lifted path pins depth, which the 2D term cannot
    traj_weight_2d: float = 1.0
    softmin_temperature: float = 0.05 ** 2   # m^2; soft closest-point temperature on squared distance
    proxy_window: int = 24            # frames searched on the lifted 3D path around each frame: the
                                      # lift's timing is loose, its path is not (8 frames: T3D +0.3 cm)
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


@dataclass(eq=False)  # compared by identity: it keys the cache of its constants (_constants)
class EnergyContext:
    """Everything the energies read besides the motion, batched over B (the K variations).

    Control tensors follow engine/controls.py with a leading batch dimension. Trajectory strokes
    are the storyboard's polylines, padded by repeating their last point (a zero-length segment
    adds nothing to a closest-point distance), S strokes of L points.

    All fields are constants to the energies (no gradient reaches them). The energies cache what
    they derive from the fields other than `occupancy` (which they read at each call, as the
    sampler re-plans it); replacing a field, editing a tensor in place or changing the config
    rebuilds that cache.
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


# ---- per-context constants ----------------------------------------------------------------------

# The fields whose values the constants may read: all but the occupancy, which the sampler
# re-plans during a generation (the energies read it per call).
_CONSTANT_FIELDS = tuple(f.name for f in fields(EnergyContext) if f.name != "occupancy")
# context -> {builder: (key, constants, the fields they were built from)}; weak, so that the
# constants go with their context
_CACHE: weakref.WeakKeyDictionary[EnergyContext, dict] = weakref.WeakKeyDictionary()


def _context_key(ctx: EnergyContext) -> tuple:
    """What the cached constants were built from: tensors by identity and version (so replacing
    a field or editing it in place both show), the config by value, anything else by identity."""
    key = []
    for name in _CONSTANT_FIELDS:
        v = getattr(ctx, name)
        if isinstance(v, Tensor):
            key.append((id(v), v._version))
        elif isinstance(v, EnergyConfig):
            key.append(tuple(vars(v).values()))
        else:
            key.append(id(v))
    return tuple(key)


def _constants(ctx: EnergyContext, build: Callable[[EnergyContext], SimpleNamespace]) -> SimpleNamespace:
    """build(ctx), the storyboard-only part of one energy, cached on the context until a field
    it may read changes. Built without autograd: constants carry no gradient."""
    key = _context_key(ctx)
    cache = _CACHE.setdefault(ctx, {})
    entry = cache.get(build)
    if entry is None or entry[0] != key:
        with torch.no_grad():
            # holding the fields keeps their ids from being reused while the entry lives
            entry = (key, build(ctx), [getattr(ctx, name) for name in _CONSTANT_FIELDS])
        cache[build] = entry
    return entry[1]


def _joint_slice(indices: tuple[int, ...]) -> slice | list[int]:
    """A slice (a view, no copy and no index op) when the joints are consecutive."""
    consecutive = list(indices) == list(range(indices[0], indices[0] + len(indices)))
    return slice(indices[0], indices[0] + len(indices)) if consecutive else list(indices)


_HAND_JOINTS = _joint_slice(HANDS)
_FOOT_JOINTS = _joint_slice(FEET)


def _const(values: tuple | str, like: Tensor) -> Tensor:
    """A constant as a tensor with like's dtype and device, made once: building a small tensor
    from Python costs more than most of the ops that use it. `values` is a tuple of numbers
    (nested for more axes) or the name of a module table in _TABLES. The tensor is shared:
    never modify it in place."""
    return _const_tensor(values, like.dtype, like.device)


@functools.lru_cache(maxsize=256)
def _const_tensor(values: tuple | str, dtype: torch.dtype, device: torch.device) -> Tensor:
    return torch.as_tensor(_TABLES[values] if isinstance(values, str) else values, dtype=dtype, device=device)


_TABLES: dict[str, np.ndarray] = {}   # filled below, next to their users


# ---- geometry helpers ---------------------------------------------------------------------

def safe_norm(v: Tensor) -> Tensor:
    """Euclidean norm over the last axis with a finite gradient at 0. (..., D) -> (...)."""
    return torch.sqrt(torch.linalg.vecdot(v, v) + _EPS)


def project(points: Tensor, ctx: EnergyContext) -> Tensor:
    """World points (B, ..., 3) -> sketch-plane points (B, ..., 2) through the storyboard camera."""
    b = points.shape[0]
    flat = points.reshape(b, -1, 3) - ctx.cam_target[:, None]
    uv = torch.bmm(flat, ctx.camera[:, :2].transpose(1, 2))
    return uv.reshape(*points.shape[:-1], 2)


def _quat_product_table() -> np.ndarray:
    """(16, 9): R - I = 2 * (q q^T).flatten() @ table for a unit quaternion q = (w, x, y, z);
    row 4a + b holds the sign of the product q_a q_b in each entry of the textbook formula."""
    entries = {(0, 0): "-yy -zz", (0, 1): "+xy -wz", (0, 2): "+xz +wy",
               (1, 0): "+xy +wz", (1, 1): "-xx -zz", (1, 2): "+yz -wx",
               (2, 0): "+xz -wy", (2, 1): "+yz +wx", (2, 2): "-xx -yy"}
    table = np.zeros((16, 9))
    for (row, col), terms in entries.items():
        for sign, a, b in terms.split():
            table[4 * "wxyz".index(a) + "wxyz".index(b), 3 * row + col] = 1.0 if sign == "+" else -1.0
    return table


_TABLES["quat"], _TABLES["eye3"] = _quat_product_table(), np.eye(3).ravel()


def quat_to_matrix(q: Tensor) -> Tensor:
    """(..., 4) wxyz, normalised here -> (..., 3, 3).
    One matmul over the outer product instead of nine expressions (a few ops instead of ~40);
    each entry is the same two-product sum, so the values are the formula's."""
    q = q / safe_norm(q)[..., None]
    products = (q[..., :, None] * q[..., None, :]).flatten(-2)               # (..., 16)
    r = 2 * (products @ _const("quat", q)) + _const("eye3", q)
    return r.reshape(*q.shape[:-1], 3, 3)


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


_SPHERE_RADII = np.concatenate([JOINT_RADII, 0.5 * (JOINT_RADII[BONES[:, 0]] + JOINT_RADII[BONES[:, 1]])])
_BONE_ENDS = torch.as_tensor(BONES, dtype=torch.long)                                   # (21, 2)
# sphere k is the midpoint of joints _SPHERE_ENDS[k] (a joint sphere: of itself and itself)
_SPHERE_ENDS = torch.cat([torch.arange(NUM_JOINTS)[:, None].expand(-1, 2), _BONE_ENDS])   # (43, 2)
_TABLES["sphere_radii"] = _SPHERE_RADII


def body_points(joints: Tensor) -> tuple[Tensor, Tensor]:
    """The capsule proxy of a body as spheres: joints and bone midpoints (see metrics.BONES).
    joints (..., 22, 3) -> points (..., 43, 3), radii (43,)."""
    return _sphere_centres_all(joints), joints.new_tensor(_SPHERE_RADII)


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
        if y.shape[1] > 1:  # forward difference, the last frame repeating the one before
            dy = y[:, 1:] - y[:, :-1]
            vy = torch.cat([dy, dy[:, -1:]], 1) * fps
        else:
            vy = torch.zeros_like(y)
        low = torch.sigmoid((cfg.stance_height - height) / cfg.stance_height_softness)
        still = torch.sigmoid((cfg.stance_speed - vy.abs()) / cfg.stance_speed_softness)
        return low * still


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


def keyframe_energy(motion: dict[str, Tensor], ctx: EnergyContext) -> Tensor:
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


def trajectory_energy(motion: dict[str, Tensor], ctx: EnergyContext) -> Tensor:
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
    when nothing constrains an object, half_height (O, 1): the object centre above its pose."""
    key, path = ctx.obj_mask.to(ctx.obj2d.dtype), ctx.objpath_mask.to(ctx.obj2d.dtype)
    weights = torch.stack([key, path], -1)
    count = weights.sum((1, 2, 3))
    return SimpleNamespace(targets=torch.stack([ctx.obj2d[..., :2], ctx.objpath2d], -2),
                           weights=(weights / count.clamp_min(1.0)[:, None, None, None])[..., None],
                           any=bool(count.any()),
                           half_height=ctx.obj2d.new_tensor([[spec.size[1] / 2] for spec in ctx.objects]))


def object_energy(motion: dict[str, Tensor], ctx: EnergyContext) -> Tensor:
    """Projected object centre (the middle of its bounding box) vs the sketched silhouette's
    centre at object keys and vs the object path on its frames; per constrained (frame, object).
    -> (B,)"""
    pose = motion.get("obj_pose")
    b = motion["joints"].shape[0]
    if pose is None or not ctx.objects:
        return motion["joints"].new_zeros(b)
    c = _constants(ctx, _object_constants)
    if not c.any:
        return motion["joints"].new_zeros(b)
    up = quat_to_matrix(pose[..., 3:])[..., 1]                              # (B, N, O, 3) rotated y axis
    uv = project(torch.addcmul(pose[..., :3], up, c.half_height), ctx)      # (B, N, O, 2)
    err = uv[..., None, :] - c.targets                                      # (B, N, O, 2, 2)
    return (err * err * c.weights).sum((1, 2, 3, 4))


def _contact_constants(ctx: EnergyContext) -> SimpleNamespace:
    """Contact constants: index (B, N, H*2, 3) of each hand's anchor in anchors.reshape(B, N, -1, 3),
    weight (B, N, H, 2): the active hands over their count; `any`: some hand is active."""
    b, n, h = ctx.contact.shape[:3]
    active = (ctx.contact & (ctx.contact_anchor >= 0)).to(ctx.kp2d.dtype)   # (B, N, H, 2)
    count = active.sum((1, 2, 3)).clamp_min(1.0)
    index = ctx.contact_anchor.clamp_min(0).reshape(b, n, h * 2, 1).expand(b, n, h * 2, 3)
    return SimpleNamespace(index=index, weight=active / count[:, None, None, None], any=bool(active.any()))


def contact_energy(motion: dict[str, Tensor], ctx: EnergyContext) -> Tensor:
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
    weight = c.weight * _interaction_gate(ctx, joints)[:, :, None, None]
    return (_huber(gap, ctx.config.huber_delta) * weight).sum((1, 2, 3))


def _hand_contact_constants(ctx: EnergyContext) -> SimpleNamespace:
    """Hand-holding constants: index (B, N, H*2, 3) of each hand's partner among the (H*2) hands,
    weight (B, N, H, 2): the holding hands over their count; `any`: some hand holds one."""
    b, n, h = ctx.hand_partner.shape[:3]
    active = (ctx.hand_partner >= 0).to(ctx.kp2d.dtype)
    count = active.sum((1, 2, 3)).clamp_min(1.0)
    index = ctx.hand_partner.clamp_min(0).reshape(b, n, h * 2, 1).expand(b, n, h * 2, 3)
    return SimpleNamespace(index=index, weight=active / count[:, None, None, None], any=bool(active.any()))


def hand_contact_energy(motion: dict[str, Tensor], ctx: EnergyContext) -> Tensor:
    """Like contact_energy for a hand holding another person's hand (wrist to wrist). -> (B,)"""
    joints = motion["joints"]
    b, n, h = joints.shape[:3]
    c = _constants(ctx, _hand_contact_constants)
    if not c.any:
        return joints.new_zeros(b)
    hands = joints[:, :, :, _HAND_JOINTS]                                    # (B, N, H, 2, 3)
    partner = hands.reshape(b, n, h * 2, 3).gather(2, c.index).view(b, n, h, 2, 3)
    gap = (safe_norm(hands - partner) - ctx.config.hand_margin).clamp_min(0)
    weight = c.weight * _interaction_gate(ctx, joints)[:, :, None, None]
    return (_huber(gap, ctx.config.huber_delta) * weight).sum((1, 2, 3))


def _spacing_constants(ctx: EnergyContext) -> SimpleNamespace:
    """Spacing constants: the pairs (P,) i < j of people, and weight (B, N): the frames without a
    storyboard contact over the number of (frame, pair) constraints."""
    h = ctx.contact.shape[2]
    i, j = _pairs(h, ctx.contact.device)
    free = (~ctx.contact.flatten(2).any(-1)).to(ctx.kp2d.dtype)             # (B, N)
    return SimpleNamespace(i=i, j=j, weight=free / (free.sum(1) * len(i)).clamp_min(1.0)[:, None])


def spacing_energy(motion: dict[str, Tensor], ctx: EnergyContext) -> Tensor:
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
    weight = c.weight if ctx.occupancy is None else c.weight * ctx.occupancy[..., 0]
    return (crowd * weight[..., None]).sum((1, 2))


def foot_skate_energy(motion: dict[str, Tensor], ctx: EnergyContext) -> Tensor:
    """Squared horizontal foot speed (m/s)^2 weighted by the soft stance of the foot; normalised
    by the total stance weight. -> (B,)"""
    feet = motion["joints"][:, :, :, _FOOT_JOINTS]                          # (B, N, H, 2, 3)
    if feet.shape[1] < 2:
        return feet.new_zeros(feet.shape[0])
    stance = _stance(feet, ctx.fps, ctx.config)[:, :-1]
    vel = (feet[:, 1:, ..., ::2] - feet[:, :-1, ..., ::2]) * ctx.fps         # x, z
    return _per_constraint((vel * vel * stance[..., None]).sum((1, 2, 3, 4)), stance.sum((1, 2, 3)))


def ground_energy(motion: dict[str, Tensor], ctx: EnergyContext) -> Tensor:
    """Depth^2 of joints below the ground (per joint below) + (foot height - standing height)^2
    of feet in stance (per unit stance weight). -> (B,)"""
    joints = motion["joints"]
    below = joints[..., 1].clamp_max(0)                                      # -depth (B, N, H, J)
    count = (below.detach() < 0).sum((1, 2, 3)).to(joints.dtype)
    sunk = _per_constraint((below * below).sum((1, 2, 3)), count)
    feet = joints[:, :, :, _FOOT_JOINTS]
    stance = _stance(feet, ctx.fps, ctx.config)
    lift = (feet[..., 1] - ctx.config.foot_height) ** 2
    return sunk + _per_constraint((lift * stance).sum((1, 2, 3)), stance.sum((1, 2, 3)))


def smoothness_energy(motion: dict[str, Tensor], ctx: EnergyContext) -> Tensor:
    """Mean squared second difference (per frame^2) of joint positions, plus that of the 6D
    rotations times rot_smooth_weight. -> (B,)"""
    def accel(x: Tensor) -> Tensor:
        if x.shape[1] < 3:
            return x.new_zeros(x.shape[0])
        a = torch.add(x[:, 2:], x[:, 1:-1], alpha=-2) + x[:, :-2]            # x'' per frame^2
        return (a * a).sum(tuple(range(1, a.dim()))) * (x.shape[-1] * a.shape[0] / a.numel())   # mean |x''|^2

    out = accel(motion["joints"])
    if "rot6d" in motion:
        out = out + ctx.config.rot_smooth_weight * accel(motion["rot6d"])
    return out


_PENETRATION_SLACK = 1e-4   # m; candidate search tolerance, so that the exact depth decides
_TABLES["sphere_pair_reach"] = (_SPHERE_RADII[:, None] + _SPHERE_RADII[None] + _PENETRATION_SLACK) ** 2


def _object_candidates(coords: Tensor, pose: Tensor, o: int, spec: ObjectSpec) -> Tensor:
    """Flat indices (M,) into (B, N, H, P) of the body spheres that may reach object o: their
    centres come within their radius of a ball holding the primitive (centred at the pose's
    origin, its base centre, so no rotation is needed). coords (3, B, N, H, P): the sphere
    centres coordinate-first; pose (B, N, O, 7). No gradient."""
    w, height, d = spec.size
    ball = math.sqrt((w / 2) ** 2 + height ** 2 + (d / 2) ** 2)           # the primitive spans y in [0, h]
    reach = (_const("sphere_radii", coords) + (ball + _PENETRATION_SLACK)) ** 2   # (P,)
    centre = pose[:, :, o, :3].detach().movedim(-1, 0).contiguous()[..., None, None]   # (3, B, N, 1, 1)
    return (((coords - centre) ** 2).sum(0) < reach).flatten().nonzero()[:, 0]


def _object_depth(centres: Tensor, sphere: Tensor, pose: Tensor, o: int, spec: ObjectSpec,
                  shape: tuple[int, ...]) -> Tensor:
    """Depth (M,) inside object o (<= 0: outside) of the spheres with flat index sphere (M,)
    into shape = (B, N, H, P) and centres (M, 3); differentiable in centres and pose (B, N, O, 7)."""
    b, n, h, p = shape
    at = pose[:, :, o].reshape(-1, 7).index_select(0, sphere // (h * p))    # (M, 7) at its frame
    local = ((centres - at[:, :3])[:, None] @ quat_to_matrix(at[:, 3:]))[:, 0]
    return _const("sphere_radii", centres)[sphere % p] - object_sdf(spec, local)


@functools.lru_cache(maxsize=16)
def _pairs(h: int, device: torch.device) -> tuple[Tensor, Tensor]:
    """The index pairs i < j of h people, (P,) each."""
    return tuple(torch.triu_indices(h, h, 1, device=device))


def _people_candidates(coords: Tensor) -> tuple[Tensor, Tensor]:
    """Flat indices (M,), (M,) into (B, N, H, P) of the sphere pairs of two different people that
    may overlap: first the frames where two people's bounding boxes come within twice the
    largest radius, then the sphere pairs there. coords (3, B, N, H, P) as in
    _object_candidates. No gradient."""
    _, b, n, h, p = coords.shape
    i, j = _pairs(h, coords.device)
    lo, hi = coords.amin(-1), coords.amax(-1)                                # (3, B, N, H)
    lo_i, lo_j, hi_i, hi_j = (x.index_select(-1, k) for x in (lo, hi) for k in (i, j))
    apart = torch.maximum(lo_i - hi_j, lo_j - hi_i).amax(0)                 # (B, N, pairs)
    bi, ni, pair = (apart < 2 * float(_SPHERE_RADII.max()) + _PENETRATION_SLACK).nonzero(as_tuple=True)
    if not len(bi):
        return bi, bi
    people = coords.reshape(3, b * n * h, p)
    first = (bi * n + ni) * h                                                # flat index of person 0
    side_a, side_b = people[:, first + i[pair]], people[:, first + j[pair]]   # (3, F, P)
    d2 = ((side_a[..., :, None] - side_b[..., None, :]) ** 2).sum(0)        # (F, P, P)
    fi, ka, kb = (d2 < _const("sphere_pair_reach", d2)).nonzero(as_tuple=True)
    if not len(fi):
        return fi, fi
    return (first[fi] + i[pair[fi]]) * p + ka, (first[fi] + j[pair[fi]]) * p + kb


def _sphere_centres(joints: Tensor, sphere: Tensor) -> Tensor:
    """Centres (M, 3) of the spheres with flat index `sphere` (M,) into (B, N, H, P), from their
    two joints (B, N, H, 22, 3): autograd sees M points, not every sphere of every frame."""
    p = len(_SPHERE_RADII)
    rows = (sphere // p)[:, None] * NUM_JOINTS + _SPHERE_ENDS.to(sphere.device)[sphere % p]   # (M, 2)
    return 0.5 * joints.reshape(-1, 3).index_select(0, rows.flatten()).view(-1, 2, 3).sum(1)


def _cat(tensors: list[Tensor]) -> Tensor:
    """torch.cat, without a copy (and a graph node) for a single tensor."""
    return tensors[0] if len(tensors) == 1 else torch.cat(tensors)


def penetration_energy(motion: dict[str, Tensor], ctx: EnergyContext) -> Tensor:
    """Depth^2 of the body's capsule spheres inside objects (analytic SDF at the object's pose)
    and inside the other people's spheres; per penetrating (sphere, obstacle). -> (B,)

    Candidate pairs are found without autograd first (conservatively: the exact depth decides);
    only those get a differentiable depth, which keeps the cost independent of the (mostly
    empty) pair count."""
    joints = motion["joints"]
    b, n, h = joints.shape[:3]
    shape = (b, n, h, len(_SPHERE_RADII))
    pose = motion.get("obj_pose")
    objects = ctx.objects if pose is not None else ()
    with torch.no_grad():  # the search sums over xyz: fast coordinate-first, slow coordinate-last
        coords = _sphere_centres_all(joints).movedim(-1, 0).contiguous()     # (3, B, N, H, P)
        found = [_object_candidates(coords, pose, o, spec) for o, spec in enumerate(objects)]
        none = torch.zeros(0, dtype=torch.long, device=joints.device)
        side_a, side_b = _people_candidates(coords) if h > 1 else (none, none)
    depth, owner = [], []
    for o, (spec, sphere) in enumerate(zip(objects, found)):
        if len(sphere):
            depth.append(_object_depth(_sphere_centres(joints, sphere), sphere, pose, o, spec, shape))
            owner.append(sphere)
    if len(side_a):
        radii = _const("sphere_radii", joints)
        centres = _sphere_centres(joints, torch.cat([side_a, side_b])).view(2, -1, 3)
        depth.append(radii[side_a % shape[3]] + radii[side_b % shape[3]] - safe_norm(centres[0] - centres[1]))
        owner.append(side_a)
    if not depth:
        return joints.new_zeros(b)
    depth = _cat(depth).clamp_min(0)
    owner = _cat(owner) // (n * h * shape[3])                                # batch index of each
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
    terms = {}
    for name in names:
        if lam[name] != 0:
            terms[name] = ENERGIES[name](motion, ctx)
        else:  # reported, but no graph to build
            with torch.no_grad():
                terms[name] = ENERGIES[name](motion, ctx)
    if not terms:
        return motion["joints"].new_zeros(motion["joints"].shape[0]), terms
    stacked = torch.stack(list(terms.values()), -1)                          # (B, R)
    return stacked @ stacked.new_tensor([lam[name] for name in terms]), terms   # one op, not 2R

"""The physics terms: feet that stand still and on the ground, smooth motion, no interpenetration
of people and objects. Penetration searches its candidate sphere pairs without autograd."""
from __future__ import annotations

import math

import torch
from torch import Tensor

from ...body import SPHERE_RADII
from ...geometry.rotations_torch import quat_to_matrix, safe_norm
from ...objects import ObjectSpec
from ...skeleton import NUM_JOINTS
from .context import _FOOT_JOINTS, _TABLES, EnergyConfig, EnergyContext, _const
from .geometry import _SPHERE_ENDS, _pairs, _per_constraint, _sphere_centres_all, object_sdf


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


def foot_skate_energy(motion: dict[str, Tensor], ctx: EnergyContext, occupancy: Tensor | None = None) -> Tensor:
    """Squared horizontal foot speed (m/s)^2 weighted by the soft stance of the foot; normalised
    by the total stance weight. -> (B,)"""
    feet = motion["joints"][:, :, :, _FOOT_JOINTS]                          # (B, N, H, 2, 3)
    if feet.shape[1] < 2:
        return feet.new_zeros(feet.shape[0])
    stance = _stance(feet, ctx.fps, ctx.config)[:, :-1]
    vel = (feet[:, 1:, ..., ::2] - feet[:, :-1, ..., ::2]) * ctx.fps         # x, z
    return _per_constraint((vel * vel * stance[..., None]).sum((1, 2, 3, 4)), stance.sum((1, 2, 3)))


def ground_energy(motion: dict[str, Tensor], ctx: EnergyContext, occupancy: Tensor | None = None) -> Tensor:
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


def smoothness_energy(motion: dict[str, Tensor], ctx: EnergyContext, occupancy: Tensor | None = None) -> Tensor:
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
_TABLES["sphere_pair_reach"] = (SPHERE_RADII[:, None] + SPHERE_RADII[None] + _PENETRATION_SLACK) ** 2


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
    bi, ni, pair = (apart < 2 * float(SPHERE_RADII.max()) + _PENETRATION_SLACK).nonzero(as_tuple=True)
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
    p = len(SPHERE_RADII)
    rows = (sphere // p)[:, None] * NUM_JOINTS + _SPHERE_ENDS.to(sphere.device)[sphere % p]   # (M, 2)
    return 0.5 * joints.reshape(-1, 3).index_select(0, rows.flatten()).view(-1, 2, 3).sum(1)


def _cat(tensors: list[Tensor]) -> Tensor:
    """torch.cat, without a copy (and a graph node) for a single tensor."""
    return tensors[0] if len(tensors) == 1 else torch.cat(tensors)


def penetration_energy(motion: dict[str, Tensor], ctx: EnergyContext, occupancy: Tensor | None = None) -> Tensor:
    """Depth^2 of the body's capsule spheres inside objects (analytic SDF at the object's pose)
    and inside the other people's spheres; per penetrating (sphere, obstacle). -> (B,)

    Candidate pairs are found without autograd first (conservatively: the exact depth decides);
    only those get a differentiable depth, which keeps the cost independent of the (mostly
    empty) pair count."""
    joints = motion["joints"]
    b, n, h = joints.shape[:3]
    shape = (b, n, h, len(SPHERE_RADII))
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


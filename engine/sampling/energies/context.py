"""The energies' context: what they read besides the motion, built once per storyboard.

Every energy is `(motion, ctx, occupancy) -> (B,)` where `motion` is the decoder's dict
    joints (B, N, H, 22, 3)  rot6d (B, N, H, 22, 6)  obj_pose (B, N, O, 7)  obj_anchors (B, N, O, K, 3)
`ctx` an EnergyContext and `occupancy` (B, N, 3) the CTMC planner's current approach / contact /
carry phases, or None (no planner). See engine.sampling.energies for the list and their sum.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass, field, fields
from types import SimpleNamespace
from typing import Callable

import numpy as np
import torch
from torch import Tensor

from ...controls import Controls, build_controls
from ...geometry.polylines import resample_polyline
from ...objects import ObjectSpec
from ...skeleton import FEET, HANDS, JOINT_INDEX, NUM_JOINTS
from ...storyboard import HANDS as HAND_NAMES
from ...storyboard import Storyboard

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


@dataclass(eq=False)  # compared by identity: it owns the cache of its constants (_constants)
class EnergyContext:
    """Everything the energies read besides the motion, batched over B (the K variations).

    Control tensors follow engine/controls.py with a leading batch dimension. Trajectory strokes
    are the storyboard's polylines, padded by repeating their last point (a zero-length segment
    adds nothing to a closest-point distance), S strokes of L points.

    All fields are constants to the energies (no gradient reaches them). The energies cache what
    they derive from them on the context itself; replacing a field, editing a tensor in place or
    changing the config rebuilds that cache. What changes during a generation (the CTMC
    occupancy) is not here: the sampler passes it with each call.
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
        (K3D_hat, T3D_hat, quality gates, config) as given."""
        return cls.from_controls(sb, build_controls(sb), batch, max_stroke_points=max_stroke_points, dtype=dtype,
                                 device=device, **extra)

    @classmethod
    def from_controls(cls, sb: Storyboard, c: Controls, batch: int = 1, *, max_stroke_points: int = 64,
                      dtype: torch.dtype = torch.float32, device: str | torch.device = "cpu",
                      **extra) -> "EnergyContext":
        """The same, from the storyboard's controls when the caller has them already (the sampler
        builds them once for the network and the energies alike)."""
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

_CONSTANT_FIELDS = tuple(f.name for f in fields(EnergyContext))


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
    cache = ctx.__dict__.setdefault("_constants", {})   # builder -> (key, constants, the fields read)
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


"""Guidance energies: known values on hand-made scenes, normalisation, finite gradients that
descend, the schedule's shape, and a timing print."""
from dataclasses import fields

import numpy as np
import pytest
import torch

from engine.objects import ObjectSpec
from engine.sampling import energies as E
from engine.sampling.energies.context import _EPS
from engine.sampling.energies.geometry import _invalid_bias, _soft_segments_sq_distance
from engine.skeleton import FEET, HANDS, JOINT_INDEX, rest_pose
from engine.storyboard import Agent, Contact, Keypose, ObjectKey, ObjectPath, SceneObject, Storyboard, Trajectory

torch.set_num_threads(1)
N = 40
WRIST = JOINT_INDEX["l_wrist"]


def storyboard(**kw) -> Storyboard:
    sb = Storyboard(length=N, agents=[Agent("a"), Agent("b")],
                    objects=[SceneObject("box", ObjectSpec("box"))])
    for name, items in kw.items():
        getattr(sb, name).extend(items)
    return sb


def motion(apart: float = 1.5, box_at=(0.0, 0.0, 3.0)) -> dict[str, torch.Tensor]:
    """Two people standing in rest pose `apart` metres apart along x, a box at `box_at`."""
    joints = torch.tensor(rest_pose(), dtype=torch.float64)[None, None, None].repeat(1, N, 2, 1, 1)
    joints[:, :, 1, :, 0] += apart
    pose = torch.zeros(1, N, 1, 7, dtype=torch.float64)
    pose[..., :3] = torch.tensor(box_at, dtype=torch.float64)
    pose[..., 3] = 1.0
    spec = ObjectSpec("box")
    anchors = torch.tensor(spec.anchors, dtype=torch.float64) + pose[..., None, :3]
    return {"joints": joints, "rot6d": torch.zeros(1, N, 2, 22, 6, dtype=torch.float64),
            "obj_pose": pose, "obj_anchors": anchors}


def context(sb: Storyboard, **kw) -> E.EnergyContext:
    return E.EnergyContext.from_storyboard(sb, dtype=torch.float64, **kw)


def keypose(m, frame: int, agent: int, joints: list[int], offset=(0.0, 0.0), camera=None):
    """A keypose that matches the motion's projection except for `offset` (sketch metres)."""
    cam = (camera or Storyboard().camera)
    pts = cam.project(m["joints"][0, frame, agent].numpy()) + np.asarray(offset)
    mask = np.zeros(22, bool)
    mask[joints] = True
    return Keypose("ab"[agent], frame, pts, mask)


# ---- geometry ---------------------------------------------------------------------------------

@pytest.mark.parametrize("kind", ["box", "table", "canister"])
def test_torch_sdf_matches_numpy(kind):
    spec = ObjectSpec(kind)
    p = np.random.default_rng(0).uniform(-1, 1.5, (500, 3))
    got = E.object_sdf(spec, torch.tensor(p)).numpy()
    np.testing.assert_allclose(got, spec.sdf_local(p), atol=1e-5)


def test_soft_polyline_distance_exact_on_straight_line():
    poly = torch.tensor([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]], dtype=torch.float64)
    for d in (0.0, 0.05, 0.3):
        pt = torch.tensor([[0.7, d]], dtype=torch.float64)
        got = E.soft_polyline_sq_distance(pt, poly, temperature=1e-4)
        assert float(got) == pytest.approx(d * d, abs=1e-9)


def test_soft_polyline_matches_brute_force_closest_point():
    rng = np.random.default_rng(1)
    poly, pts = rng.normal(size=(6, 2)), rng.normal(size=(50, 2))
    got = E.soft_polyline_sq_distance(torch.tensor(pts), torch.tensor(poly), temperature=1e-9).numpy()
    dense = np.concatenate([a + np.linspace(0, 1, 4001)[:, None] * (b - a) for a, b in zip(poly[:-1], poly[1:])])
    want = np.min(np.sum((pts[:, None] - dense[None]) ** 2, -1), 1)
    np.testing.assert_allclose(got, want, atol=2e-6)


# ---- known values -----------------------------------------------------------------------------

def test_keyframe_3d_joint_off_by_10cm():
    m = motion()
    sb = storyboard(keyposes=[keypose(m, 10, 0, [WRIST])])
    proxy = m["joints"].clone()
    proxy[0, 10, 0, WRIST, 1] += 0.1
    ctx = context(sb, K3D_hat=proxy)
    ctx.config.key_weight_2d = 0.0
    assert float(E.keyframe_energy(m, ctx)) == pytest.approx(0.01)


def test_keyframe_2d_projected_error_and_normalisation():
    m = motion()
    one = context(storyboard(keyposes=[keypose(m, 10, 0, [WRIST], offset=(0.1, 0.0))]))
    two = context(storyboard(keyposes=[keypose(m, 10, 0, [WRIST, 0], offset=(0.0, 0.1)),
                                       keypose(m, 20, 1, [3], offset=(0.06, 0.08))]))
    for ctx in (one, two):
        ctx.config.key_time_sigma = 0.0  # only the keyframe itself
        assert float(E.keyframe_energy(m, ctx)) == pytest.approx(0.01)


def test_keyframe_quality_gate_downweights_inconsistent_keypoints():
    m = motion()
    ctx = context(storyboard(keyposes=[keypose(m, 10, 0, [WRIST], offset=(0.3, 0.0))]), K3D_hat=m["joints"])
    ctx.config.key_time_sigma = 0.0
    gated = float(E.keyframe_energy(m, ctx))
    assert 0 < gated < 0.09 * np.exp(-0.5 * 0.09 / 0.01) * 1.01   # 2D target is 0.3 m off the proxy


def test_trajectory_2d_distance_to_polyline():
    m = motion()
    cam = Storyboard().camera
    pelvis = cam.project(m["joints"][0, 0, 0, 0].numpy())
    d = 0.12
    line = np.array([pelvis + (-1.0, d), pelvis + (1.0, d)])   # horizontal line d above the pelvis
    one = context(storyboard(trajectories=[Trajectory("a", "pelvis", 0, N - 1, line)]))
    both = context(storyboard(trajectories=[Trajectory("a", "pelvis", 0, N - 1, line),
                                            Trajectory("a", "pelvis", 5, 9, line[::-1])]))
    for ctx in (one, both):
        assert float(E.trajectory_energy(m, ctx)) == pytest.approx(d * d, rel=1e-6)


def test_trajectory_3d_proxy_term():
    m = motion()
    proxy = m["joints"].clone()
    proxy[..., 2] += 0.2  # the lifted path runs 0.2 m in front of every joint
    ctx = context(storyboard(trajectories=[Trajectory("b", "head", 3, 30, np.array([[0.0, 0.0], [1.0, 0.0]]))]),
                  T3D_hat=proxy)
    ctx.config.traj_weight_2d = 0.0
    weight = ctx.config.traj_weight_3d
    assert float(E.trajectory_energy(m, ctx)) == pytest.approx(weight * 0.04, rel=1e-6)


def test_contact_huber_beyond_margin_and_occupancy_gate():
    m = motion()
    m["joints"][0, :, 0, HANDS[0]] = m["obj_anchors"][0, :, 0, 0] + torch.tensor([0.0, 0.0, 0.08], dtype=torch.float64)
    sb = storyboard(contacts=[Contact("a", "left", 5, 25, object="box", anchor=0)])
    ctx = context(sb)
    gap = 0.08 - ctx.config.contact_margin
    assert float(E.contact_energy(m, ctx)) == pytest.approx(0.5 * gap * gap)
    occupancy = torch.zeros(1, N, 3, dtype=torch.float64)
    occupancy[..., 0] = 1.0  # the CTMC says "approach" everywhere: the contact term is off
    assert float(E.contact_energy(m, ctx, occupancy)) == 0.0


def test_hand_contact_and_spacing():
    m = motion(apart=0.3)
    sb = storyboard(contacts=[Contact("a", "right", 0, 19, other_agent="b", other_hand="left")])
    ctx = context(sb)
    wrists = m["joints"][0, 0, 0, HANDS[1]] - m["joints"][0, 0, 1, HANDS[0]]
    gap = float(wrists.norm()) - ctx.config.hand_margin
    assert float(E.hand_contact_energy(m, ctx)) == pytest.approx(0.5 * gap ** 2 if gap < 0.1 else 0.1 * (gap - 0.05))
    # frames 20..39 have no contact: pelvises 0.3 m apart crowd by 0.15 m
    assert float(E.spacing_energy(m, ctx)) == pytest.approx((ctx.config.min_spacing - 0.3) ** 2)


def test_penetration_of_a_wrist_inside_a_box():
    m = motion(apart=3.0)
    wrist = m["joints"][0, 0, 0, WRIST]
    # box occupies x in [wrist - 0.03, wrist + 0.42]: only the wrist is inside, 0.03 deep
    m["obj_pose"][..., :3] = torch.stack([wrist[0] + 0.195, wrist[1] - 0.175, wrist[2]])
    radius = E.body_points(m["joints"])[1][WRIST]
    assert float(E.penetration_energy(m, context(storyboard()))) == pytest.approx(float(radius + 0.03) ** 2, abs=1e-6)


def test_ground_and_foot_skate():
    m = motion()
    m["joints"][0, :, 0, JOINT_INDEX["l_knee"], 1] = -0.1
    assert float(E.ground_energy(m, context(storyboard()))) == pytest.approx(0.01, rel=1e-3)
    m = motion()
    m["joints"][0, :, :, list(FEET), 0] += torch.arange(N, dtype=torch.float64)[:, None, None] * 0.05  # 1 m/s
    assert float(E.foot_skate_energy(m, context(storyboard()))) == pytest.approx(1.0, rel=1e-3)


def test_smoothness_of_constant_acceleration():
    m = motion()
    m["joints"] = m["joints"] + 0.5 * 0.01 * torch.arange(N, dtype=torch.float64)[None, :, None, None, None] ** 2
    assert float(E.smoothness_energy(m, context(storyboard()))) == pytest.approx(3 * 0.01 ** 2)


def test_no_constraints_give_zero():
    m = motion()
    ctx = context(storyboard())
    for name in ("keyframe", "trajectory", "object", "contact", "hand_contact", "penetration"):
        assert float(E.ENERGIES[name](m, ctx)) == 0.0, name


def test_object_path_is_the_base_and_a_key_the_silhouette_centre():
    """An object path traces the object's base (engine.sketchify), an object key's outline its
    middle: both met give no energy; the path put through the centre, with no outline to read it
    by (engine.controls.base_path), does."""
    m = motion(box_at=(0.2, 0.0, 0.5))
    cam, spec = Storyboard().camera, ObjectSpec("box")
    base = cam.project(m["obj_pose"][0, :, 0, :3].numpy())                     # (N, 2)
    centre = cam.project(m["obj_pose"][0, :, 0, :3].numpy() + (0.0, spec.size[1] / 2, 0.0))
    half = np.array([0.1, 0.1])
    outline = np.stack([centre[5] - half, centre[5] + (half[0], -half[1]), centre[5] + half])
    key = ObjectKey("box", 5, outline)
    on_base = context(storyboard(object_keys=[key], object_paths=[ObjectPath("box", 0, N - 1, base[[0, -1]])]))
    on_centre = context(storyboard(object_paths=[ObjectPath("box", 0, N - 1, centre[[0, -1]])]))
    assert float(E.object_energy(m, on_base)) == pytest.approx(0.0, abs=1e-12)
    assert float(E.object_energy(m, on_centre)) == pytest.approx((centre[0] - base[0]) @ (centre[0] - base[0]))


# ---- gradients ---------------------------------------------------------------------------------

def _fields(ctx: E.EnergyContext) -> dict:
    return {f.name: getattr(ctx, f.name) for f in fields(ctx)}


def busy_scene(apart: float = 0.35, box_at=(0.6, 0.0, 0.1)):
    """Every energy active: off-target keyposes and paths, contacts out of reach, crowding,
    overlap between the people and with the box, a sunk joint and sliding feet."""
    rng = np.random.default_rng(3)
    m = motion(apart=apart, box_at=box_at)
    m["joints"] = m["joints"] + torch.tensor(rng.normal(0, 0.02, m["joints"].shape))
    m["joints"][0, :, 0, JOINT_INDEX["l_knee"], 1] -= 0.5
    m["joints"][0, :, :, list(FEET), 0] += torch.arange(N, dtype=torch.float64)[:, None, None] * 0.03
    m["rot6d"] = torch.tensor(rng.normal(size=m["rot6d"].shape))
    sb = storyboard(keyposes=[keypose(m, 10, 0, [0, WRIST], offset=(0.2, 0.1))],
                    trajectories=[Trajectory("b", "head", 0, 30, rng.normal(size=(8, 2))),
                                  Trajectory("a", "r_wrist", 4, 4, np.zeros((2, 2)))],  # zero-length stroke
                    contacts=[Contact("a", "left", 5, 15, object="box", anchor=1),
                              Contact("b", "right", 16, 20, other_agent="a", other_hand="left")],
                    object_paths=[ObjectPath("box", 0, 39, rng.normal(size=(5, 2)))])
    proxy = m["joints"] + torch.tensor(rng.normal(0, 0.1, m["joints"].shape))
    occupancy = torch.softmax(torch.tensor(rng.normal(size=(1, N, 3))), -1)
    return m, context(sb, K3D_hat=proxy, T3D_hat=proxy), occupancy


@pytest.mark.parametrize("name", list(E.ENERGIES))
def test_gradient_finite_and_descends(name):
    m, ctx, occupancy = busy_scene()
    m = {k: v.clone().requires_grad_() for k, v in m.items()}
    value = E.ENERGIES[name](m, ctx, occupancy)
    assert value.shape == (1,) and float(value.detach()) > 0
    grads = torch.autograd.grad(value.sum(), list(m.values()), allow_unused=True)
    grads = [torch.zeros_like(v) if g is None else g for v, g in zip(m.values(), grads)]
    assert all(torch.isfinite(g).all() for g in grads)
    norm = torch.sqrt(sum((g * g).sum() for g in grads))
    assert norm > 0
    with torch.no_grad():
        stepped = {k: v - 1e-4 * g / norm for (k, v), g in zip(m.items(), grads)}
    assert float(E.ENERGIES[name](stepped, ctx, occupancy)) < float(value.detach())


def test_gradients_finite_at_coincident_points():
    m = motion(apart=0.0)  # the two people on top of each other
    m["joints"][0, :, 0, HANDS[0]] = m["obj_anchors"][0, :, 0, 0]     # hand exactly on its anchor
    m["joints"][0, :, 1, HANDS[0]] = m["joints"][0, :, 0, HANDS[1]]   # held hands coincide
    m["obj_pose"][..., :3] = m["joints"][0, 0, 0, 0]                  # box around the pelvis
    m["obj_pose"][..., 3:] = 0.0                                      # degenerate quaternion
    sb = storyboard(trajectories=[Trajectory("a", "pelvis", 0, 9, np.ones((3, 2)))],
                    contacts=[Contact("a", "left", 0, 9, object="box", anchor=0),
                              Contact("b", "left", 0, 9, other_agent="a", other_hand="right")])
    m = {k: v.clone().requires_grad_() for k, v in m.items()}
    total, terms = E.total_energy(m, context(sb, T3D_hat=m["joints"].detach()), t=0.5)
    assert all(torch.isfinite(v).all() for v in terms.values())
    total.sum().backward()
    assert all(torch.isfinite(v.grad).all() for v in m.values())


# ---- schedule and total -----------------------------------------------------------------------

def test_schedule_shape():
    w = E.EnergyWeights()
    early, mid, late = w.at(0.9), w.at(0.5), w.at(0.1)
    assert early["keyframe"] > mid["keyframe"] > late["keyframe"] > 0
    assert late["smoothness"] > mid["smoothness"] > early["smoothness"] > 0
    assert mid["contact"] > early["contact"] and mid["contact"] > late["contact"]
    ts = np.linspace(0, 1, 101)
    for name in E.ENERGIES:
        curve = np.array([w.at(t)[name] for t in ts]) / getattr(w, name)
        assert curve.max() <= 1 + 1e-9 and curve.min() >= w.schedule.floor - 1e-9
        assert np.max(np.abs(np.diff(curve))) < 0.1  # smooth: no jumps between close times


def test_total_is_the_weighted_sum_of_enabled_terms():
    m, ctx, _ = busy_scene()
    w = E.EnergyWeights()
    total, terms = E.total_energy(m, ctx, 0.3, w, enabled={"keyframe", "ground"})
    assert set(terms) == {"keyframe", "ground"}
    lam = w.at(0.3)
    assert float(total) == pytest.approx(sum(lam[k] * float(v) for k, v in terms.items()))
    with pytest.raises(ValueError, match="unknown energies"):
        E.total_energy(m, ctx, 0.3, w, enabled={"gravity"})


def test_batch_of_variations_is_independent():
    m, ctx, _ = busy_scene()
    sb_ctx = E.EnergyContext(**{f: (torch.cat([v, v]) if isinstance(v, torch.Tensor) else v)
                                for f, v in _fields(ctx).items()})
    m2 = {k: torch.cat([v, v + 0.05]) for k, v in m.items()}
    total, _ = E.total_energy(m2, sb_ctx, 0.5)
    alone, _ = E.total_energy(m, ctx, 0.5)
    assert total.shape == (2,) and float(total[0]) == pytest.approx(float(alone[0]))


# ---- the fast paths against plain references ---------------------------------------------------

def test_context_constants_follow_the_context():
    """The storyboard-only constants are cached per context: changing the config, replacing a
    field or editing one in place must give what a fresh context gives."""
    m, ctx, _ = busy_scene()

    def fresh():
        return E.EnergyContext(**{f: getattr(ctx, f) for f in _fields(ctx)})

    def same(a, b):
        return float(E.keyframe_energy(m, a)) == pytest.approx(float(E.keyframe_energy(m, b)), rel=1e-12)

    E.keyframe_energy(m, ctx)                       # fills the cache
    ctx.config.key_time_sigma = 0.0
    assert same(ctx, fresh())
    ctx.kp2d = ctx.kp2d + 0.05                      # a new tensor
    assert same(ctx, fresh())
    with torch.no_grad():
        ctx.kp2d[..., 0] += 0.05                    # the same tensor, edited in place
    assert same(ctx, fresh())


def _reference_soft_distance(points, a, b, temperature, valid=None):
    """Plain autograd soft distance of points (..., D) to their segments a, b (..., K, D): the
    mean squared closest-point distance under softmin weights held constant."""
    seg, rel = b - a, points[..., None, :] - a
    t = ((rel * seg).sum(-1) / ((seg * seg).sum(-1) + 1e-12)).clamp(0, 1)
    d2 = ((rel - t[..., None] * seg) ** 2).sum(-1)
    logits = -d2.detach() / temperature
    if valid is not None:
        logits = logits - 1e9 * (~valid).to(logits.dtype)
    return (torch.softmax(logits, -1) * d2).sum(-1)


def test_soft_polyline_gradient_matches_autograd():
    """The polyline distance computes its gradient in closed form (_SoftDistance): it must match
    autograd through the plain (P, L, D) computation with the softmin weights held constant."""
    rng = np.random.default_rng(5)
    poly = torch.tensor(rng.normal(size=(3, 9, 2)))
    pts = torch.tensor(rng.normal(size=(3, 40, 2)), requires_grad=True)
    for temperature in (1e-3, 0.05, 1.0):
        fast = E.soft_polyline_sq_distance(pts, poly, temperature)
        ref = _reference_soft_distance(pts, poly[:, None, :-1], poly[:, None, 1:], temperature)
        torch.testing.assert_close(fast, ref, rtol=1e-9, atol=1e-12)
        w = torch.tensor(rng.uniform(size=ref.shape))
        g_fast, = torch.autograd.grad((fast * w).sum(), pts)
        g_ref, = torch.autograd.grad((ref * w).sum(), pts)
        torch.testing.assert_close(g_fast, g_ref, rtol=1e-7, atol=1e-10)


def test_soft_segments_gradient_matches_autograd():
    rng = np.random.default_rng(6)
    a, b = torch.tensor(rng.normal(size=(2, 30, 7, 3))), torch.tensor(rng.normal(size=(2, 30, 7, 3)))
    b[:, :, 0] = a[:, :, 0]                                       # zero-length segments too
    valid = torch.tensor(rng.uniform(size=(2, 30, 7)) > 0.3)
    pts = torch.tensor(rng.normal(size=(2, 30, 3)), requires_grad=True)
    seg = b - a
    fast = _soft_segments_sq_distance(pts, a.movedim(-1, 0).contiguous(), seg.movedim(-1, 0).contiguous(),
                                        (seg * seg).sum(-1) + _EPS, 0.05, _invalid_bias(valid, a.dtype))
    ref = _reference_soft_distance(pts, a, b, 0.05, valid)
    torch.testing.assert_close(fast, ref, rtol=1e-9, atol=1e-12)
    g_fast, = torch.autograd.grad(fast.sum(), pts)
    g_ref, = torch.autograd.grad(ref.sum(), pts)
    torch.testing.assert_close(g_fast, g_ref, rtol=1e-7, atol=1e-10)


def _reference_penetration(m, ctx):
    """Every sphere against every object and every other person's sphere, no candidate search."""
    points, radii = E.body_points(m["joints"])                       # (B, N, H, P, 3)
    b, n, h, p = points.shape[:4]
    depth = []
    for o, spec in enumerate(ctx.objects):
        local = E.world_to_local(points.reshape(b, n, h * p, 3), m["obj_pose"][:, :, o])
        depth.append((radii.repeat(h) - E.object_sdf(spec, local)).flatten(1))
    for i in range(h):
        for j in range(i + 1, h):
            gap = E.safe_norm(points[:, :, i, :, None] - points[:, :, j, None])
            depth.append((radii[:, None] + radii[None] - gap).flatten(1))
    depth = torch.cat(depth, 1).clamp_min(0)
    return (depth ** 2).sum(1) / (depth > 0).sum(1).clamp_min(1)


@pytest.mark.parametrize("kind", ["box", "table", "canister"])
def test_penetration_matches_all_pairs(kind):
    """The candidate search must not lose a penetrating pair: value and gradient equal the
    all-pairs computation, on crowded scenes with the object among the people."""
    for seed, apart in enumerate((0.2, 0.35, 0.8)):
        m, ctx, _ = busy_scene(apart=apart, box_at=(0.3, 0.3, 0.0))
        ctx.objects = (ObjectSpec(kind),)
        rng = np.random.default_rng(seed)
        m["obj_pose"][..., 3:] = torch.tensor(rng.normal(size=(1, N, 1, 4)))   # tilted, unnormalised quaternions
        m = {k: v.clone().requires_grad_() for k, v in m.items()}
        fast, ref = E.penetration_energy(m, ctx), _reference_penetration(m, ctx)
        assert float(ref.detach()) > 0
        torch.testing.assert_close(fast, ref, rtol=1e-9, atol=1e-12)
        for g_fast, g_ref in zip(torch.autograd.grad(fast.sum(), [m["joints"], m["obj_pose"]]),
                                 torch.autograd.grad(ref.sum(), [m["joints"], m["obj_pose"]])):
            torch.testing.assert_close(g_fast, g_ref, rtol=1e-9, atol=1e-12)


def test_penetration_finds_pairs_at_the_edge_of_the_box_test():
    """Two people collapsed to points a distance d apart: their bounding boxes are d apart, and
    their largest spheres (r = 0.1) overlap up to d = 0.2, which the frame search must keep."""
    m, ctx, _ = busy_scene(box_at=(5.0, 0.0, 5.0))
    d = torch.linspace(0.05, 0.25, N, dtype=torch.float64)
    joints = torch.zeros(1, N, 2, 22, 3, dtype=torch.float64)
    joints[:, :, 1, :, 0] = d[:, None]
    m = dict(m, joints=joints.requires_grad_())
    fast, ref = E.penetration_energy(m, ctx), _reference_penetration(m, ctx)
    assert float(ref.detach()) > 0
    torch.testing.assert_close(fast, ref, rtol=1e-9, atol=1e-12)
    torch.testing.assert_close(torch.autograd.grad(fast.sum(), joints)[0],
                               torch.autograd.grad(ref.sum(), joints)[0], rtol=1e-9, atol=1e-12)


def _graph_size(output: torch.Tensor) -> int:
    """Autograd nodes behind `output`: the number of ops a backward pass runs."""
    seen, todo = set(), [output.grad_fn]
    while todo:
        node = todo.pop()
        if node is not None and node not in seen:
            seen.add(node)
            todo.extend(next_node for next_node, _ in node.next_functions)
    return len(seen)


def test_the_cost_per_call_does_not_grow_with_the_storyboard():
    """The energies run ~26 times a generation on small tensors, so their cost is the number of
    ops: the per-call graph of every term must be the same for 1 and for 6 keyposes, strokes and
    contacts (constraints are batched, never looped over in Python)."""
    m = motion(apart=0.6, box_at=(0.3, 0.0, 0.3))
    rng = np.random.default_rng(0)

    def scene(count: int) -> E.EnergyContext:
        return context(storyboard(
            keyposes=[keypose(m, 3 + 5 * i, i % 2, [0, WRIST], offset=(0.1, 0.0)) for i in range(count)],
            trajectories=[Trajectory("ab"[i % 2], "head" if i < 2 else ("pelvis", "l_wrist", "r_foot")[i % 3],
                                     5 * i, 5 * i + 4, rng.normal(size=(6, 2))) for i in range(count)],
            contacts=[Contact("ab"[i % 2], "left", 5 * i, 5 * i + 3, object="box", anchor=i % 4) for i in range(count)]),
            K3D_hat=m["joints"] + 0.05, T3D_hat=m["joints"] + 0.05)

    occupancy = torch.full((1, N, 3), 1 / 3, dtype=torch.float64)
    for name, term in E.ENERGIES.items():
        sizes = []
        for ctx in (scene(1), scene(6)):
            grad_m = {k: v.clone().requires_grad_() for k, v in m.items()}
            sizes.append(_graph_size(term(grad_m, ctx, occupancy)))
        assert sizes[0] == sizes[1], (name, sizes)

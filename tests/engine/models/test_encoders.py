"""Sketch encoders: conditioning shapes and semantics, lifting, along-path phase, the keyframe
time gate, 2D/3D alignment with InfoNCE, and the latent head f_gamma with L_lat / E_lat."""
import torch

from engine.camera import StoryboardCamera
from engine.models.alignment import LatentProjectionHead, alignment_loss, info_nce, latent_alignment_loss, latent_energy
from engine.models.encoders import (EncoderConfig, SketchConditioner, condition_presence, frames_to_latent,
                                    keyframe_gate, lift_loss, path_phase)
from engine.skeleton import JOINT_INDEX
from tests.engine.fixtures import fake_batch

torch.set_num_threads(1)
N, T_LAT = 120, 30


def consistent_batch(size: int, seed: int = 0, keyframes=(10, 60, 110)) -> dict:
    """Fake motion with storyboard controls drawn from it through a tilted storyboard camera."""
    b = fake_batch(size, seed=seed)
    g = torch.Generator().manual_seed(seed)
    cam = StoryboardCamera(25.0, 35.0, (0.0, 0.9, 0.0))
    basis = torch.tensor(cam.basis(), dtype=torch.float32)
    target = torch.tensor(cam.target, dtype=torch.float32)

    def project(p):
        return (p - target) @ basis[:2].T

    # Vary the motions so samples are distinguishable: offset and stretch each one.
    shift = torch.randn(size, 1, 1, 1, 3, generator=g) * torch.tensor([1.0, 0.0, 1.0])
    b["joints"] = b["joints"] + shift
    b["obj_pose"][..., :3] += shift[:, :, :, 0]
    b["obj_anchors"] += shift[..., None, :][:, :, :, 0]
    kp_mask = torch.zeros(size, N, 2, 22)
    kp_mask[:, list(keyframes)] = 1.0
    tr_mask = torch.zeros(size, N, 2, 22)
    tr_mask[:, 20:100, 0, JOINT_INDEX["pelvis"]] = 1.0
    tr_mask[:, 40:80, 1, JOINT_INDEX["r_wrist"]] = 1.0
    joints2d = project(b["joints"])
    b.update(kp2d=joints2d * kp_mask[..., None], kp_mask=kp_mask, tr2d=joints2d * tr_mask[..., None], tr_mask=tr_mask)
    obj_mask = torch.zeros(size, N, 1)
    obj_mask[:, list(keyframes)] = 1.0
    path_mask = torch.zeros(size, N, 1)
    path_mask[:, 30:90] = 1.0
    obj2d = project(b["obj_pose"][..., :3])
    b.update(obj2d=torch.cat([obj2d, torch.full_like(obj2d, 0.4)], -1) * obj_mask[..., None], obj_mask=obj_mask,
             objpath2d=obj2d * path_mask[..., None], objpath_mask=path_mask,
             camera=basis.expand(size, 3, 3).clone(), cam_target=target.expand(size, 3).clone())
    return b


def empty_controls(size: int) -> dict:
    b = consistent_batch(size)
    for k in ("kp_mask", "tr_mask", "obj_mask", "objpath_mask", "contact"):
        b[k] = torch.zeros_like(b[k])
    return b


def test_conditioning_shapes_and_entity_slots():
    torch.manual_seed(0)
    cond = SketchConditioner()
    b = consistent_batch(2)
    c = cond(b, T_LAT)
    assert c.residual.shape == (2, T_LAT, 3, 128)
    assert c.temporal_bias.shape == (2, T_LAT, T_LAT)
    assert c.embed.shape == (2, 256)
    assert torch.isfinite(c.residual).all() and c.residual[:, :, 2].abs().sum() > 0  # object slot fed
    wide = cond(b, T_LAT, V=4)
    assert wide.residual.shape == (2, T_LAT, 4, 128) and wide.residual[:, :, 3].abs().sum() == 0
    assert torch.allclose(wide.residual[:, :, :3], c.residual, atol=1e-6)
    assert torch.allclose(c.by_type.sum(3), c.residual, atol=1e-5)   # the ControlNet branches' split
    assert c.text is None                                            # a sketch-only conditioner


def test_a_text_conditioner_encodes_the_words_and_nothing_else_changes():
    from engine.text import tokenize
    torch.manual_seed(0)
    sketch_only = SketchConditioner()
    reading = SketchConditioner(EncoderConfig(text=True))
    reading.load_state_dict(sketch_only.state_dict(), strict=False)
    b = consistent_batch(2)
    tokens = [tokenize("two people carry the box together"), tokenize("")]
    b.update({k: torch.stack([torch.as_tensor(t[k]) for t in tokens]) for k in tokens[0]})
    c, plain = reading(b, T_LAT), sketch_only(b, T_LAT)
    assert c.text.shape == (2, 32, 64) and torch.isfinite(c.text).all()
    assert c.text_mask[0].sum() == 6 and c.text_mask[1].sum() == 0
    assert torch.equal(c.residual, plain.residual) and torch.equal(c.embed, plain.embed)


def test_empty_storyboard_gives_zero_residual_and_bias():
    cond = SketchConditioner()
    c = cond(empty_controls(2), T_LAT)
    assert c.residual.abs().max() == 0 and c.temporal_bias.abs().max() == 0
    assert not any(v.any() for v in condition_presence(empty_controls(1)).values())


def test_temporal_bias_is_symmetric_nonpositive_and_only_on_paths():
    cond = SketchConditioner()
    c = cond(consistent_batch(2), T_LAT)
    bias = c.temporal_bias
    assert torch.allclose(bias, bias.transpose(1, 2), atol=1e-6) and (bias <= 0).all()
    # Trajectories cover frames 20..99 -> latent steps 5..24; outside, the bias is zero.
    assert bias[:, :4].abs().max() == 0 and bias[:, :, 26:].abs().max() == 0
    assert bias[:, 6:24, 6:24].abs().sum() > 0


def test_keyframe_adapter_is_localised_in_time():
    torch.manual_seed(0)
    cond = SketchConditioner()
    b = consistent_batch(1, keyframes=(60,))
    b["kp_mask"][:, :, 1] = 0.0                        # only human 0 has a keypose
    k3d = cond.lift(b).keyposes
    r = cond.keyframes(k3d, b, T_LAT)                  # (1, T_lat, H, d)
    energy = r[0, :, 0].norm(dim=-1)
    peak = int(energy.argmax())
    assert abs(peak - round(60 / 119 * 29)) <= 1
    assert energy[:peak - 4].max() < 1e-3 * energy[peak] and energy[peak + 5:].max() < 1e-3 * energy[peak]
    assert r[0, :, 1].abs().max() == 0                 # the other human is untouched
    gate = keyframe_gate(N, T_LAT, 0.03)
    assert gate.shape == (T_LAT, N) and torch.allclose(gate.max(1).values, torch.ones(T_LAT), atol=0.02)


def test_path_phase_arc_length_speed_and_curvature():
    n = 40
    t = torch.linspace(0, 1, n)
    line = torch.stack([t * 2.0, torch.zeros(n), torch.zeros(n)], -1)
    circle = torch.stack([torch.cos(t * 3.14), torch.sin(t * 3.14), torch.zeros(n)], -1)
    pts = torch.zeros(1, n, 2, 22, 3)
    pts[0, :, 0, 0], pts[0, :, 1, 0] = line, circle
    mask = torch.zeros(1, n, 2, 22, dtype=torch.bool)
    mask[0, :, :, 0] = True
    phi = path_phase(pts, mask)
    s = phi[0, :, 0, 0, 0]
    assert s[0] == 0 and abs(s[-1] - 1) < 1e-5 and (s.diff() > 0).all()
    assert torch.allclose(phi[0, :, 0, 0, 1], torch.full((n,), 2.0 / (n - 1)), atol=1e-4)
    assert phi[0, 1:-1, 0, 0, 2].abs().max() < 1e-3               # straight: no curvature
    assert (phi[0, 2:-2, 1, 0, 2] * 50 - 1.0).abs().max() < 0.05    # unit circle: curvature 1
    assert phi[0, :, :, 1:].abs().max() == 0                        # unconstrained joints: zero


def test_lifter_prior_and_training():
    torch.manual_seed(0)
    cond = SketchConditioner()
    b = consistent_batch(4)
    lifted = cond.lift(b)
    m = b["kp_mask"] > 0
    err = (lifted.keyposes - b["joints"]).norm(dim=-1)[m]
    assert err.mean() < 0.5                            # the rest-height prior is already near
    opt = torch.optim.Adam(list(cond.lift_kf.parameters()) + list(cond.lift_tr.parameters()), lr=1e-3)
    first = None
    for _ in range(40):
        loss, parts = lift_loss(cond.lift(b), b, b)
        first = first if first is not None else loss.item()
        opt.zero_grad()
        loss.backward()
        opt.step()
    assert loss.item() < 0.5 * first and set(parts) == {"lift_kf", "lift_tr"}


def test_what_a_storyboard_leaves_unplaced_changes_nothing():
    # The lifter and the per-frame branches run only on the rows a storyboard places: values
    # left under its masks (an editor's stale points) must not reach the conditioning.
    torch.manual_seed(0)
    cond = SketchConditioner().eval()
    b = consistent_batch(2)
    noisy = dict(b)
    for uv, mask in (("kp2d", "kp_mask"), ("tr2d", "tr_mask")):
        noisy[uv] = b[uv] + 5.0 * torch.randn(b[uv].shape) * (b[mask] == 0)[..., None]
    with torch.no_grad():
        clean, dirty = cond.encode(b, T_LAT), cond.encode(noisy, T_LAT)
        alone = cond.lift({k: v[1:] for k, v in b.items()})
    lifted = clean.lifted.keyposes
    assert torch.equal(lifted[b["kp_mask"] == 0], torch.zeros_like(lifted[b["kp_mask"] == 0]))
    assert torch.allclose(alone.keyposes, lifted[1:], atol=1e-6)      # each pose lifted on its own
    assert torch.allclose(dirty.lifted.trajectories, clean.lifted.trajectories, atol=1e-6)
    assert torch.allclose(dirty.conditioning.residual, clean.conditioning.residual, atol=1e-5)
    assert torch.allclose(dirty.conditioning.embed, clean.conditioning.embed, atol=1e-5)


def test_alignment_pulls_matched_pairs_together():
    torch.manual_seed(0)
    cond = SketchConditioner()
    b = consistent_batch(12, seed=3)
    present = condition_presence(b)
    params = list(cond.enc2d.parameters()) + list(cond.enc3d.parameters())
    opt = torch.optim.Adam(params, lr=1e-3)

    def loss_now():
        return alignment_loss(cond.embed_2d(b), cond.embed_3d(b, b), present, cond.cfg)

    first, _ = loss_now()
    for _ in range(40):
        loss, parts = loss_now()
        opt.zero_grad()
        loss.backward()
        opt.step()
    assert loss.item() < 0.6 * first.item()
    with torch.no_grad():
        s2, s3 = cond.embed_2d(b), cond.embed_3d(b, b)
    retrieval = {y: (s2[y] @ s3[y].T).argmax(1).eq(torch.arange(12)).float().mean().item() for y in s2}
    assert retrieval["kf"] > 0.75 and sum(retrieval.values()) / 3 > 0.5   # chance: 1/12
    assert torch.allclose(s2["tr"].norm(dim=-1), torch.ones(12), atol=1e-5)


def test_info_nce_prefers_matched_pairs_and_ignores_absent_rows():
    a = torch.randn(6, 16)
    assert info_nce(a, a, 0.1) < info_nce(a, a[torch.randperm(6)], 0.1)
    valid = torch.tensor([True, False, False, False, False, False])
    assert info_nce(a, torch.randn(6, 16), 0.1, valid) == 0


def test_latent_head_loss_and_energy():
    torch.manual_seed(0)
    cfg = EncoderConfig()
    head = LatentProjectionHead(cfg)
    z = torch.randn(4, T_LAT, 3, cfg.latent_dim)
    out = head(z)
    assert set(out) == {"kf", "tr", "o"} and out["kf"].shape == (4, 256)
    targets = {y: torch.nn.functional.normalize(torch.randn(4, 256), dim=-1) for y in out}
    present = {y: torch.ones(4, dtype=torch.bool) for y in out}
    opt = torch.optim.Adam(head.parameters(), lr=1e-3)
    first = None
    for _ in range(30):
        loss, parts = latent_alignment_loss(head, z, targets, present, cfg)
        first = first if first is not None else loss.item()
        opt.zero_grad()
        loss.backward()
        opt.step()
    assert loss.item() < 0.5 * first
    # E_lat: (B,), zero weight for absent types, and gradient descent on z lowers it.
    e = latent_energy(head, z, targets, present)
    assert e.shape == (4,)
    none = {y: torch.zeros(4, dtype=torch.bool) for y in out}
    assert latent_energy(head, z, targets, none).abs().max() == 0
    zz = torch.randn(1, T_LAT, 3, cfg.latent_dim, requires_grad=True)
    s1 = {y: v[:1] for y, v in targets.items()}
    e0 = latent_energy(head, zz, s1)
    (grad,) = torch.autograd.grad(e0.sum(), zz)
    assert latent_energy(head, zz.detach() - 0.5 * grad, s1) < e0


def test_frames_to_latent_averages_each_window():
    x = torch.arange(N, dtype=torch.float32).reshape(1, N, 1)
    y = frames_to_latent(x, T_LAT)
    assert y.shape == (1, T_LAT, 1) and torch.allclose(y[0, :, 0], torch.arange(T_LAT) * 4 + 1.5)

"""Training windows: fixed shapes, canonicalization that keeps motion and controls in
agreement, determinism per (seed, epoch, index), mixed real + synthetic batches, splits."""
import time

import numpy as np
import pytest
import torch
from torch.utils.data import DataLoader

from engine.clip import ClipError, MotionClip
from engine.controls import Controls, build_controls
from engine.dataset import HELD_OUT_SALSA_TAKES, DatasetConfig, StoryboardWindows, canonicalize, split_files
from engine.geometry.rotations import sixd_to_matrix
from engine.io.resample import resample_clip
from engine.skeleton import REST_OFFSETS, forward_kinematics
from tests.engine.test_sketchify import carry_clip, handshake_clip

EXACT = DatasetConfig(noise_range=(0.0, 0.0))


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """Two synthetic-like carry clips (20 fps) and one real-like take (60 fps, no object, no labels)."""
    d = tmp_path_factory.mktemp("clips")
    carry_clip(120, seed=0).save(d / "synth_000001.npz")
    carry_clip(200, seed=1).save(d / "synth_000002.npz")
    mocap = carry_clip(480, seed=2, fps=60.0)
    MotionClip(fps=60.0, joints=mocap.joints, rot6d=mocap.rot6d).save(d / "60_01_61_01.npz")
    return sorted(d.glob("*.npz"))


@pytest.fixture(scope="module")
def exact(files):
    return StoryboardWindows(files, EXACT)


def test_windows_cover_every_clip_with_the_tail(exact):
    # 60 fps x 480 frames -> 160 frames at 20 fps: starts 0, 30 and the tail at 40.
    assert exact.windows.tolist() == [[0, 0], [0, 30], [0, 40], [1, 0], [2, 0], [2, 30], [2, 60], [2, 80]]
    assert [c.fps for c in exact.clips] == [20.0, 20.0, 20.0]


def test_items_have_fixed_shapes_and_dtypes(exact):
    n = EXACT.window
    expected = {"joints": (n, 2, 22, 3), "rot6d": (n, 2, 22, 6), "obj_pose": (n, 1, 7),
                "obj_anchors": (n, 1, 4, 3), "obj_present": (), "phase": (n, 3), "contact_label": (n, 2, 2),
                "has_labels": (), "valid": (n,), "noise": (), "kp2d": (n, 2, 22, 2), "kp_mask": (n, 2, 22),
                "tr2d": (n, 2, 22, 2), "tr_mask": (n, 2, 22), "obj2d": (n, 1, 4), "obj_mask": (n, 1),
                "objpath2d": (n, 1, 2), "objpath_mask": (n, 1), "contact": (n, 2, 2),
                "contact_anchor": (n, 2, 2), "camera": (3, 3), "cam_target": (3,), "text_ids": (32,), "text_mask": (32,)}
    assert {f.name for f in Controls.__dataclass_fields__.values()} <= set(expected)
    for i in range(len(exact)):
        item = exact[i]
        assert {k: tuple(v.shape) for k, v in item.items()} == expected
        for k, v in item.items():
            assert v.dtype == (torch.int64 if k in ("contact_anchor", "text_ids") else torch.float32), k
            assert torch.isfinite(v.float()).all(), k
    real, synth = exact[0], exact[3]
    assert real["obj_present"] == 0 and real["has_labels"] == 0 and real["obj_pose"].abs().sum() == 0
    assert synth["obj_present"] == 1 and synth["has_labels"] == 1
    assert synth["contact"].sum() > 0 and (synth["contact_anchor"] >= 0).any()
    assert real["text_mask"].sum() >= 3 and synth["text_mask"].sum() >= 3      # every clip has a caption


def test_canonical_window_starts_at_origin_and_keeps_the_skeleton(exact):
    for i in (0, 4):
        item = exact[i]
        joints, pose = item["joints"].double().numpy(), item["obj_pose"].double().numpy()
        ground = [joints[0, :, 0]] + ([pose[0, :, :3]] if item["obj_present"] else [])
        np.testing.assert_allclose(np.concatenate(ground).mean(0)[[0, 2]], 0.0, atol=1e-5)
        # The yaw turned the root rotation with the joints: FK of the rotations still gives the joints.
        rot = sixd_to_matrix(item["rot6d"].double().numpy())
        fk = forward_kinematics(joints[:, :, 0], rot, REST_OFFSETS)
        np.testing.assert_allclose(fk, joints, atol=1e-4)


def test_canonicalize_yaw_turns_the_object_and_anchors():
    clip = carry_clip(40)
    turned = canonicalize(clip, yaw=np.pi / 2)
    # +90 degrees about +Y takes +Z to +X: the box, carried along +Z, now travels along +X.
    travel = turned.obj_pose[-1, 0, :3] - turned.obj_pose[0, 0, :3]
    assert travel[0] > 0.5 and abs(travel[2]) < 1e-5
    np.testing.assert_allclose(turned.joints[..., 1], clip.joints[..., 1], atol=1e-6)
    np.testing.assert_allclose(turned.obj_anchors[:, 0, 0], turned.joints[:, 0, 21], atol=1e-5)


def project(item, points):
    return (points - item["cam_target"]) @ item["camera"][:2].T


def test_motion_and_controls_agree_at_noise_zero(exact):
    for i in range(len(exact)):
        item = exact[i]
        kp_mask = item["kp_mask"].bool()
        assert kp_mask.sum() >= 2 * 2 * 22
        uv = project(item, item["joints"])
        torch.testing.assert_close(item["kp2d"][kp_mask], uv[kp_mask], atol=1e-4, rtol=0)
        # Strokes keep their ends, so the pelvis path starts and ends on the projected pelvis.
        for frame in (0, -1):
            torch.testing.assert_close(item["tr2d"][frame, :, 0], uv[frame, :, 0], atol=1e-4, rtol=0)
        if item["obj_present"]:
            obj_uv = project(item, item["obj_pose"][..., :3])
            torch.testing.assert_close(item["objpath2d"][[0, -1]], obj_uv[[0, -1]], atol=1e-4, rtol=0)


def test_items_are_deterministic_per_epoch(files):
    ds = StoryboardWindows(files, DatasetConfig(seed=3))
    a, b = ds[4], ds[4]
    assert all(torch.equal(a[k], b[k]) for k in a)
    ds.set_epoch(1)
    c = ds[4]
    assert not torch.equal(a["joints"], c["joints"]) and not torch.equal(a["camera"], c["camera"])
    assert 0.0 <= float(a["noise"]) <= 0.8


def test_mixed_real_and_synthetic_batches_collate(files):
    ds = StoryboardWindows(files)
    batch = next(iter(DataLoader(ds, batch_size=len(ds), shuffle=False)))
    assert batch["joints"].shape == (len(ds), 120, 2, 22, 3)
    assert batch["obj_present"].tolist() == [0, 0, 0, 1, 1, 1, 1, 1]
    assert batch["has_labels"].tolist() == batch["obj_present"].tolist()


def test_short_clip_is_padded_with_its_last_frame(tmp_path):
    carry_clip(90).save(tmp_path / "short.npz")
    item = StoryboardWindows([tmp_path / "short.npz"], EXACT)[0]
    assert item["valid"].sum() == 90 and item["valid"][89] == 1 and item["valid"][90] == 0
    assert torch.equal(item["joints"][90:], item["joints"][89:90].expand(30, -1, -1, -1))


def test_person_person_clip_has_empty_object_slot(tmp_path):
    handshake_clip(120).save(tmp_path / "hands.npz")
    item = StoryboardWindows([tmp_path / "hands.npz"], EXACT)[0]
    assert item["obj_present"] == 0 and item["obj_mask"].sum() == 0
    assert item["contact"][30:50, 0, 1].all() and (item["contact_anchor"] == -1).all()


def test_clips_that_do_not_fit_the_slots_are_refused(tmp_path):
    one = carry_clip(80)
    MotionClip(fps=20.0, joints=one.joints[:, :1], rot6d=one.rot6d[:, :1]).save(tmp_path / "solo.npz")
    with pytest.raises(ClipError, match="2 humans"):
        StoryboardWindows([tmp_path / "solo.npz"])


def test_resample_picks_every_third_frame_from_60_fps():
    clip = carry_clip(61, fps=60.0)
    slow = resample_clip(clip, 20.0)
    assert slow.num_frames == 21 and slow.fps == 20.0
    np.testing.assert_allclose(slow.joints, clip.joints[::3], atol=1e-6)
    np.testing.assert_allclose(slow.rot6d, clip.rot6d[::3], atol=1e-5)
    np.testing.assert_array_equal(slow.contact, clip.contact[::3])


def test_splits_by_seed_and_held_out_salsa_take(tmp_path):
    synth, real = tmp_path / "synth", tmp_path / "real"
    synth.mkdir(), real.mkdir()
    for seed in range(200):
        (synth / f"scene_{seed:05d}.npz").touch()
    for take in ("01", "02", "10"):
        (real / f"60_{take}_61_{take}.npz").touch()
    splits = split_files(synth, real)
    assert HELD_OUT_SALSA_TAKES == ("60_10/61_10",)
    assert [p.name for p in splits.test if p.parent == real] == ["60_10_61_10.npz"]
    assert not any("60_10" in p.name for p in splits.train + splits.val)
    assert sorted(splits.train + splits.val + splits.test) == sorted(list(synth.glob("*")) + list(real.glob("*")))
    # seed mod 1000 < 50 -> test, < 100 -> val: 50 test and 50 val of seeds 0..199.
    assert len([p for p in splits.test if p.parent == synth]) == 50 and len(splits.val) == 50
    again = split_files(synth, real)
    assert again == splits


def test_getitem_is_fast(files):
    ds = StoryboardWindows(files)
    ds[0]
    start = time.perf_counter()
    for i in range(3 * len(ds)):
        ds[i % len(ds)]
    per_item = (time.perf_counter() - start) / (3 * len(ds))
    assert per_item < 0.04, f"{per_item * 1e3:.1f} ms per item"  # ~5 ms unloaded; generous for shared CI


def test_a_sparse_storyboard_keeps_the_ends_and_leaves_the_middle_to_the_text(files):
    full = StoryboardWindows(files, DatasetConfig(seed=3))
    thumbs = StoryboardWindows(files, DatasetConfig(seed=3, sparse_share=1.0))
    a, b = full[3], thumbs[3]
    assert torch.equal(a["joints"], b["joints"]) and torch.equal(a["text_ids"], b["text_ids"])
    assert b["tr_mask"].sum() == 0 and b["contact"].sum() == 0 and b["objpath_mask"].sum() == 0
    keyed = b["kp_mask"].flatten(1).any(1).nonzero().flatten().tolist()
    assert len(keyed) in (1, 2) and keyed[0] == a["kp_mask"].flatten(1).any(1).nonzero().min()
    assert 0 < b["kp_mask"].sum() < a["kp_mask"].sum()
    kinds = {int(thumbs[i]["kp_mask"].flatten(1).any(1).sum()) for i in range(len(thumbs))}
    assert kinds == {1, 2}                                   # start only, or start and end
    assert torch.equal(full[4]["kp_mask"], StoryboardWindows(files, DatasetConfig(seed=3, sparse_share=0.0))[4]["kp_mask"])


def test_artist_style_sketches_are_mended_as_a_request_mends_them(files, monkeypatch):
    """A posed sketch whose template faces the other way reaches the model as generation gives it:
    its template joints unplaced (engine.mirrored)."""
    import engine.dataset as dataset
    from engine.mirrored import TEMPLATE, TEMPLATE_JOINTS, crossed_over
    from engine.skeleton import MIRROR

    crossed = []

    def facing_away(storyboard, seed, posed=False):      # the template's left and right swapped at every key
        for k in storyboard.keyposes:
            k.mask[:] = True
            k.points[TEMPLATE_JOINTS] = k.points[np.asarray(MIRROR)[TEMPLATE_JOINTS]]
        crossed.extend((k.agent, k.frame) for k in storyboard.keyposes if crossed_over(k))
        return storyboard

    seen = []
    monkeypatch.setattr(dataset, "redrawn", facing_away)
    monkeypatch.setattr(dataset, "build_controls", lambda sb: seen.append(sb) or build_controls(sb))
    StoryboardWindows(files[:1], DatasetConfig(noise_range=(0.0, 0.0), artist_share=1.0))[0]
    assert crossed and seen
    assert not any((k.mask & TEMPLATE).any() for k in seen[0].keyposes if (k.agent, k.frame) in crossed)

"""The motion evaluator: shapes, invariance to a global yaw and shift, contrastive learning that
lifts R-precision above chance, FID sanity, file round trip and clear errors, the training entry."""
import numpy as np
import pytest
import torch

from engine.camera import StoryboardCamera
from engine.clip import MotionClip
from engine.controls import build_controls
from engine.evaluation import (EvaluatorConfig, EvaluatorError, MotionEvaluator, embedding_diversity, fid,
                               load_evaluator, motion_embeddings, r_precision_top3, save_evaluator, story_embeddings)
from engine.evaluation.evaluator import motion_batch, story_batch
from engine.evaluation.features import motion_features, story_features
from engine.evaluation.train_evaluator import FeatureCache, TrainConfig, fit, main
from engine.geometry.rotations import matrix_to_6d
from engine.objects import NUM_ANCHORS
from engine.skeleton import JOINT_INDEX, rest_pose
from engine.sketchify import sketchify

torch.set_num_threads(1)
TINY = EvaluatorConfig(hidden=32, embed=64)


def yaw_matrix(yaw):
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def scene(rng, n=120, fps=20.0, with_object=True):
    """Two rest-pose people side by side walking a curved path at a random speed and turn rate,
    from a random start and heading, carrying a box between them (or with no object)."""
    heading0, turn, speed = rng.uniform(-np.pi, np.pi), rng.uniform(-1.2, 1.2), rng.uniform(0.2, 1.4)
    gap = rng.uniform(0.5, 1.2)
    heading = heading0 + turn * np.linspace(0, 1, n)
    step = speed / fps * np.stack([np.sin(heading), np.zeros(n), np.cos(heading)], -1)
    centre = np.cumsum(step, axis=0) + [rng.uniform(-3, 3), 0.0, rng.uniform(-3, 3)]
    R = np.stack([yaw_matrix(h) for h in heading])                                  # (n, 3, 3)
    left = R @ np.array([gap / 2, 0.0, 0.0])                                        # (n, 3)
    body = np.einsum("nij,kj->nki", R, rest_pose())
    joints = np.stack([body + (centre - left)[:, None], body + (centre + left)[:, None]], axis=1)
    rot = np.broadcast_to(np.eye(3), (n, 2, 22, 3, 3)).copy()
    rot[:, :, 0] = R[:, None]
    kw = {}
    if with_object:
        pose = np.zeros((n, 1, 7))
        pose[:, 0, :3] = centre + [0.0, 0.8, 0.0]
        pose[:, 0, 3], pose[:, 0, 5] = np.cos(heading / 2), np.sin(heading / 2)
        wrists = joints[:, :, [JOINT_INDEX["r_wrist"], JOINT_INDEX["l_wrist"]]][:, [0, 1], [0, 1]]
        anchors = wrists[:, np.arange(NUM_ANCHORS) % 2][:, None]                    # (n, 1, K, 3)
        kw = dict(obj_pose=pose, obj_anchors=anchors, obj_type=np.array(["box"]),
                  obj_size=np.array([[0.45, 0.35, 0.35]]))
    return MotionClip(fps=fps, joints=joints, rot6d=matrix_to_6d(rot), **kw)


def storyboard(clip, seed):
    return sketchify(clip, keyframes=2, noise=0.0, seed=seed, camera=StoryboardCamera())


def turned_and_moved(clip, yaw, shift):
    """The same scene under a global yaw about +Y and then a ground shift."""
    R = yaw_matrix(yaw)
    pose = clip.obj_pose.copy()
    pose[..., :3] = pose[..., :3] @ R.T + shift
    half = np.array([np.cos(yaw / 2), 0.0, np.sin(yaw / 2), 0.0])                   # wxyz of R
    w1, v1 = half[0], half[1:]
    w2, v2 = pose[..., 3:4].copy(), pose[..., 4:].copy()
    pose[..., 3:4] = w1 * w2 - v2 @ v1[:, None]
    pose[..., 4:] = w1 * v2 + w2 * v1 + np.cross(v1, v2)
    return MotionClip(fps=clip.fps, joints=clip.joints @ R.T + shift, rot6d=clip.rot6d, obj_pose=pose,
                      obj_anchors=clip.obj_anchors @ R.T + shift, obj_type=clip.obj_type, obj_size=clip.obj_size)


@pytest.fixture(scope="module")
def scenes():
    rng = np.random.default_rng(0)
    return [scene(rng) for _ in range(32)]


@pytest.fixture(scope="module")
def storyboards(scenes):
    return [storyboard(c, i) for i, c in enumerate(scenes)]


def test_default_evaluator_is_small_and_large_is_wider():
    assert MotionEvaluator().num_parameters() < 1_000_000
    assert MotionEvaluator(EvaluatorConfig.large()).num_parameters() > MotionEvaluator().num_parameters()


def test_embeddings_have_fixed_width_and_unit_norm_for_mixed_inputs(scenes, storyboards):
    torch.manual_seed(0)
    ev = MotionEvaluator().eval()
    rng = np.random.default_rng(1)
    no_object = scene(rng, n=90, with_object=False)            # shorter, no object
    fast = scene(rng, n=360, fps=60.0)                         # resampled to 20 fps
    emb = motion_embeddings(ev, [scenes[0], no_object, fast])
    assert emb.shape == (3, 256)
    np.testing.assert_allclose(np.linalg.norm(emb, axis=1), 1.0, atol=1e-6)
    story = story_embeddings(ev, [storyboards[0], storyboard(no_object, 1), build_controls(storyboards[2])])
    assert story.shape == (3, 256)
    np.testing.assert_allclose(np.linalg.norm(story, axis=1), 1.0, atol=1e-6)
    # A batched dict gives what the clips give; padding frames of a shorter clip do not count.
    batch = motion_batch(scenes[:2])
    np.testing.assert_allclose(motion_embeddings(ev, {k: v.numpy() for k, v in batch.items()}),
                               motion_embeddings(ev, scenes[:2]), atol=1e-6)
    assert story_batch([storyboards[0], storyboard(no_object, 1)])["valid"].sum() == 120 + 90


def test_motion_embedding_ignores_a_global_yaw_and_shift(scenes):
    torch.manual_seed(0)
    ev = MotionEvaluator().eval()
    moved = [turned_and_moved(c, yaw, np.array([dx, 0.0, dz]))
             for c, yaw, dx, dz in zip(scenes[:4], (0.7, -2.0, 3.0, 1.4), (5.0, -1.0, 0.3, 9.0), (-2.0, 4.0, 0.0, 1.0))]
    np.testing.assert_allclose(motion_embeddings(ev, moved), motion_embeddings(ev, scenes[:4]), atol=1e-4)
    # ... but not a change of the motion itself: person B lifted by 20 cm.
    lifted = MotionClip(fps=20.0, joints=scenes[0].joints + np.array([0, 0.2, 0]) * [[[0]], [[1]]],
                        rot6d=scenes[0].rot6d, obj_pose=scenes[0].obj_pose)
    assert np.abs(motion_embeddings(ev, [lifted]) - motion_embeddings(ev, scenes[:1])).max() > 1e-3


def cache_of(clips, boards, fps=20.0):
    motion, story = motion_batch(clips, fps), story_batch(boards)
    features = motion_features(motion["joints"], motion["obj_pose"], motion["obj_present"], motion["valid"], fps)
    return FeatureCache(
        motion=features.half(), story=story_features(story, story["valid"]).half()[None], valid=motion["valid"],
        clip=torch.arange(len(clips)), start=torch.zeros(len(clips), dtype=torch.int64))


def test_contrastive_training_lifts_r_precision_well_above_chance(scenes, storyboards):
    torch.manual_seed(0)
    ev = MotionEvaluator(TINY)
    chance = 3 / 32
    before = r_precision_top3(ev, storyboards, scenes)
    losses = fit(ev, cache_of(scenes, storyboards),
                 TrainConfig(model=TINY, steps=40, batch=32, lr=3e-3, warmup=10, log_every=0))
    assert np.mean(losses[-5:]) < 0.5 * np.mean(losses[:5])
    after = r_precision_top3(ev, storyboards, scenes)
    assert after > 5 * chance and after > before + 0.4


def test_fid_is_zero_for_a_set_with_itself_and_positive_for_a_changed_set(scenes):
    torch.manual_seed(0)
    ev = MotionEvaluator(TINY).eval()
    assert abs(fid(ev, scenes, scenes)) < 1e-6
    rng = np.random.default_rng(3)
    changed = [MotionClip(fps=c.fps, joints=c.joints + rng.normal(0, 0.05, c.joints.shape), rot6d=c.rot6d,
                          obj_pose=c.obj_pose) for c in scenes]
    assert fid(ev, scenes, changed) > 1e-3
    assert embedding_diversity(ev, scenes) > 0


def test_save_and_load_keep_config_card_and_embeddings(tmp_path, scenes, storyboards):
    torch.manual_seed(0)
    ev = MotionEvaluator(TINY, card={"seed": 7}).eval()
    path = tmp_path / "evaluator.pt"
    save_evaluator(ev, path)
    loaded = load_evaluator(path)
    assert loaded.config == TINY and loaded.card == {"seed": 7} and not loaded.training
    # Weights are stored in half precision: embeddings agree to that precision.
    np.testing.assert_allclose(motion_embeddings(loaded, scenes[:4]), motion_embeddings(ev, scenes[:4]), atol=2e-2)
    np.testing.assert_allclose(story_embeddings(loaded, storyboards[:4]), story_embeddings(ev, storyboards[:4]),
                               atol=2e-2)


def test_wrong_or_corrupt_files_raise_one_clear_line(tmp_path):
    torch.manual_seed(0)
    good = tmp_path / "good.pt"
    save_evaluator(MotionEvaluator(TINY), good)
    truncated, garbage, foreign = tmp_path / "truncated.pt", tmp_path / "garbage.pt", tmp_path / "foreign.pt"
    truncated.write_bytes(good.read_bytes()[:2000])
    garbage.write_bytes(b"definitely not torch" * 10)
    torch.save({"weights": torch.zeros(3)}, foreign)
    blob = torch.load(good, weights_only=True)
    blob["config"]["hidden"] = 48
    misfit = tmp_path / "misfit.pt"
    torch.save(blob, misfit)
    for path in (tmp_path / "missing.pt", truncated, garbage, foreign, misfit):
        with pytest.raises(EvaluatorError) as err:
            load_evaluator(path)
        assert str(path) in str(err.value) and "\n" not in str(err.value)


def test_training_entry_writes_weights_and_a_model_card_without_reading_test_files(tmp_path):
    rng = np.random.default_rng(5)
    data = tmp_path / "synth"
    data.mkdir()
    for seed in (60, 61, 70, 120, 130, 140, 150, 160):        # 60..99 val, 100.. train (split_files)
        scene(rng).save(data / f"walk_{seed:06d}.npz")
    (data / f"walk_{10:06d}.npz").write_bytes(b"a test-split file the trainer must never open")
    out = tmp_path / "res" / "evaluator.pt"
    args = ["--synth", str(data), "--steps", "3", "--views", "1", "--seed", "3", "--device", "cpu"]
    assert main(args + ["--out", str(out)]) == 0
    assert main(args + ["--out", str(tmp_path / "again.pt")]) == 0
    first, again = load_evaluator(out), load_evaluator(tmp_path / "again.pt")
    for name, value in first.state_dict().items():       # one seed, one machine: the same weights
        assert torch.equal(value, again.state_dict()[name]), name
    card = first.card
    assert card["seed"] == 3 and card["train"]["windows"] == 5 and card["val"]["windows"] == 3
    text = out.with_suffix(".md").read_text()
    for expected in ("--steps 3", "git commit", "seed: 3", "walk_000120.npz", "R-precision top-3", "FID",
                     "wall time"):
        assert expected in text
    assert "walk_000010" not in text

"""RetrievAdapt: a noise-free sketch of an indexed clip retrieves that clip (under any agent
order, ground placement and heading), retiming lands keyposes on their keyframes, blending
lowers the keypose error, the index survives save / load, and the streaming form yields one step."""
import numpy as np
import pytest

from engine.baselines import AdaptConfig, IndexConfig, RetrievalIndex, adapt, retrieve, sample_retrieval
from engine.baselines.adaptation import sample_frames, transform_clip
from engine.clip import MotionClip
from engine.geometry.rotations import axis_angle_to_matrix, matrix_to_6d
from engine.metrics import adherence
from engine.skeleton import REST_OFFSETS, REST_PELVIS_HEIGHT, forward_kinematics
from engine.sketchify import sketchify

FRAMES = 80
UNIFORM = AdaptConfig(retime=False, blend=False)


def scene_clip(seed, n=FRAMES):
    """Two people side by side (facing each other) walking a random arc with a box between
    them, each limb swinging smoothly (FK of random sinusoidal rotations); a random hold span."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 1.0, n)
    yaw = rng.uniform(-np.pi, np.pi) + rng.uniform(-1.5, 1.5) * t
    centre = np.cumsum(rng.uniform(0.5, 2.5) / n * np.stack([np.sin(yaw), np.cos(yaw)], -1), axis=0)
    joints, rot6d = [], []
    for side in (1.0, -1.0):
        ground = centre + side * 0.6 * np.stack([np.cos(yaw), -np.sin(yaw)], -1)
        local = axis_angle_to_matrix(rng.uniform(0.1, 0.5, (1, 22, 3)) * np.sin(
            2 * np.pi * rng.uniform(0.5, 2.5, (1, 22, 3)) * t[:, None, None] + rng.uniform(0, 6.3, (1, 22, 3))))
        facing = np.stack([np.zeros(n), yaw - side * np.pi / 2, np.zeros(n)], -1)
        local[:, 0] = axis_angle_to_matrix(facing) @ local[:, 0]
        root = np.stack([ground[:, 0], np.full(n, REST_PELVIS_HEIGHT), ground[:, 1]], -1)
        joints.append(forward_kinematics(root, local))
        rot6d.append(matrix_to_6d(local))
    pose = np.zeros((n, 1, 7))
    pose[:, 0, [0, 2]], pose[:, 0, 1] = centre, 0.5
    pose[:, 0, 3], pose[:, 0, 5] = np.cos(yaw / 2), np.sin(yaw / 2)
    contact = np.zeros((n, 2, 2))
    a, b = sorted(rng.integers(5, n - 5, 2))
    contact[a:b + 1, 0, 1] = contact[a:b + 1, 1, 0] = 1
    return MotionClip(fps=20.0, joints=np.stack(joints, 1), rot6d=np.stack(rot6d, 1), obj_pose=pose,
                      obj_type=np.array(["box"]), obj_size=np.array([[0.45, 0.35, 0.35]]),
                      bone_offsets=np.stack([REST_OFFSETS] * 2), contact=contact, scenario=f"scene{seed}")


def swap_people(clip):
    return MotionClip(fps=clip.fps, joints=clip.joints[:, ::-1], rot6d=clip.rot6d[:, ::-1],
                      obj_pose=clip.obj_pose, obj_type=clip.obj_type, obj_size=clip.obj_size,
                      contact=clip.contact[:, ::-1], bone_offsets=clip.bone_offsets[::-1])


@pytest.fixture(scope="module")
def clips():
    return [scene_clip(seed) for seed in range(6)]


@pytest.fixture(scope="module")
def index(clips):
    return RetrievalIndex.build(clips, IndexConfig(window=FRAMES))


def k2d(clip, storyboard):
    return adherence(clip, storyboard)["K2D"]


def test_windows_follow_the_dataset_layout(clips):
    index = RetrievalIndex.build(clips[:2], IndexConfig(window=50, stride=20))
    # Starts 0, 20 and the tail window at 30, per clip.
    assert index.windows.tolist() == [[c, s, 50] for c in range(2) for s in (0, 20, 30)]
    assert index.points.shape == (2 * FRAMES, 2 * 22 + 2, 3)


@pytest.mark.parametrize("swapped", [False, True])
def test_noise_free_sketch_retrieves_its_clip(clips, index, swapped):
    source = swap_people(clips[3]) if swapped else clips[3]
    storyboard = sketchify(source, keyframes=4, noise=0.0, seed=5)
    match = retrieve(index, storyboard)
    assert index.windows[match.window].tolist() == [3, 0, FRAMES]
    assert match.people == ((1, 0) if swapped else (0, 1))
    assert abs(match.yaw) < np.deg2rad(2) and np.linalg.norm(match.offset) < 0.05
    adapted = adapt(index, match, storyboard)
    assert adapted.clip.num_frames == storyboard.length
    assert k2d(adapted.clip, storyboard) < 0.005


def test_retiming_puts_keyposes_on_their_keyframes(index):
    """The query is indexed clip 3 turned, moved and played with a non-linear time warp."""
    warp = (FRAMES - 1) * np.linspace(0.0, 1.0, FRAMES) ** 1.4
    query = sample_frames(transform_clip(scene_clip(3), 0.7, np.array([1.0, 0.0, -0.5])), warp)
    storyboard = sketchify(query, keyframes=4, noise=0.0, seed=1)
    match = retrieve(index, storyboard)
    assert index.windows[match.window][0] == 3 and match.yaw == pytest.approx(0.7, abs=0.03)
    retimed = adapt(index, match, storyboard, AdaptConfig(blend=False))
    keys = sorted({k.frame for k in storyboard.keyposes})
    np.testing.assert_allclose(retimed.source_frames[keys], warp[keys], atol=1.0)
    uniform = adapt(index, match, storyboard, UNIFORM)
    assert k2d(retimed.clip, storyboard) < 0.3 * k2d(uniform.clip, storyboard)


def test_blending_lowers_the_keypose_error_on_unseen_motion(index):
    query = scene_clip(100)
    storyboard = sketchify(query, keyframes=4, noise=0.3, seed=2)
    match = retrieve(index, storyboard)
    before = adherence(adapt(index, match, storyboard, UNIFORM).clip, storyboard)
    after = adherence(adapt(index, match, storyboard).clip, storyboard)
    assert after["K2D"] < 0.5 * before["K2D"]
    assert after["T2D"] < before["T2D"]


def test_index_save_load_keeps_retrieval(index, clips, tmp_path):
    index.save(tmp_path / "index.npz")
    loaded = RetrievalIndex.load(tmp_path / "index.npz")
    assert loaded.windows.tolist() == index.windows.tolist() and loaded.config == index.config
    np.testing.assert_array_equal(loaded.points, index.points)
    storyboard = sketchify(clips[1], keyframes=3, noise=0.2, seed=4)
    assert retrieve(loaded, storyboard) == retrieve(index, storyboard)


def test_streaming_form_yields_one_step(index, clips):
    storyboard = sketchify(clips[2], keyframes=3, noise=0.2, seed=7)
    gen = sample_retrieval(index, storyboard)
    event = next(gen)
    assert (event.step, event.num_steps, event.t) == (0, 1, 0.0)
    assert event.phase.shape == (storyboard.length, 3) and "retrieval_cost" in event.energies
    with pytest.raises(StopIteration) as stop:
        next(gen)
    result = stop.value.value
    assert result.clips == [event.preview] and result.network_evals == 0 and result.wall_time_s > 0

"""The headless renderer: people, object and ground land where the camera should see them;
contact sheets and GIFs are written. No Qt here."""
import json

import numpy as np
import pytest
from PIL import Image

from engine.clip import MotionClip
from engine.geometry.rotations import matrix_to_6d
from engine.skeleton import NUM_JOINTS, rest_pose

render = pytest.importorskip("engine.render")
from engine.render import OrbitCamera, RenderConfig, SceneRenderer, SceneState, scene_from_clip  # noqa: E402
from engine.render.example import carry_clip, carry_storyboard  # noqa: E402
from engine.render.sheets import clip_camera, write_contact_sheet, write_gif  # noqa: E402


def standing_apart_clip(frames: int = 2) -> MotionClip:
    """Person 0 at x = -1, person 1 at x = +1, both in rest pose, a box at the origin."""
    people = np.stack([rest_pose() + [-1.0, 0.0, 0.0], rest_pose() + [1.0, 0.0, 0.0]])
    joints = np.broadcast_to(people, (frames, 2, NUM_JOINTS, 3))
    pose = np.tile(np.array([0, 0, 0, 1, 0, 0, 0], np.float32), (frames, 1, 1))
    rot = matrix_to_6d(np.broadcast_to(np.eye(3), (frames, 2, NUM_JOINTS, 3, 3)))
    return MotionClip(fps=20.0, joints=joints, rot6d=rot, obj_pose=pose, obj_type=np.array(["box"]),
                      obj_size=np.array([[0.45, 0.35, 0.35]]))


@pytest.fixture(scope="module")
def renderer():
    try:
        r = SceneRenderer(320, 240)
    except render.RenderUnavailableError as e:
        pytest.skip(str(e))
    yield r
    r.release()


def classify(image: np.ndarray) -> dict[str, np.ndarray]:
    """Boolean masks (H, W) of agent-0 orange-red, agent-1 blue, wood and neutral grey pixels."""
    r, g, b = (image[..., i].astype(int) for i in range(3))
    spread = image[..., :3].max(-1).astype(int) - image[..., :3].min(-1)
    return {"red": (r - g > 90) & (g - b > 10), "blue": b - r > 60,
            "wood": (r - g > 20) & (r - g < 70) & (g - b > 25),
            "neutral": spread < 30}


def test_people_and_box_appear_where_the_camera_sees_them(renderer):
    camera = OrbitCamera(yaw=0.0, pitch=10.0, distance=5.0, target=(0.0, 0.8, 0.0))
    image = renderer.render(scene_from_clip(standing_apart_clip(), 0), camera).copy()
    assert image.shape == (240, 320, 4) and image.dtype == np.uint8
    masks = classify(image)
    for name, lo, hi in (("red", 0, 160), ("blue", 160, 320), ("wood", 107, 213)):
        ys, xs = np.nonzero(masks[name])
        assert len(xs) > 200, f"too few {name} pixels: {len(xs)}"
        assert np.mean((xs >= lo) & (xs < hi)) > 0.95, f"{name} pixels outside columns {lo}..{hi}"
    # Upright people: the head is above the feet, so red pixels span much of the height.
    ys = np.nonzero(masks["red"])[0]
    assert ys.max() - ys.min() > 80
    # Sky at the top and ground at the bottom are both neutral and differ from each other.
    assert masks["neutral"][:10].mean() > 0.99 and masks["neutral"][-10:, :40].mean() > 0.99
    assert np.abs(image[:10].astype(int).mean((0, 1)) - image[-10:].astype(int).mean((0, 1))).max() > 5


def test_orbiting_to_the_back_swaps_the_people(renderer):
    camera = OrbitCamera(yaw=180.0, pitch=10.0, distance=5.0, target=(0.0, 0.8, 0.0))
    masks = classify(renderer.render(scene_from_clip(standing_apart_clip(), 0), camera))
    assert np.nonzero(masks["red"])[1].mean() > 160 > np.nonzero(masks["blue"])[1].mean()


def test_overlays_and_default_framing(renderer):
    clip = carry_clip(12)
    scene = scene_from_clip(clip, 6, carry_storyboard(clip))
    assert scene.ghosts and scene.target_paths and scene.generated_paths and scene.contact.any()
    image = renderer.render(scene).copy()  # no camera: framed to fit
    bare = renderer.render(scene_from_clip(clip, 6))
    assert (np.abs(image.astype(int) - bare).sum(-1) > 30).mean() > 0.01  # overlays change pixels
    masks = classify(image)
    assert masks["red"].sum() > 100 and masks["blue"].sum() > 100


@pytest.mark.parametrize("yaw, pitch, aspect", [(35.0, 18.0, 4 / 3), (120.0, 40.0, 16 / 9), (0.0, 5.0, 0.75)])
def test_frame_all_fits_the_points_tightly(yaw, pitch, aspect):
    """Every point lands inside the picture, and the farthest out nearly on its edge."""
    rng = np.random.default_rng(int(yaw))
    points = rng.uniform([-3.0, 0.0, -1.0], [2.0, 1.8, 0.5], size=(200, 3))
    camera = OrbitCamera(yaw=yaw, pitch=pitch)
    camera.frame_all(points, aspect, pad=0.0, margin=1.0)
    clip = np.c_[points, np.ones(len(points))] @ (camera.projection_matrix(aspect) @ camera.view_matrix()).T
    ndc = np.abs(clip[:, :2] / clip[:, 3:])
    assert (clip[:, 3] > 0).all() and ndc.max() <= 1.0 + 1e-6
    assert ndc.max() > 0.98
    assert camera.sees(points, aspect, pad=0.0)                        # as its projection says
    grown = camera.target + 1.3 * (points - camera.target)
    assert not camera.sees(grown, aspect, pad=0.0)


def test_a_ghost_is_one_translucent_layer_over_the_scene(renderer):
    """A keyframe ghost of alpha a shows a * (the same pose drawn solid) + (1 - a) * what is
    behind it: one layer, however many of its capsules and spheres overlap."""
    camera = OrbitCamera(yaw=0.0, pitch=10.0, distance=5.0, target=(0.0, 0.8, 0.0))
    clip = standing_apart_clip()
    pose = clip.joints[0]
    empty = renderer.render(SceneState(), camera).astype(float)
    solid = renderer.render(SceneState(people=pose), camera).astype(float)
    half = SceneRenderer(320, 240, RenderConfig(ghost_alpha=0.5))
    ghost = half.render(SceneState(ghosts=[pose]), camera).astype(float)
    half.release()
    body = solid[..., :3].max(-1) - solid[..., :3].min(-1) > 80   # coloured: the people, not their shadow
    body[:, 1:] &= body[:, :-1]   # one pixel in from the outlines
    body[1:] &= body[:-1]
    assert body.sum() > 500
    error = np.abs(ghost - (0.5 * solid + 0.5 * empty))[..., :3][body].max(-1)
    assert (error <= 3).mean() > 0.995   # a stray pixel where two of its surfaces meet at equal depth


def test_cached_layers_follow_the_camera_and_the_scene(renderer):
    """The sky and ghost layers are kept between frames: after a new camera or new ghosts the
    picture is what a fresh renderer draws."""
    clip = carry_clip(12)
    board = carry_storyboard(clip)
    near = OrbitCamera(yaw=30.0, pitch=15.0, distance=4.0, target=(0.0, 0.8, 0.0))
    far = OrbitCamera(yaw=120.0, pitch=25.0, distance=6.0, target=(0.2, 0.7, 0.1))
    renderer.render(scene_from_clip(clip, 3, board), near)
    moved = renderer.render(scene_from_clip(clip, 3, board), far).copy()
    other = carry_clip(12)
    other.joints = other.joints + np.array([0.3, 0.0, 0.0], np.float32)   # other ghosts too
    changed = renderer.render(scene_from_clip(other, 3, board), far).copy()
    fresh = SceneRenderer(320, 240)
    assert np.array_equal(moved, fresh.render(scene_from_clip(clip, 3, board), far))
    assert np.array_equal(changed, fresh.render(scene_from_clip(other, 3, board), far))
    fresh.release()


def test_benchmark_prints_one_json_line(capsys):
    """`python -m engine.render.benchmark` reports times, never asserts them (shared machines)."""
    from engine.render.benchmark import main
    try:
        main(["--frames", "3", "--size", "160x90", "--orbit"])
    except render.RenderUnavailableError as e:
        pytest.skip(str(e))
    report = json.loads(capsys.readouterr().out)
    for key in ("scene_ms", "draw_ms", "readback_ms", "frame_ms"):
        assert 0 < report[key]["median"] <= report[key]["p95"]
    assert report["fps"] > 0 and report["size"] == [160, 90] and report["orbit"]
    assert report["gl_renderer"] and report["machine"]["cores"] >= 1


def test_contact_sheet_and_gif(tmp_path):
    clip = carry_clip(8)
    try:
        frames = write_contact_sheet(clip, tmp_path / "sheet.png", count=6, columns=3, tile=(96, 64))
        written = write_gif(clip, tmp_path / "clip.gif", size=(96, 64))
    except render.RenderUnavailableError as e:
        pytest.skip(str(e))
    assert frames == [0, 1, 3, 4, 6, 7]
    with Image.open(tmp_path / "sheet.png") as sheet:
        assert sheet.size == (3 * 96, 2 * 64)
    assert written == 8
    with Image.open(tmp_path / "clip.gif") as gif:
        assert gif.n_frames == 8


@pytest.mark.parametrize("angle", [0.0, 60.0, 150.0, 270.0])
def test_sheets_look_across_the_line_between_the_people(angle):
    clip = standing_apart_clip()
    turn = np.radians(angle)
    rot = np.array([[np.cos(turn), 0, np.sin(turn)], [0, 1, 0], [-np.sin(turn), 0, np.cos(turn)]])
    clip.joints = clip.joints @ rot.T
    right = clip_camera(clip, None, 1.5).basis()[0]
    pelvis = clip.joints[0, :, 0]
    assert (pelvis[1] - pelvis[0]) @ right == pytest.approx(2.0, abs=1e-6)   # side by side, first on the left


def test_strokes_of_a_longer_storyboard_than_the_motion_lie_at_rest_height():
    """The clip made before the storyboard was lengthened ends before a stroke starts (an undone
    length change): the stroke lies at the joint's rest height, not at NaN."""
    from dataclasses import replace

    from engine.render.scene import lift_storyboard_paths
    clip = carry_clip()
    storyboard = carry_storyboard(clip)
    late = [replace(t, start=clip.num_frames + 5, end=clip.num_frames + 20) for t in storyboard.trajectories]
    longer = replace(storyboard, length=clip.num_frames + 40, trajectories=late)
    paths = lift_storyboard_paths(longer, clip)
    assert paths and all(np.isfinite(p.points).all() for p in paths)

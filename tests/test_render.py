"""The headless renderer: people, object and ground land where the camera should see them;
contact sheets and GIFs are written. No Qt here."""
import time

import numpy as np
import pytest
from PIL import Image

from engine.clip import MotionClip
from engine.rotations import matrix_to_6d
from engine.skeleton import NUM_JOINTS, rest_pose

render = pytest.importorskip("engine.render")
from engine.render import OrbitCamera, SceneRenderer, scene_from_clip  # noqa: E402
from engine.render.example import carry_clip, carry_storyboard  # noqa: E402
from engine.render.sheets import write_contact_sheet, write_gif  # noqa: E402


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


def test_render_speed_is_reported():
    """Prints ms per 1280x720 frame (run with -s); never asserts a time on a shared machine."""
    try:
        r = SceneRenderer(1280, 720)
    except render.RenderUnavailableError as e:
        pytest.skip(str(e))
    clip = carry_clip(20)
    camera = OrbitCamera()
    camera.frame_all(scene_from_clip(clip, 0).bounds())
    scenes = [scene_from_clip(clip, f) for f in range(20)]
    r.render(scenes[0], camera)
    wall, cpu = time.perf_counter(), time.process_time()
    for s in scenes:
        image = r.render(s, camera)
    wall, cpu = (time.perf_counter() - wall) / 20, (time.process_time() - cpu) / 20
    print(f"\n1280x720, 2 people + box, playback: {wall * 1e3:.1f} ms/frame wall ({1 / wall:.0f} fps), "
          f"{cpu * 1e3:.1f} ms CPU over all threads")
    assert image.shape == (720, 1280, 4)
    r.release()


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

"""The artist-style check (engine.bench.artist_check): a put-down is told from a drop, a
wrist's miss at its key is told apart (the drawing's, the sketch plane's, depth), a jump from a
spike, and a held object's distance to its drawing is measured while it is held."""
import numpy as np

from engine.bench.animator import pop
from engine.bench.artist_check import held_off_drawing, largest_jump, release_drops, wrist_key_parts
from engine.camera import StoryboardCamera
from engine.clip import MotionClip
from engine.geometry.polylines import point_polyline_distance
from engine.objects import ObjectSpec
from engine.skeleton import JOINT_INDEX
from engine.storyboard import Agent, Contact, Keypose, ObjectKey, ObjectPath, SceneObject, Storyboard

N = 30


def carried(heights: np.ndarray) -> tuple[MotionClip, Storyboard]:
    """A box at heights (N,) held by one hand over frames 5-14 and 18-22."""
    sb = Storyboard(length=N, agents=[Agent("A")], objects=[SceneObject("box", ObjectSpec("box"))],
                    contacts=[Contact("A", "left", 5, 14, "box", 0), Contact("A", "left", 18, 22, "box", 0)])
    pose = np.zeros((N, 1, 7))
    pose[:, 0, 1], pose[:, 0, 3] = heights, 1.0
    return MotionClip(fps=20.0, joints=np.zeros((N, 1, 22, 3)), rot6d=np.zeros((N, 1, 22, 6)), obj_pose=pose), sb


def test_a_box_let_go_of_in_the_air_drops_and_one_set_down_does_not():
    dropped = np.zeros(N)
    dropped[5:15] = 0.4                          # let go 40 cm up at frame 14
    dropped[18:23] = 0.3                         # and 30 cm up at frame 22
    clip, sb = carried(dropped)
    np.testing.assert_allclose(release_drops(clip, sb), [0.4, 0.3])
    set_down = dropped.copy()
    set_down[14] = set_down[22] = 0.0           # lowered onto the floor as the hand lets go
    np.testing.assert_allclose(release_drops(*carried(set_down)), [0.0, 0.0])


def test_a_hold_to_the_end_is_no_release():
    heights = np.zeros(N)
    heights[5:] = 0.5
    clip, sb = carried(heights)
    sb.contacts = [Contact("A", "left", 5, N - 1, "box", 0)]
    assert release_drops(clip, sb) == []


def test_a_hold_ending_a_few_frames_before_the_end_is_carried_on_unless_the_sketch_puts_the_box_down():
    heights = np.zeros(N)
    heights[5:] = 0.5
    clip, sb = carried(heights)
    sb.contacts = [Contact("A", "left", 5, N - 4, "box", 0)]   # the artist's span 3 frames short of the end
    assert release_drops(clip, sb) == []                        # held.py holds it on to the end
    box = sb.objects[0].spec.size
    around = sb.camera.project(np.array([[x, y, 0.0] for x in (-box[0] / 2, box[0] / 2) for y in (0.5, 0.5 + box[1])]))
    sb.object_keys = [ObjectKey("box", N - 1, around)]         # drawn where the hands hold it at the end
    assert release_drops(clip, sb) == []
    sb.object_keys = [ObjectKey("box", N - 1, around + [1.0, -0.5])]   # drawn set down on the floor away
    np.testing.assert_allclose(release_drops(clip, sb), [0.5])


def test_a_wrist_miss_is_split_into_the_drawing_the_sketch_plane_and_depth():
    camera = StoryboardCamera(20.0, 30.0)
    right, up, back = camera.basis()
    wrist = JOINT_INDEX["l_wrist"]
    reference = np.zeros((N, 1, 22, 3))
    reference[10, 0, wrist] = [0.3, 1.0, 0.2]
    joints = reference.copy()
    joints[10, 0, wrist] += 0.05 * up + 0.2 * back           # 5 cm up in the sketch, 20 cm deeper
    mask = np.zeros(22, bool)
    mask[wrist] = True
    points = np.zeros((22, 2))
    points[wrist] = camera.project(reference[10, 0, wrist]) + [0.03, 0.0]   # drawn 3 cm right
    sb = Storyboard(length=N, agents=[Agent("A")], keyposes=[Keypose("A", 10, points, mask)], camera=camera)
    np.testing.assert_allclose(wrist_key_parts(joints, reference, sb), [0.03, np.hypot(0.03, 0.05), 0.2], atol=1e-9)
    sb.keyposes = []
    assert wrist_key_parts(joints, reference, sb) is None


def test_a_jump_is_a_step_beyond_both_neighbouring_steps_and_a_spike_is_none():
    joints = np.zeros((N, 1, 22, 3))
    joints[:, 0, :, 0] = 0.02 * np.arange(N)[:, None]      # 2 cm a frame
    jumped = joints.copy()
    jumped[15:, 0, :, 0] += 0.1                              # one step of 12 cm
    assert np.isclose(largest_jump(jumped), 0.1)
    spiked = joints.copy()
    spiked[15, 0, 3, 1] += 0.1                               # one joint 10 cm up for a frame, and back
    assert np.isclose(pop(spiked), 0.1)
    assert largest_jump(spiked) < 1e-9


def test_a_held_object_off_its_drawing_is_measured_in_the_sketch_plane_while_held():
    """The box held over frames 5-14 and 18-22: its base 10 cm above its drawn path there (the
    frames it is not held do not count), and its centre on the outline drawn at frame 8."""
    clip, sb = carried(np.full(N, 0.1))
    cam, size = sb.camera, sb.objects[0].spec.size
    ground = cam.project(np.array([[-1.0, 0.0, 0.0], [1.0, 0.0, 0.0]]))     # the path along x, on the floor
    sb.object_paths = [ObjectPath("box", 0, N - 1, ground)]
    centre = cam.project(np.array([0.0, 0.1 + size[1] / 2, 0.0]))
    sb.object_keys = [ObjectKey("box", 8, centre + np.array([[-0.2, -0.1], [0.2, -0.1], [0.2, 0.1], [-0.2, 0.1]]))]
    path_offs, outline_offs = held_off_drawing(clip, sb)
    assert len(path_offs) == 15 and len(outline_offs) == 1
    above = point_polyline_distance(cam.project(np.array([[0.0, 0.1, 0.0]])), ground)[0]
    assert 0.08 < above < 0.1                                                # 10 cm up, seen from above
    np.testing.assert_allclose(path_offs, above, rtol=1e-6)   # (a clip stores float32)
    np.testing.assert_allclose(outline_offs, 0.0, atol=1e-6)

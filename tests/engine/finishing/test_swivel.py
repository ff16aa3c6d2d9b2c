"""Finishing, swivel: an elbow whose arm passes through an object turns about the shoulder-wrist
line to where it does not, keeping both bones, and over frames gradually; so does a knee about
the hip-ankle line, and (after the steadying) an elbow wherever its arm is."""
import numpy as np

from engine.finishing.contacts import ContactConfig
from engine.finishing.swivel import LEG_RADII, clear_elbows, clear_knees, limb_penetration, swivel_clear
from engine.objects import ObjectSpec
from engine.skeleton import ANKLES, ELBOWS, HANDS, HIPS, KNEES, SHOULDERS, rest_pose


def test_an_elbow_in_an_object_swivels_out_keeping_its_bones():
    shoulder, wrist = np.array([[0.0, 1.4, 0.0]]), np.array([[0.45, 1.0, 0.0]])
    elbow = np.array([[0.3, 1.45, 0.0]])                   # bent up and out, into the box above
    box = ObjectSpec("box")
    pose = np.array([[[0.35, 1.3, 0.0, 1.0, 0.0, 0.0, 0.0]]])  # (M, O, 7): the box's base at 1.3 m
    before = limb_penetration(shoulder[:, None], elbow[:, None], wrist[:, None], pose, [box])
    one = [np.array([0])]                                  # one frame: a run of its own
    moved = swivel_clear(shoulder, elbow, wrist, pose, [box], ContactConfig(), one)
    after = limb_penetration(shoulder[:, None], moved[:, None], wrist[:, None], pose, [box])
    assert before[0, 0] > 0.05 and after[0, 0] <= 0.0
    clear = np.array([[0.15, 1.0, 0.1]])                   # an elbow already clear stays, exactly
    assert np.array_equal(swivel_clear(shoulder, clear, wrist, pose, [box], ContactConfig(), one), clear)
    for a, b in ((shoulder, elbow), (wrist, elbow)):
        np.testing.assert_allclose(np.linalg.norm(moved - a, axis=-1), np.linalg.norm(b - a, axis=-1))


def test_an_elbow_swivels_out_of_an_object_gradually_not_in_one_frame():
    """Over consecutive frames the swivel is chosen as a path: an arm that must clear a box
    from some frame on turns over several frames, never flipping by more than a few cm a frame."""
    n = 20
    shoulder, wrist = np.tile([0.0, 1.4, 0.0], (n, 1)), np.tile([0.45, 1.0, 0.0], (n, 1))
    elbow = np.tile([0.3, 1.45, 0.0], (n, 1))
    box = ObjectSpec("box")
    pose = np.tile([0.35, 1.3, 0.0, 1.0, 0.0, 0.0, 0.0], (n, 1, 1))
    pose[:10, 0, 1] = 3.0                                  # the box arrives at frame 10
    moved = swivel_clear(shoulder, elbow, wrist, pose, [box], ContactConfig(), [np.arange(n)])
    after = limb_penetration(shoulder[:, None], moved[:, None], wrist[:, None], pose, [box])
    assert after[:10].max() <= 0.0 and after[13:].max() <= 0.005   # clear within a few frames
    swing, steps = np.linalg.norm(moved[-1] - moved[0]), np.linalg.norm(np.diff(moved, axis=0), axis=-1)
    assert swing > 0.2 and steps.max() < 0.4 * swing      # a per-frame choice made it in one step


def test_a_knee_crouching_into_a_box_on_the_floor_swivels_out_and_the_feet_stay():
    """A person crouching beside a box on the floor, the left knee bent forward into it."""
    n = 6
    pose = np.tile(rest_pose(), (n, 1, 1, 1)).astype(float)       # (N, 1, 22, 3), facing +z
    hip, knee, ankle = HIPS[0], KNEES[0], ANKLES[0]
    thigh = np.linalg.norm(pose[0, 0, knee] - pose[0, 0, hip])
    pose[..., hip, :] = pose[..., ankle, :] + [0.0, 0.55, 0.0]    # crouched: the knee must bend
    half = np.linalg.norm(pose[0, 0, hip] - pose[0, 0, ankle]) / 2
    out_by = np.sqrt(thigh ** 2 - half ** 2)                      # the knee bent forward
    pose[..., knee, :] = (pose[..., hip, :] + pose[..., ankle, :]) / 2 + [0.0, 0.0, out_by]
    box = ObjectSpec("box")
    place = pose[0, 0, knee] + [0.0, -0.2, 0.15]                  # the box's base on the floor ahead
    obj_pose = np.tile([place[0], 0.0, place[2], 1.0, 0.0, 0.0, 0.0], (n, 1, 1))
    leg = lambda j: limb_penetration(j[:, 0, hip, None], j[:, 0, knee, None], j[:, 0, ankle, None], obj_pose, [box],
                                     LEG_RADII, ground=False)[:, 0]
    assert leg(pose).min() > 0.03
    out = clear_knees(pose, obj_pose, [box], ContactConfig())
    assert leg(out).max() < 0.01
    moved = np.any(out != pose, axis=-1)[0, 0]
    assert np.flatnonzero(moved).tolist() == [knee]               # hips, ankles and feet stay
    for a in (hip, ankle):
        np.testing.assert_allclose(np.linalg.norm(out[..., knee, :] - out[..., a, :], axis=-1),
                                   np.linalg.norm(pose[..., knee, :] - pose[..., a, :], axis=-1))
    far = obj_pose.copy()
    far[..., 0] += 2.0
    assert np.array_equal(clear_knees(pose, far, [box], ContactConfig()), pose)


def test_a_knee_one_frame_in_a_box_swings_out_and_back_over_frames():
    """A knee brushing a box for one frame swivels over the frames around it too, not 16 cm in one."""
    n = 15
    pose = np.tile(rest_pose(), (n, 1, 1, 1)).astype(float)
    hip, knee, ankle = HIPS[0], KNEES[0], ANKLES[0]
    thigh = np.linalg.norm(pose[0, 0, knee] - pose[0, 0, hip])
    pose[..., hip, :] = pose[..., ankle, :] + [0.0, 0.55, 0.0]
    half = np.linalg.norm(pose[0, 0, hip] - pose[0, 0, ankle]) / 2
    pose[..., knee, :] = (pose[..., hip, :] + pose[..., ankle, :]) / 2 + [0.0, 0.0, np.sqrt(thigh ** 2 - half ** 2)]
    place = pose[0, 0, knee] + [0.0, -0.2, 0.15]
    obj_pose = np.tile([place[0], 0.0, place[2], 1.0, 0.0, 0.0, 0.0], (n, 1, 1))
    obj_pose[np.arange(n) != 7, 0, 0] += 2.0                          # there at frame 7 only
    out = clear_knees(pose, obj_pose, [ObjectSpec("box")], ContactConfig())
    swing = np.linalg.norm(out[:, 0, knee] - pose[:, 0, knee], axis=-1)
    steps = np.linalg.norm(np.diff(out[:, 0, knee], axis=0), axis=-1)
    assert swing[7] > 0.05 and (swing[[6, 8]] > 0.0).all()            # turned either side too
    assert steps.max() < 0.6 * swing[7]                               # at once: all of it in a frame
    step = clear_knees(pose, obj_pose, [ObjectSpec("box")], ContactConfig(knee_ease_frames=0))
    assert np.linalg.norm(np.diff(step[:, 0, knee], axis=0), axis=-1).max() > 0.9 * swing[7]


def test_an_arm_through_a_box_swivels_out_and_only_its_elbow_moves():
    """clear_elbows, run on whole bodies after the steadying: the steadying turned forearms back
    into boxes beside their grips."""
    n = 6
    pose = np.tile(rest_pose(), (n, 1, 1, 1)).astype(float)              # (N, 1, 22, 3)
    shoulder, elbow, wrist = SHOULDERS[0], ELBOWS[0], HANDS[0]
    pose[..., shoulder, :], pose[..., wrist, :] = [0.0, 1.4, 0.0], [0.45, 1.0, 0.0]
    pose[..., elbow, :] = [0.3, 1.45, 0.0]                                 # bent up into the box
    box = ObjectSpec("box")
    obj_pose = np.tile([0.35, 1.3, 0.0, 1.0, 0.0, 0.0, 0.0], (n, 1, 1))
    arm = lambda j: limb_penetration(j[:, 0, shoulder, None], j[:, 0, elbow, None], j[:, 0, wrist, None],
                                     obj_pose, [box])[:, 0]
    assert arm(pose).min() > 0.05
    out = clear_elbows(pose, obj_pose, [box], ContactConfig())
    assert arm(out).max() <= 0.0
    assert np.flatnonzero(np.any(out != pose, axis=-1)[0, 0]).tolist() == [elbow]
    for a in (shoulder, wrist):
        np.testing.assert_allclose(np.linalg.norm(out[..., elbow, :] - out[..., a, :], axis=-1),
                                   np.linalg.norm(pose[..., elbow, :] - pose[..., a, :], axis=-1))
    obj_pose[..., 0] += 2.0
    assert np.array_equal(clear_elbows(pose, obj_pose, [box], ContactConfig()), pose)

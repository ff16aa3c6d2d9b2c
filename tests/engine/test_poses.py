"""The pose library (engine/poses.py): every pose keeps the rest skeleton's bones, stands on the
floor and faces +Z; its 2D figure is what the camera sees of it."""
import numpy as np
import pytest

from engine.camera import StoryboardCamera
from engine.poses import POSE_NAMES, library_pose, library_pose_2d
from engine.skeleton import FEET, JOINT_INDEX, PARENTS, rest_pose
from engine.synth.reach import yaw_matrix


def bones(p):
    return np.linalg.norm(p[1:] - p[list(PARENTS[1:])], axis=-1)


@pytest.mark.parametrize("name", POSE_NAMES)
def test_library_poses_are_the_rest_skeleton_standing_on_the_floor(name):
    pose = library_pose(name)
    np.testing.assert_allclose(bones(pose), bones(rest_pose()), atol=1e-9)
    assert pose[list(FEET), 1].min() == pytest.approx(0.02, abs=0.03)           # a foot on the floor
    assert pose[JOINT_INDEX["head"], 1] > pose[JOINT_INDEX["pelvis"], 1]


def test_the_figures_are_the_poses_seen_through_the_camera():
    camera = StoryboardCamera()
    for name in POSE_NAMES:
        uv = library_pose_2d(name, camera)
        seen = camera.project(library_pose(name))
        np.testing.assert_allclose(uv - uv[0], seen - seen[0], atol=1e-12)
    crouch, stand = library_pose_2d("crouch-reach", camera), library_pose_2d("stand", camera)
    assert crouch[0, 1] < stand[0, 1] - 0.2                                     # the pelvis is lower


def test_a_pose_reaching_for_the_floor_bends_at_the_hips_and_knees_to_get_there():
    """Hands asked to reach a box's grips 15 cm off the floor, 45 cm ahead: the crouch-reach's own
    hands stop at 40 cm. The trunk bends and the knees go lower until the grips are within 90% of
    an arm's length; bones and feet stay."""
    wrists = [JOINT_INDEX["l_wrist"], JOINT_INDEX["r_wrist"]]
    own = library_pose("crouch-reach", 0.3)
    grips = np.array([[0.12, 0.15, 0.45], [-0.12, 0.15, 0.45]]) @ yaw_matrix(np.array(0.3)).T
    reached = library_pose("crouch-reach", 0.3, grips, reach=0.9)
    np.testing.assert_allclose(reached[wrists], grips, atol=1e-3)
    np.testing.assert_allclose(bones(reached), bones(rest_pose()), atol=1e-9)
    np.testing.assert_allclose(reached[list(FEET)], own[list(FEET)], atol=1e-9)
    assert own[wrists, 1].min() > 0.35
    assert reached[JOINT_INDEX["head"], 1] < own[JOINT_INDEX["head"], 1] - 0.3     # bent over
    np.testing.assert_allclose(library_pose("crouch-reach", 0.3, own[wrists]), own, atol=1e-9)   # nothing to reach

"""The pose library (engine/poses.py): every pose keeps the rest skeleton's bones, stands on the
floor and faces +Z; its 2D figure is what the camera sees of it."""
import numpy as np
import pytest

from engine.camera import StoryboardCamera
from engine.poses import POSE_NAMES, library_pose, library_pose_2d
from engine.skeleton import FEET, JOINT_INDEX, PARENTS, rest_pose


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

"""Facing: a sketched figure lifted, measured and turned about the vertical."""
import numpy as np

from engine.camera import StoryboardCamera
from engine.facing import depth_of, facing, lift, moved_depth, turned
from engine.poses import library_pose, standing_pose_2d
from engine.skeleton import FEET


def test_a_posed_figure_lifts_back_to_its_pose_and_turns_by_the_angle():
    camera = StoryboardCamera()
    pose = library_pose("walk stride")
    pose = pose - (0.0, pose[list(FEET), 1].mean(), 0.0)          # feet on the ground
    points, depth = camera.project(pose), depth_of(pose, camera)
    lifted = lift(points, camera, depth)
    np.testing.assert_allclose(lifted, pose, atol=1e-9)             # the pose, exactly
    for angle in (0.4, -1.2, 2.5):
        after, after_depth = turned(points, camera, angle, depth)
        change = facing(lift(after, camera, after_depth)) - facing(pose)
        assert abs(np.angle(np.exp(1j * (change - angle)))) < 1e-6
        assert np.allclose(after[list(FEET)].mean(0), points[list(FEET)].mean(0))   # it turns in place
        back, back_depth = turned(after, camera, -angle, after_depth)
        assert np.allclose(back, points) and np.allclose(back_depth, depth)


def test_a_flat_figure_faces_the_camera_or_away_and_turns_side_on():
    camera = StoryboardCamera(azimuth_deg=0.0)                    # looking from +Z
    front = standing_pose_2d(camera)
    yaw = facing(lift(front, camera))
    assert min(abs(yaw), abs(abs(yaw) - np.pi)) < 1e-6           # square to the view
    side, depth = turned(front, camera, np.pi / 2)
    assert np.ptp(side[:, 0]) < 0.1 * np.ptp(front[:, 0])         # seen from the side: narrow
    assert abs(abs(facing(lift(side, camera, depth)) - yaw) - np.pi / 2) < 1e-6


def test_a_dragged_joint_keeps_its_bones_in_depth():
    """A hand dragged on a stamped figure kept the stamp's depth, its forearm stretched or
    shrunk in 3D; each moved joint slides along its ray to keep its bone, the others stay."""
    from engine.rig import drag_pose
    from engine.skeleton import JOINT_INDEX, PARENTS
    camera = StoryboardCamera()
    pose = library_pose("hand over", 0.8)
    points, depth = camera.project(pose), depth_of(pose, camera)
    wrist = JOINT_INDEX["r_wrist"]
    after = drag_pose(points, np.ones(len(points), bool), wrist, points[wrist] + (0.15, -0.2), "rig",
                      template=standing_pose_2d(camera))
    moved = np.linalg.norm(after - points, axis=-1) > 1e-9
    assert moved.sum() >= 2
    bones = lambda p: np.linalg.norm(p[1:] - p[list(PARENTS[1:])], axis=-1)
    new = moved_depth(points, depth, after, camera)
    drawn = bones(after)                       # a bone can be no shorter in 3D than on the sketch
    np.testing.assert_allclose(bones(lift(after, camera, new)), np.maximum(bones(lift(points, camera, depth)), drawn), atol=1e-6)
    assert np.abs(bones(lift(after, camera, depth)) - bones(lift(points, camera, depth))).max() > 0.01
    for j in range(1, len(PARENTS)):           # a joint whose parent moved moves with it
        moved[j] |= moved[PARENTS[j]]
    np.testing.assert_allclose(new[~moved] - new[list(FEET)].mean(), depth[~moved] - depth[list(FEET)].mean(), atol=1e-9)

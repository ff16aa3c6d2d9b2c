"""Skeleton, rotations and scene flattening: round trips as properties."""
import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from engine.geometry import rotations as rot
from engine.skeleton import (FEET, JOINT_INDEX, MIRROR, NUM_JOINTS, PARENTS, REST_OFFSETS, REST_PELVIS_HEIGHT,
                             bone_lengths, fit_offsets, forward_kinematics, inverse_kinematics, rest_pose)
from engine.state_vector import SceneLayout

finite = st.floats(-3.0, 3.0, allow_nan=False, width=64)
rotvecs = arrays(np.float64, (4, NUM_JOINTS, 3), elements=st.floats(-2.5, 2.5, width=64))


def test_hierarchy_is_topological_and_mirrored():
    assert PARENTS[0] == -1 and all(p < j for j, p in enumerate(PARENTS) if j)
    assert all(MIRROR[MIRROR[j]] == j for j in range(NUM_JOINTS))
    assert MIRROR[JOINT_INDEX["l_wrist"]] == JOINT_INDEX["r_wrist"]


def test_rest_pose_stands_on_ground_facing_z_with_left_at_plus_x():
    p = rest_pose()
    assert abs(p[:, 1].min() - 0.02) < 1e-9 and np.allclose(p[list(FEET), 1], 0.02)
    assert p[JOINT_INDEX["l_hip"], 0] > p[JOINT_INDEX["r_hip"], 0]
    assert p[JOINT_INDEX["l_foot"], 2] > p[JOINT_INDEX["l_ankle"], 2]  # toes point to +Z
    assert 1.45 < p[JOINT_INDEX["head"], 1] < 1.65
    assert p[0, 1] == REST_PELVIS_HEIGHT


@settings(max_examples=40, deadline=None)
@given(arrays(np.float64, (6,), elements=st.floats(-10, 10, width=64)))
def test_6d_round_trip(v):
    if np.linalg.norm(v[:3]) < 1e-3 or np.linalg.norm(np.cross(v[:3], v[3:])) < 1e-3:
        return  # degenerate 6D input has no rotation
    R = rot.sixd_to_matrix(v)
    assert np.allclose(R @ R.T, np.eye(3), atol=1e-9) and np.isclose(np.linalg.det(R), 1)
    assert np.allclose(rot.sixd_to_matrix(rot.matrix_to_6d(R)), R, atol=1e-9)


@settings(max_examples=40, deadline=None)
@given(arrays(np.float64, (8, 3), elements=st.floats(-3, 3, width=64)))
def test_quaternion_round_trip(aa):
    R = rot.axis_angle_to_matrix(aa)
    q = rot.matrix_to_quat(R)
    assert np.allclose(np.linalg.norm(q, axis=-1), 1) and np.all(q[:, 0] >= 0)
    assert np.allclose(rot.quat_to_matrix(q), R, atol=1e-9)


@settings(max_examples=30, deadline=None)
@given(arrays(np.float64, (3,), elements=st.floats(-85, 85, width=64)),
       st.sampled_from(["XYZ", "ZXY", "ZYX", "YXZ", "YZX", "XZY"]))
def test_euler_round_trip(angles, order):
    R = rot.euler_to_matrix(angles, order)
    assert np.allclose(rot.matrix_to_euler(R, order), angles, atol=1e-7)


@settings(max_examples=25, deadline=None)
@given(rotvecs, arrays(np.float64, (4, 3), elements=finite))
def test_fk_ik_round_trip(aa, root):
    joints = forward_kinematics(root, rot.axis_angle_to_matrix(aa))
    local = inverse_kinematics(joints)
    assert np.allclose(forward_kinematics(joints[:, 0], local), joints, atol=1e-9)
    assert np.allclose(bone_lengths(joints), bone_lengths(rest_pose()), atol=1e-9)


@settings(max_examples=10, deadline=None)
@given(rotvecs, arrays(np.float64, (4, 3), elements=finite))
def test_ik_keeps_a_given_pelvis_rotation(aa, root):
    """Given the true pelvis rotations, IK keeps them and still reproduces the joints; given
    others, the pelvis takes them and the limbs still point at their joints."""
    rotations = rot.axis_angle_to_matrix(aa)
    joints = forward_kinematics(root, rotations)
    kept = inverse_kinematics(joints, root=rotations[:, 0])
    assert np.allclose(kept[:, 0], rotations[:, 0]) and np.allclose(forward_kinematics(root, kept), joints, atol=1e-9)
    turned = rot.axis_angle_to_matrix(np.array([0.0, 0.5, 0.0])) @ rotations[:, 0]
    again = forward_kinematics(root, inverse_kinematics(joints, root=turned))
    knee, ankle = JOINT_INDEX["l_knee"], JOINT_INDEX["l_ankle"]
    shin = again[:, ankle] - again[:, knee]
    wanted = joints[:, ankle] - joints[:, knee]
    assert np.allclose(shin / np.linalg.norm(shin, axis=-1, keepdims=True),
                       wanted / np.linalg.norm(wanted, axis=-1, keepdims=True), atol=1e-9)


@settings(max_examples=10, deadline=None)
@given(rotvecs, st.floats(0.8, 1.2), arrays(np.float64, (3,), elements=st.floats(-0.03, 0.03)))
def test_fit_offsets_recovers_a_different_body(aa, scale, hip_shift):
    """Imported people have their own proportions; FK(IK) must still reproduce them."""
    offsets = REST_OFFSETS * scale
    offsets[JOINT_INDEX["l_hip"]] += hip_shift
    joints = forward_kinematics(np.zeros((4, 3)), rot.axis_angle_to_matrix(aa), offsets)
    fitted = fit_offsets(joints)
    again = forward_kinematics(joints[:, 0], inverse_kinematics(joints, fitted), fitted)
    assert np.abs(again - joints).max() < 1e-6


@settings(max_examples=20, deadline=None)
@given(st.integers(1, 3), st.lists(st.integers(1, 4), max_size=2), st.integers(1, 5), st.data())
def test_scene_flatten_round_trip(h, anchors, n, data):
    layout = SceneLayout(h, tuple(anchors))
    rng = np.random.default_rng(data.draw(st.integers(0, 2**31)))
    joints, r6 = rng.normal(size=(n, h, 22, 3)), rng.normal(size=(n, h, 22, 6))
    pose = rng.normal(size=(n, len(anchors), 7))
    anc = [rng.normal(size=(n, k, 3)) for k in anchors]
    flat = layout.flatten(joints, r6, pose, anc)
    assert flat.shape == (n, h * 22 * 9 + 7 * len(anchors) + 3 * sum(anchors)) == (n, layout.dim)
    j2, r2, p2, a2 = layout.unflatten(flat)
    assert np.array_equal(j2, joints) and np.array_equal(r2, r6)
    if anchors:
        assert np.array_equal(p2, pose) and all(np.array_equal(x, y) for x, y in zip(a2, anc))


def test_fit_offsets_fits_each_person_of_a_scene_apart():
    """(N, H, 22, 3) gives each person the body (N, 22, 3) alone would."""
    rng = np.random.default_rng(3)
    bodies = [REST_OFFSETS * 0.9, REST_OFFSETS * 1.1]
    joints = np.stack([forward_kinematics(rng.normal(size=(6, 3)), rot.axis_angle_to_matrix(0.4 * rng.normal(size=(6, 22, 3))), body)
                       for body in bodies], 1)
    together = fit_offsets(joints)
    for h in range(2):
        np.testing.assert_allclose(together[h], fit_offsets(joints[:, h]), atol=1e-12)
        np.testing.assert_allclose(together[h], bodies[h], atol=1e-6)


def test_ik_of_people_with_their_own_bodies_round_trips_even_through_a_bone_turned_half_round():
    """(N, H, 22, 3) with offsets (H, 22, 3): the IK walks the offsets unbroadcast; a forearm
    folded straight back along its rest direction (the antiparallel case of rotation_between)
    still comes back exactly."""
    rng = np.random.default_rng(5)
    bodies = np.stack([REST_OFFSETS * 0.9, REST_OFFSETS * 1.1])                      # (2, 22, 3)
    rotations = np.broadcast_to(np.eye(3), (5, 2, 22, 3, 3)).copy()   # rest poses: the IK's frames are theirs
    rotations[2, 1, JOINT_INDEX["l_elbow"]] = rot.axis_angle_to_matrix(np.array([0.0, 0.0, np.pi]))
    joints = forward_kinematics(rng.normal(size=(5, 2, 3)), rotations, bodies)
    np.testing.assert_allclose(forward_kinematics(joints[:, :, 0], inverse_kinematics(joints, bodies), bodies),
                               joints, atol=1e-9)

"""A pelvis heading that flips in a frame is spread over the frames around it, on the same feet; spins stay."""
import numpy as np

from engine.finishing.feet import reach_with_legs
from engine.finishing.turns import FLIP, SPREAD, spread_flips
from engine.skeleton import ANKLES, FEET, HIPS, KNEES, REST_OFFSETS, REST_PELVIS_HEIGHT, forward_kinematics, inverse_kinematics
from engine.synth.reach import heading_of, yaw_matrix


def turning(yaw: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A person standing in the rest pose, turned by yaw (N,) -> (joints (N, 22, 3), IK rotations)."""
    n = len(yaw)
    rotations = np.broadcast_to(np.eye(3), (n, 22, 3, 3)).copy()
    rotations[:, 0] = yaw_matrix(yaw)
    joints = forward_kinematics(np.tile([0.0, REST_PELVIS_HEIGHT, 0.0], (n, 1)), rotations)
    return joints, inverse_kinematics(joints)


def heading_steps(rotations: np.ndarray) -> np.ndarray:
    return np.abs(np.angle(np.exp(1j * np.diff(heading_of(rotations[:, 0, :, 2])))))


def test_a_half_turn_in_one_frame_is_spread_and_the_rest_left_exactly():
    yaw = np.where(np.arange(40) < 20, 0.0, np.deg2rad(170.0))
    joints, rotations = turning(yaw)
    out, frames = spread_flips(joints, rotations, REST_OFFSETS)
    assert np.array_equal(frames, np.arange(20 - SPREAD - 1, 20 + SPREAD + 1))
    assert heading_steps(rotations).max() > FLIP
    assert heading_steps(out).max() < np.deg2rad(170.0) / (2 * SPREAD)      # about 170 / 10 degrees a frame
    assert np.allclose(heading_of(out[[0, -1], 0, :, 2]), heading_of(rotations[[0, -1], 0, :, 2]))   # the same turn
    far = np.r_[0:20 - SPREAD - 1, 20 + SPREAD + 1:40]
    assert np.array_equal(out[far], rotations[far])
    hips = forward_kinematics(joints[:, 0], out, REST_OFFSETS)[:, HIPS[0]]
    assert np.linalg.norm(np.diff(hips, axis=0), axis=-1).max() < 0.05    # flipped, the hip jumped 14 cm


def test_a_spin_and_a_steady_turn_stay_as_fitted():
    frames = np.arange(40)
    spin = np.deg2rad(170.0) * ((frames >= 18).astype(float) + (frames >= 24))   # two flips 6 frames apart
    joints, rotations = turning(spin)
    assert np.array_equal(spread_flips(joints, rotations, REST_OFFSETS)[0], rotations)
    joints, rotations = turning(np.deg2rad(60.0) * frames / 10)                  # 6 degrees a frame
    assert spread_flips(joints, rotations, REST_OFFSETS)[0] is rotations


def test_the_legs_of_a_turned_pelvis_keep_their_feet():
    n = 6
    root = np.tile([0.0, REST_PELVIS_HEIGHT, 0.0], (n, 1))
    rotations = np.broadcast_to(np.eye(3), (n, 22, 3, 3)).copy()
    feet = forward_kinematics(root, rotations)[:, list(FEET)] + [0.0, 0.08, 0.0]   # within reach of bent knees
    rotations[:, 0] = yaw_matrix(np.deg2rad(np.linspace(10.0, 60.0, n)))
    turned = forward_kinematics(root, rotations)                      # the whole body turned, feet swung round
    assert np.linalg.norm(turned[:, list(FEET)] - feet, axis=-1).max() > 0.05
    kept = reach_with_legs(turned, feet)
    assert np.linalg.norm(kept[:, list(FEET)] - feet, axis=-1).max() < 1e-3
    legs = [(h, k) for h, k in zip(HIPS, KNEES)] + [(k, a) for k, a in zip(KNEES, ANKLES)]
    for a, b in legs:
        assert np.allclose(np.linalg.norm(kept[:, a] - kept[:, b], axis=-1), np.linalg.norm(turned[:, a] - turned[:, b], axis=-1))
    upper = [j for j in range(22) if j not in set(KNEES) | set(ANKLES) | set(FEET)]
    assert np.array_equal(kept[:, upper], turned[:, upper])

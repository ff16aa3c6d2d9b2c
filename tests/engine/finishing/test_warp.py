"""Motion warping onto keyposes (engine/finishing/warp.py) and the finishing pass."""
import numpy as np
import pytest
from scipy.ndimage import maximum_filter1d

from engine.artist_sketch import hand_drawn
from engine.bench.animator import pop
from engine.controls import build_controls
from engine.finishing import consistent_skeleton, finish
from engine.finishing.keys import spread
from engine.finishing.limbs import LIMBS
from engine.finishing.steady import SteadyConfig, frame_pops
from engine.finishing.warp import (BODY_PARTS, WarpConfig, scale_per_bone, sketched_scales, solve_keypose,
                                  warp_to_keyposes)
from engine.geometry.rotations import axis_angle_to_matrix
from engine.metrics import keypose_errors_2d
from engine.skeleton import ELBOWS, HANDS, JOINT_INDEX, bone_lengths, fit_offsets, forward_kinematics, inverse_kinematics
from engine.sketchify import sketchify
from engine.synth import synthesize


@pytest.fixture(scope="module")
def scene():
    clip = synthesize("carry_together", 3, fps=20)
    return clip, sketchify(clip, 4, 0.0, 3)


def disturbed(joints: np.ndarray, seed: int = 0) -> np.ndarray:
    """The motion with a slow drift of each person and a bent pose: what a rough generator makes."""
    rng = np.random.default_rng(seed)
    n = len(joints)
    drift = np.cumsum(rng.normal(0, 0.01, (n, joints.shape[1], 1, 3)), 0) * (1, 0, 1)
    out = joints + drift
    out[:, :, 16:, :] += 0.05 * np.sin(np.linspace(0, 3, n))[:, None, None, None]  # arms off
    return out


def test_spread_is_exact_at_keys_linear_between_and_fades_outside():
    out = spread(40, [10, 20], np.array([[1.0], [3.0]]), falloff=5)
    assert out[10, 0] == pytest.approx(1.0) and out[20, 0] == pytest.approx(3.0)
    assert out[15, 0] == pytest.approx(2.0)
    assert out[4, 0] == 0.0 and out[26, 0] == 0.0 and 0 < out[7, 0] < 1


@pytest.mark.parametrize("drawn, expected", [(1.0, 1.0), (1.05, 1.05), (0.8, 1.0), (1.4, 1.1)])
def test_sketched_scales_grow_a_body_the_sketch_shows_larger_by_at_most_a_tenth(scene, drawn, expected):
    clip, sb = scene
    offsets = fit_offsets(clip.joints[:, 0].astype(float), iterations=1) / drawn   # the model drew it smaller
    assert sketched_scales(offsets, clip.joints[:, 0].astype(float), sb, 0) == pytest.approx(dict.fromkeys(BODY_PARTS, expected), abs=0.03)


def test_arms_drawn_longer_grow_the_arms_and_leave_the_legs_and_the_pelvis_height(scene):
    """A person built unlike the decoder's bodies (a salsa dancer's long arms) keeps the legs the
    sketch shows: grown with the arms, they lifted the pelvis and pushed it along the camera ray."""
    clip, sb = scene
    own = fit_offsets(clip.joints[:, 0].astype(float), iterations=1)
    arms = scale_per_bone({"legs": 1.0, "arms": 1.3, "trunk": 1.0})
    scales = sketched_scales(own / arms[:, None], clip.joints[:, 0].astype(float), sb, 0)   # drawn short arms
    assert scales["arms"] == pytest.approx(1.1, abs=0.01)
    assert scales["legs"] == pytest.approx(1.0, abs=0.03) and scales["trunk"] == pytest.approx(1.0, abs=0.03)
    joints = clip.joints.astype(float)
    short_arms = joints.copy()
    short_arms[:, 0] = forward_kinematics(joints[:, 0, 0], inverse_kinematics(joints[:, 0], own / arms[:, None]),
                                          own / arms[:, None])
    fixed, offsets = consistent_skeleton(short_arms, sb)
    assert np.abs(fixed[:, 0, 0, 1] - joints[:, 0, 0, 1]).max() < 0.01          # pelvis height kept
    grown = np.linalg.norm(offsets[0], axis=-1) / np.linalg.norm(own / arms[:, None], axis=-1).clip(1e-9)
    assert grown[[16, 18, 20]] == pytest.approx(1.1, abs=0.02) and grown[[4, 7]] == pytest.approx(1.0, abs=0.03)


def test_solve_keypose_lands_on_the_sketch_with_the_feet_on_the_ground_and_the_bones_nearly_kept(scene):
    clip, sb = scene
    joints, offsets = consistent_skeleton(disturbed(clip.joints))
    key = sb.keyposes[0]
    h = sb.agent_index(key.agent)
    lengths = np.linalg.norm(offsets[h], axis=-1)
    posed = solve_keypose(joints[key.frame, h], key.points, key.mask, sb.camera, lengths)
    assert np.abs(sb.camera.project(posed) - key.points)[key.mask].max() < 1e-9
    change = np.abs(bone_lengths(posed)[1:] - lengths[1:])   # the warp's refit restores them exactly
    assert change.mean() < 0.01 and change.max() < 0.06
    assert posed[[10, 11], 1].min() == pytest.approx(0.02, abs=1e-9)


def test_solve_keypose_places_a_pose_drawn_at_the_wrong_depth_by_its_standing_feet(scene):
    """The generated pose is the true one slid 40 cm along the viewing direction and lifted
    10 cm: the sketch (the true pose's projection) says nothing of depth, the ground does. The
    bone-length route picked each bone's depth from its sketched length and missed by
    decimetres once the bones were a few percent off."""
    clip, sb = scene
    joints, offsets = consistent_skeleton(clip.joints.astype(float))
    back = sb.camera.basis()[2]
    for key in sb.keyposes:
        h = sb.agent_index(key.agent)
        truth = joints[key.frame, h]
        if truth[[10, 11], 1].max() > 0.05:       # one foot up: depth is then only as good as the pose
            continue
        lengths = np.linalg.norm(offsets[h], axis=-1) * 1.03   # the decoder's bones are a little off
        drawn = truth + 0.4 * back + (0.0, 0.1, 0.0)
        posed = solve_keypose(drawn, key.points, key.mask, sb.camera, lengths)
        assert np.linalg.norm(posed - truth, axis=-1).max() < 0.03


def test_a_keypose_whose_depths_are_known_is_solved_at_them(scene):
    """A stamped or turned pose carries its joints' depths (Keypose.depth, the app's): the
    generated pose, a standing one in another place, says nothing of a crouch leaning towards a
    box, and solved by its depths the pose missed it by decimetres."""
    from engine.facing import depth_of
    from engine.poses import library_pose
    from engine.skeleton import rest_pose
    _, sb = scene
    truth = library_pose("crouch-reach", 0.7, np.array([[0.3, 0.15, 0.3], [0.1, 0.15, 0.4]]), reach=0.9) + (0.3, 0.0, -0.4)
    generated = rest_pose() + (0.5, 0.0, 0.2)
    uv, mask = sb.camera.project(truth), np.ones(len(truth), bool)
    lengths = bone_lengths(truth)
    guessed = solve_keypose(generated, uv, mask, sb.camera, lengths)
    known = solve_keypose(generated, uv, mask, sb.camera, lengths, known=depth_of(truth, sb.camera))
    assert np.linalg.norm(guessed - truth, axis=-1).max() > 0.2
    assert np.linalg.norm(known - truth, axis=-1).max() < 0.03
    np.testing.assert_allclose(sb.camera.project(known), uv, atol=1e-9)


def test_a_sketched_ankle_the_generated_depths_would_sink_stays_above_the_floor_on_its_drawn_point(scene):
    """Seen from above, an ankle whose generated depth is behind its drawn foot's lies lower on
    its ray: solved by the generated depth differences, posed heels sank 8 cm into the floor."""
    clip, sb = scene
    joints, offsets = consistent_skeleton(clip.joints.astype(float))
    back = sb.camera.basis()[2]
    ankle = JOINT_INDEX["l_ankle"]
    key = next(k for k in sb.keyposes if k.mask[ankle] and joints[k.frame, sb.agent_index(k.agent), 10, 1] < 0.05)
    h = sb.agent_index(key.agent)
    generated = joints[key.frame, h].copy()
    generated[ankle] -= 0.4 * back                       # the ankle further along its ray, away from the camera
    lengths = np.linalg.norm(offsets[h], axis=-1)
    posed = solve_keypose(generated, key.points, key.mask, sb.camera, lengths)
    sunk = solve_keypose(generated, key.points, key.mask, sb.camera, lengths, WarpConfig(ankle_floor=-np.inf))
    assert sunk[ankle, 1] < 0.0                           # where the depth differences alone put it
    assert posed[ankle, 1] >= WarpConfig().ankle_floor - 1e-9
    np.testing.assert_allclose(sb.camera.project(posed)[key.mask], key.points[key.mask], atol=1e-9)


def test_solve_keypose_slides_the_arms_with_the_body_when_the_spine_and_collars_are_unplaced(scene):
    """Artists often leave the spine and collars out: the shoulders then still ride on the
    pelvis as the ground places the figure (linked only to their own unplaced parents, the arms
    stayed at the generated depth while the legs slid 40 cm along the rays)."""
    clip, sb = scene
    joints, offsets = consistent_skeleton(clip.joints.astype(float))
    back = sb.camera.basis()[2]
    unplaced = [JOINT_INDEX[name] for name in ("spine1", "spine2", "spine3", "l_collar", "r_collar")]
    for key in sb.keyposes:
        h = sb.agent_index(key.agent)
        truth = joints[key.frame, h]
        if truth[[10, 11], 1].max() > 0.05:
            continue
        mask = key.mask.copy()
        mask[unplaced] = False
        lengths = np.linalg.norm(offsets[h], axis=-1)
        posed = solve_keypose(truth + 0.4 * back, key.points, mask, sb.camera, lengths)
        assert np.linalg.norm(posed - truth, axis=-1).max() < 0.03


def test_warp_to_keyposes_passes_through_every_keypose_and_keeps_the_skeleton(scene):
    clip, sb = scene
    joints, offsets = consistent_skeleton(disturbed(clip.joints))
    c = build_controls(sb)
    before = keypose_errors_2d(joints, c.kp2d, c.kp_mask, sb.camera).mean()
    warped = warp_to_keyposes(joints, offsets, sb)
    after = keypose_errors_2d(warped, c.kp2d, c.kp_mask, sb.camera).mean()
    assert after < 0.03 < before
    for h in range(2):
        np.testing.assert_allclose(bone_lengths(warped[:, h])[:, 1:],
                                   np.broadcast_to(np.linalg.norm(offsets[h], axis=-1)[1:], (len(warped), 21)),
                                   atol=1e-9)
    assert np.isfinite(warped).all()


def test_the_wrists_of_a_figure_drawn_out_of_proportion_land_on_their_drawn_points(scene):
    """A drawn figure stretched by up to 12% has bones the skeleton cannot match: the refit that
    keeps the skeleton left the wrists 4-5 cm off their drawn points; the arms reach for them,
    the elbows bending the way the drawing bends them (3.8 cm off before, 3.0 now)."""
    clip, clean = scene
    sb = hand_drawn(clean, seed=1)
    joints, offsets = consistent_skeleton(disturbed(clip.joints), sb)
    warped = warp_to_keyposes(joints, offsets, sb)

    def misses(chain):
        return [np.linalg.norm(sb.camera.project(warped[k.frame, sb.agent_index(k.agent), j]) - k.points[j])
                for k in sb.keyposes for j in chain if k.mask[j]]
    assert np.median(misses(HANDS)) < 0.002 and np.mean(misses(HANDS)) < 0.01
    assert np.mean(misses(ELBOWS)) < 0.033
    for h in range(2):
        np.testing.assert_allclose(bone_lengths(warped[:, h])[:, 1:],
                                   np.broadcast_to(np.linalg.norm(offsets[h], axis=-1)[1:], (len(warped), 21)),
                                   atol=1e-9)


def test_a_keypose_the_body_leans_into_keeps_the_legs_under_it_between_keys(scene):
    """The generated upper body bent 70 degrees forward about the pelvis (legs untouched) while
    the sketch shows it upright: between keys the warp straightens the torso part way, and the
    feet stay where they stood (a rotation warp folded legs up off the ground here)."""
    clip, sb = scene
    joints, offsets = consistent_skeleton(clip.joints.astype(float))
    upper = [j for j in range(22) if j not in (0, 1, 2, 4, 5, 7, 8, 10, 11)]   # spine and up
    bend = np.radians(70.0)
    for h in range(2):
        side = joints[:, h, 1] - joints[:, h, 2]                               # hip line: the bend axis
        axis = side / np.linalg.norm(side, axis=-1, keepdims=True)
        rel = joints[:, h, upper] - joints[:, h, :1]
        along = np.sum(rel * axis[:, None], -1, keepdims=True) * axis[:, None]
        joints[:, h, upper] = (joints[:, h, :1] + along + np.cos(bend) * (rel - along)
                               + np.sin(bend) * np.cross(axis[:, None], rel))
    warped = warp_to_keyposes(joints, offsets, sb)
    feet = [10, 11]
    assert np.abs(warped[:, :, feet] - joints[:, :, feet]).max() < 0.15
    assert warped[:, :, feet, 1].min(-1).max() < 0.12                         # one foot always down


def test_finish_leaves_a_motion_that_already_matches_its_sketch_nearly_alone(scene):
    clip, sb = scene
    done = finish(clip, sb)
    assert np.linalg.norm(done.joints - clip.joints, axis=-1).mean() < 0.03
    assert done.bone_offsets.shape == (2, 22, 3) and np.isfinite(done.rot6d).all()


def test_finish_without_keyposes_or_strokes_only_fixes_the_skeleton(scene):
    clip, sb = scene
    bare = type(sb)(fps=sb.fps, length=sb.length, camera=sb.camera, agents=sb.agents)
    done = finish(clip, bare)
    moved = np.linalg.norm(done.joints - clip.joints, axis=-1)              # (N, H, 22)
    # Knees and elbows may move where the synthesized clip's own feet pop (by 38 cm here), and
    # the whole body within a few frames of such a pop (the steadying).
    popping = np.stack([frame_pops(clip.joints[:, h].astype(float)) > SteadyConfig().tolerance for h in range(2)], 1)
    calm = ~maximum_filter1d(popping, 2 * SteadyConfig().spread + 3, axis=0)
    assert calm.mean() > 0.3
    assert np.delete(moved, [mid for _, mid, _ in LIMBS], axis=2)[calm].max() < 0.05
    assert pop(done.joints.astype(float)) <= pop(clip.joints.astype(float)) + 1e-6


def test_a_keys_pose_change_fades_out_between_keys_far_apart(scene):
    """Keys 3 s apart: half way between them the pose is the generated one (its place moves with
    the root): a key's pose change spread over a whole walk turned the posed figure's straight
    template knee with the body."""
    clip, sb = scene
    raised = clip.joints.astype(float)
    raised[:, :, 16:] += (0.0, 0.2, 0.0)                      # arms 20 cm up all along; the keys have them down
    joints, offsets = consistent_skeleton(raised)
    sb.keyposes = [k for k in sb.keyposes if k.frame in (0, sb.length - 1)]
    warped = warp_to_keyposes(joints, offsets, sb)
    middle = sb.length // 2
    pose = lambda j: j[middle] - j[middle, :, :1]
    assert np.abs(pose(warped) - pose(joints)).max() < 0.03


def test_a_key_pose_change_turns_smoothly_with_a_body_whose_hips_jitter(scene):
    """A body's heading is read off its hips; the fit of a real dancer's spin turned them 135
    degrees in one frame, and a key's pose change spread in the body's frame swung a wrist 40 cm
    with it. Smoothed over a few frames, the heading swings the wrists a third as far (33 -> 9 cm
    beyond their neighbouring frames' moves in this scene)."""
    clip = scene[0]
    sb = sketchify(clip, 4, 0.0, 3)                           # keys at 0, 41, 98, 119
    raised = clip.joints.astype(float)
    raised[:, :, 16:] += (0.0, 0.2, 0.0)                      # the keys pull the arms 20 cm down
    jittered = raised.copy()
    turn = axis_angle_to_matrix(np.array([0.0, np.radians(135.0), 0.0]))
    for n in range(31, 51, 2):                                # every other frame the hips turn 135 degrees
        hips = jittered[n, 0, [1, 2]] - jittered[n, 0, 0]
        jittered[n, 0, [1, 2]] = jittered[n, 0, 0] + hips @ turn.T
    wrists = slice(25, 57), slice(0, 1), [20, 21]
    smooth = warp_to_keyposes(*consistent_skeleton(raised), sb)[wrists]
    shaken = warp_to_keyposes(*consistent_skeleton(jittered), sb)[wrists]
    assert pop(shaken) < pop(smooth) + 0.1

"""Finishing, contacts and held objects (contacts.py, held.py, tested together: a hold is judged
by where the hands end up): held objects follow the hands and rest on the ground otherwise;
wrists reach their grips (or the other person's hand) by exact-length arm IK."""
from dataclasses import replace

import numpy as np
import pytest

from engine.body import body_points
from engine.controls import build_controls
from engine.finishing.blend import spike
from engine.finishing.contacts import ContactConfig, arm_lengths, object_anchors, reach_contacts
from engine.finishing.held import BODY_SPHERES, _within_holders_reach, _within_reach_across, hold_object, step_within_reach
from engine.finishing.held_yaw import carried_yaw, yaw_of
from engine.geometry.polylines import point_polyline_distance
from engine.metrics import anchor_error
from engine.objects import ObjectSpec, world_to_local
from engine.skeleton import HANDS, JOINT_INDEX, bone_lengths, rest_pose
from engine.sketchify import sketchify
from engine.storyboard import Agent, Contact, ObjectKey, SceneObject, Storyboard
from engine.synth import synthesize
from engine.synth.reach import wrap_angle, yaw_matrix

ARMS = [(JOINT_INDEX[f"{s}_shoulder"], JOINT_INDEX[f"{s}_elbow"], JOINT_INDEX[f"{s}_wrist"]) for s in "lr"]


def scrambled(scenario: str, seed: int = 3):
    """A synthesized clip's storyboard, its joints with every arm swung 0.4 rad about the
    shoulder (bone lengths kept), and its object poses shifted and jittered.
    Returns storyboard, joints (N, H, 22, 3), obj_pose (N, O, 7)."""
    clip = synthesize(scenario, seed, fps=20)
    sb = sketchify(clip, 4, 0.0, seed)
    joints = clip.joints.astype(float)
    for side, (shoulder, *rest) in enumerate(ARMS):
        swing = yaw_matrix(np.array(0.4 if side else -0.4))
        root = joints[:, :, shoulder, None]
        joints[:, :, rest] = (joints[:, :, rest] - root) @ swing.T + root
    rng = np.random.default_rng(seed)
    pose = clip.obj_pose + np.array([0.5, 0.3, -0.4, 0, 0, 0, 0]) + rng.normal(0, 0.1, clip.obj_pose.shape)
    return sb, joints, pose


def finish(sb, joints, pose, config=ContactConfig()):
    held = hold_object(joints, pose, sb, config)
    anchors = object_anchors(held, sb)
    return held, anchors, reach_contacts(joints, anchors, sb, config)


@pytest.fixture(scope="module")
def carry():
    sb, joints, pose = scrambled("carry_together")
    return (sb, joints, pose) + finish(sb, joints, pose)


def test_carry_hands_on_the_object(carry):
    sb, joints, _, held, anchors, out = carry
    contact_anchor = build_controls(sb).contact_anchor
    assert anchor_error(joints, anchors, contact_anchor) > 0.03  # the swung arms miss the grips
    assert anchor_error(out, anchors, contact_anchor) < 0.01
    assert np.isfinite(out).all() and np.isfinite(held).all()


def test_carry_keeps_bones_and_the_rest_of_the_body(carry):
    _, joints, _, _, _, out = carry
    np.testing.assert_allclose(bone_lengths(out), bone_lengths(joints), atol=1e-9)
    arms = [j for arm in ARMS for j in arm[1:]]
    others = [j for j in range(22) if j not in arms]
    np.testing.assert_array_equal(out[:, :, others], joints[:, :, others])


def test_carry_object_rests_still_on_the_ground(carry):
    sb, _, _, held, _, _ = carry
    first = min(c.start for c in sb.contacts)
    last = max(c.end for c in sb.contacts)
    settled = last + 10  # time to drop from a release just above the ground
    assert settled < sb.length - 1
    for rest in (held[:first + 1, 0], held[settled:, 0]):
        np.testing.assert_allclose(rest[:, 1], 0.0, atol=1e-12)
        np.testing.assert_allclose(rest, np.broadcast_to(rest[0], rest.shape), atol=1e-12)
        np.testing.assert_allclose(np.linalg.norm(rest[:, 3:], axis=-1), 1.0)
    assert np.ptp(held[first:last, 0, :3], axis=0).max() > 0.2  # and it is carried in between


def test_held_object_is_upright_and_moves_smoothly(carry):
    _, _, _, held, _, _ = carry
    np.testing.assert_allclose(held[..., [4, 6]], 0.0, atol=1e-12)  # yaw only: no tilt
    step = np.linalg.norm(np.diff(held[:, 0, :3], axis=0), axis=-1)
    assert step.max() < 0.1  # m per frame at 20 fps: no jumps


def test_handshake_brings_wrists_together():
    sb, joints, pose = scrambled("handshake")
    config = ContactConfig()
    held, anchors, out = finish(sb, joints, pose, config)
    shake = sb.contacts[0]
    right = HANDS[1]
    span = slice(shake.start, shake.end + 1)
    gap = np.linalg.norm(out[span, 0, right] - out[span, 1, right], axis=-1)
    before = np.linalg.norm(joints[span, 0, right] - joints[span, 1, right], axis=-1)
    assert before.mean() > 0.15
    np.testing.assert_allclose(gap, config.hand_gap, atol=1e-6)
    np.testing.assert_allclose(bone_lengths(out), bone_lengths(joints), atol=1e-9)
    # Nobody holds the object: it stays still on the ground (where: the next test).
    np.testing.assert_allclose(held[:, 0], np.broadcast_to(held[0, 0], held[:, 0].shape), atol=1e-12)
    assert held[0, 0, 1] == 0.0


def test_an_unsketched_object_nobody_holds_rests_where_it_was_decoded():
    sb, joints, pose = scrambled("handshake")
    sb.object_keys, sb.object_paths = [], []
    held = hold_object(joints, pose, sb)
    np.testing.assert_allclose(held[0, 0, [0, 2]], np.median(pose[:, 0, [0, 2]], axis=0))


def test_no_contacts_grounds_a_still_object():
    sb, joints, pose = scrambled("carry_together")
    sb.contacts = []
    held, anchors, out = finish(sb, joints, pose)
    assert np.isfinite(held).all()
    np.testing.assert_allclose(held[..., 1], 0.0, atol=1e-12)
    np.testing.assert_allclose(held, np.broadcast_to(held[:1], held.shape), atol=1e-12)
    np.testing.assert_array_equal(out, joints)


def test_an_object_nobody_holds_rests_where_it_was_sketched():
    clip = synthesize("handshake", 4, fps=20)             # the prop stands by, never touched
    sb = sketchify(clip, 4, 0.0, 4)
    assert sb.object_keys and not any(c.object for c in sb.contacts)
    pose = clip.obj_pose + np.array([1.0, 0.3, -0.8, 0, 0, 0, 0])
    held = hold_object(clip.joints.astype(float), pose, sb)
    np.testing.assert_allclose(held[..., :3], clip.obj_pose[..., :3], atol=0.01)


def test_a_hand_inside_the_object_near_its_span_is_on_its_grip_already():
    """A generated right hand inside the box 8-10 frames before the artist's span: on its grip
    there (eased on before), not left to be pushed out of the box; far from the span it is left."""
    sb, joints, pose = scrambled("carry_together")
    pose = hold_object(joints, pose, sb)
    hold = next(c for c in sb.contacts if c.hand == "right" and c.object)
    person, wrist = sb.agent_index(hold.agent), JOINT_INDEX["r_wrist"]
    anchors = object_anchors(pose, sb)[:, sb.object_index(hold.object), hold.anchor]
    sunk = joints.copy()
    frames = np.arange(hold.start - 10, hold.start - 7)
    sunk[frames, person, wrist] = pose[frames, 0, :3] + (0.0, sb.objects[0].spec.size[1] / 2, 0.0)   # at its centre
    reached = reach_contacts(sunk, object_anchors(pose, sb), sb, ContactConfig(), pose)
    gap = np.linalg.norm(reached[:, person, wrist] - anchors, axis=-1)
    assert gap[frames].max() < 0.01
    far = hold.start - 10 - ContactConfig().blend_frames - 2
    np.testing.assert_allclose(reached[:far, person, wrist], sunk[:far, person, wrist])
    np.testing.assert_allclose(bone_lengths(reached), bone_lengths(sunk), atol=1e-9)


def test_a_resting_object_slides_out_of_the_legs_of_a_person_who_stands_in_it():
    """The sketch puts a box where a person walks up to it: at their closest the person's knees
    stand 8 cm inside it. It slides along the ground (the same place all through: it rests) by
    the least that clears every body sphere but the arms', within ContactConfig.most_rest_shift."""
    clip = synthesize("handshake", 4, fps=20)              # the prop stands by, never touched
    sb = sketchify(clip, 4, 0.0, 4)
    spec, rest = sb.objects[0].spec, clip.obj_pose[0, 0, :3].astype(float)
    joints = clip.joints.astype(float)
    away = (joints[:, 0, 0] - rest) * (1, 0, 1)
    f = int(np.argmin(np.linalg.norm(away, axis=-1)))
    joints[:, 0] += (rest + away[f] / np.linalg.norm(away[f]) * (max(spec.size[0], spec.size[2]) / 2 + 0.1)
                     - joints[f, 0, 0]) * (1, 0, 1)

    def deepest(pose):
        points, radii = body_points(joints)
        points, radii = points[:, :, BODY_SPHERES], radii[BODY_SPHERES]
        local = world_to_local(points.reshape(len(joints), -1, 3), pose[:, 0])
        return spec.penetration_local(local, np.tile(radii, joints.shape[1])).max()

    assert deepest(clip.obj_pose.astype(float)) > 0.05
    held = hold_object(joints, clip.obj_pose + np.array([1.0, 0.3, -0.8, 0, 0, 0, 0]), sb)
    assert deepest(held) < 1e-3
    slide = held[:, 0, :3] - clip.obj_pose[:, 0, :3]
    assert np.ptp(slide, axis=0).max() < 1e-9 and abs(slide[0, 1]) < 1e-9          # one place, on the ground
    assert 0.02 < np.linalg.norm(slide[0]) <= ContactConfig().most_rest_shift + 1e-9


def test_a_resting_object_slides_no_further_out_of_reach_of_the_hands_that_take_it_next():
    """A box a person's right hand takes right after it rests: a slide of 0.5 m away from the
    person is cut short where the grip would lie over rest_reach_slack beyond the arm's reach;
    with no hands to take it, the slide is whole."""
    config = ContactConfig()
    joints = rest_pose()[None, None].repeat(3, axis=0)                       # (3, 1, 22, 3), facing +Z
    shoulder = joints[0, 0, JOINT_INDEX["r_shoulder"]]
    place = np.array([shoulder[0], 0.0, 0.35, 1.0, 0.0, 0.0, 0.0])           # grip 0.35 m ahead, at the box's origin
    grips = np.zeros((3, 2, 3))
    grips[..., 1] = shoulder[1]                                              # at shoulder height
    held = np.zeros((3, 2), bool)
    held[2, 1] = True                                                        # the right hand, at frame 2
    away = _within_holders_reach(np.array([0.0, 0.0, 0.5]), place, [2], joints, grips, held, config)
    grip = place[:3] + away + grips[2, 1]
    reach = config.reach * np.linalg.norm(joints[0, 0, JOINT_INDEX["r_elbow"]] - shoulder) + config.reach * np.linalg.norm(
        joints[0, 0, JOINT_INDEX["r_wrist"]] - joints[0, 0, JOINT_INDEX["r_elbow"]])
    assert 0.0 < away[2] < 0.5 and np.linalg.norm(grip - shoulder) <= reach + config.rest_reach_slack + 1e-9
    np.testing.assert_allclose(_within_holders_reach(np.array([0.0, 0.0, 0.5]), place, [], joints, grips, held, config),
                               [0.0, 0.0, 0.5])                              # nobody takes it: the whole slide


@pytest.mark.parametrize("scenario", ["carry_together", "let_go"])
def test_a_held_object_is_picked_up_and_lands_where_it_was_sketched(scenario):
    sb, joints, pose = scrambled(scenario, 2)   # hands swung off the grips: a fit to them would miss
    held_frames = np.flatnonzero([any(c.start <= f <= c.end for c in sb.contacts if c.object)
                                  for f in range(sb.length)])
    assert held_frames[-1] < sb.length - 15   # time to slide to its landing place
    before, after = slice(0, held_frames[0]), slice(-5, None)
    held = hold_object(joints, pose, sb)
    true = synthesize(scenario, 2, fps=20).obj_pose[..., :3]
    assert np.abs(held[before, :, :3] - true[before]).max() < 1e-6
    assert np.abs(held[after, :, [0, 2]] - true[after][..., [0, 2]]).max() < 1e-6


def one_person(n: int = 40):
    """One person in rest pose walking along +Z, holding a box with both hands over [0, 30] and
    with the right hand alone over [31, 34]. Returns storyboard, joints (N, 1, 22, 3)."""
    sb = Storyboard(length=n, agents=[Agent("A")], objects=[SceneObject("box", ObjectSpec("box"))],
                    contacts=[Contact("A", "left", 0, 30, "box", 0), Contact("A", "right", 0, 34, "box", 2)])
    joints = rest_pose()[None, None] + np.linspace(0, 1, n)[:, None, None, None] * [0, 0, 1]
    return sb, joints


def test_one_person_and_one_hand():
    sb, joints = one_person()
    held, anchors, out = finish(sb, joints, np.zeros((len(joints), 1, 7)))
    contact_anchor = build_controls(sb).contact_anchor
    assert np.isfinite(out).all()
    both = slice(0, 31)  # (the T-pose's far-apart hands put the one-hand grip out of reach)
    assert anchor_error(out[both], anchors[both], contact_anchor[both]) < 1e-6
    np.testing.assert_allclose(bone_lengths(out), bone_lengths(joints), atol=1e-9)
    # The right hand alone carries it on without turning it.
    np.testing.assert_allclose(held[31:35, 0, 3:], np.broadcast_to(held[30, 0, 3:], (4, 4)), atol=1e-12)


def test_a_few_frames_without_a_hold_are_the_artists_not_a_lift_or_a_drop():
    sb, joints = one_person()      # walking 2.5 cm a frame; the box held by both hands
    pose = np.zeros((len(joints), 1, 7))

    def holds(*spans):
        return [Contact("A", hand, a, b, "box", anchor) for a, b in spans
                for hand, anchor in (("left", 0), ("right", 2))]

    sb.contacts = holds((3, 15), (19, 36))      # late by 3 frames, a 3-frame gap, early by 3
    held = hold_object(joints, pose, sb)[:, 0, :3]
    assert np.ptp(held[:, 1]) < 1e-6            # in the hands all along: no lift, no 11 cm drop
    assert np.abs(np.diff(held, axis=0)).max() < 0.03
    sb.contacts = holds((3, 15), (26, 36))      # a gap of ten frames: put down and picked up again
    assert hold_object(joints, pose, sb)[20, 0, 1] < held[20, 1] - 0.1
    floor = sb.camera.project(np.array([1.5, ObjectSpec("box").size[1] / 2, 0.0]))
    sb.contacts = holds((3, 15), (19, 36))      # keyed on the floor 1.5 m away at frame 0: it lies there
    sb.object_keys = [ObjectKey("box", 0, floor + np.array([[-0.2, -0.15], [0.2, -0.15], [0.2, 0.15], [-0.2, 0.15]]))]
    on_floor = hold_object(joints, pose, sb)[:4, 0, :3]
    np.testing.assert_allclose(on_floor, np.broadcast_to([1.5, 0.0, 0.0], (4, 3)), atol=0.02)


def test_a_box_let_go_of_is_put_down_by_the_hands_not_dropped():
    sb, joints = one_person(60)    # carried at the hands' height, let go of at frame 34
    held = hold_object(joints, np.zeros((len(joints), 1, 7)), sb)[:, 0, :3]
    config = ContactConfig()
    carried = held[34 - config.lift_frames, 1]
    assert carried > 0.5 and held[34, 1] == config.rest_height     # on the ground as the last hand lets go
    np.testing.assert_allclose(held[35:], np.broadcast_to(held[34], (len(held) - 35, 3)))   # and there it stays
    lowering = np.diff(held[34 - config.lift_frames:35, 1])
    assert (lowering <= 1e-12).all() and -lowering.max() < carried / 3   # eased down, never up
    assert np.abs(np.diff(held[:34 - config.lift_frames, 1])).max() < 1e-6   # carried level before


def test_a_box_handed_over_is_pushed_out_of_the_giver_who_let_go_of_it():
    n = 20
    sb = Storyboard(length=n, agents=[Agent("A"), Agent("B")], objects=[SceneObject("box", ObjectSpec("box"))],
                    contacts=[Contact("B", "left", 0, n - 1, "box", 0), Contact("B", "right", 0, n - 1, "box", 2)])
    giver = rest_pose()
    taker = (giver - giver[0]) @ yaw_matrix(np.array(np.pi)).T + giver[0] + (0.0, 0.0, 0.6)   # facing A
    taker[list(HANDS)] = giver[0] + (np.array([[0.2, 0.0, 0.0], [-0.2, 0.0, 0.0]]))          # at A's pelvis
    joints = np.tile(np.stack([giver, taker]), (n, 1, 1, 1))
    held = hold_object(joints, np.zeros((n, 1, 7)), sb)
    points, radii = body_points(joints[:, :1])
    local = world_to_local(points[:, 0][:, BODY_SPHERES], held[:, 0])
    assert ObjectSpec("box").penetration_local(local, radii[BODY_SPHERES]).max() < 0.01   # out of the giver
    assert held[0, 0, 2] > giver[0, 2] + 0.1                                               # towards the taker


def test_a_held_box_whose_fit_jumps_is_smoothed_round_its_holder_not_through_the_hips():
    """Where a second holder takes hold, the hands' fit of a box jumps (by 18 cm in a frame); the
    carried path smoothed over it passed through the hips. Here the fit jumps from one side of
    the holder to the other, both clear of the body (held by its ends, the hands uncrossed: the box
    turned half round, its grip at local -x on the holder's left)."""
    n, jump = 30, 15
    sb = Storyboard(length=n, agents=[Agent("A")], objects=[SceneObject("box", ObjectSpec("box"))],
                    contacts=[Contact("A", "left", 0, n - 1, "box", 0), Contact("A", "right", 0, n - 1, "box", 2)])
    spec = sb.objects[0].spec
    body = rest_pose()
    joints = np.tile(body, (n, 1, 1, 1)).reshape(n, 1, 22, 3)
    for frames, side in ((slice(0, jump), 1.0), (slice(jump, n), -1.0)):
        base = body[0] + (side * 0.45, -spec.size[1] / 2, 0.0)          # the box beside the hips
        joints[frames, 0, list(HANDS)] = base + spec.anchors[[0, 2]] @ yaw_matrix(np.array(np.pi)).T
    held = hold_object(joints, np.zeros((n, 1, 7)), sb)
    points, radii = body_points(joints[:, 0])
    local = world_to_local(points[:, BODY_SPHERES], held[:, 0])
    assert spec.penetration_local(local, radii[BODY_SPHERES]).max() < 0.01


def test_one_holder_turns_the_object_with_their_chest_not_their_wrists():
    sb, joints = one_person()
    wrists = list(HANDS)
    middle = joints[:, :, wrists].mean(axis=2, keepdims=True)
    spin = np.linspace(0.0, 2 * np.pi, len(joints))            # the wrists circle each other once
    crossing = joints.copy()
    crossing[:, :, wrists] = middle + np.einsum("nij,nhkj->nhki", yaw_matrix(spin), joints[:, :, wrists] - middle)
    yaw = np.unwrap(yaw_of(hold_object(crossing, np.zeros((len(joints), 1, 7)), sb)[:31, 0, 3:]))
    assert np.ptp(yaw) < 1e-6                                  # the chest does not turn: neither does the box
    pelvis = joints[:, :, :1]
    turn = np.linspace(0.0, np.pi / 2, len(joints))            # the whole body turns a quarter
    turning = pelvis + np.einsum("nij,nhkj->nhki", yaw_matrix(turn), joints - pelvis)
    yaw = np.unwrap(yaw_of(hold_object(turning, np.zeros((len(joints), 1, 7)), sb)[:, 0, 3:]))
    np.testing.assert_allclose(yaw[30] - yaw[0], turn[30], atol=0.05)


def test_two_carriers_turn_the_object_with_the_line_between_them_not_their_wrists(carry):
    """Their hands circle half a turn about the box and back over 15 frames (as warped hands can):
    the box stays; the two of them turning a quarter about it turn it with them."""
    sb, joints, pose = carry[:3]
    n = len(joints)
    both = np.ones(n, bool)
    for agent in sb.agents:
        mine = np.zeros(n, bool)
        for c in sb.contacts:
            if c.agent == agent.id:
                mine[c.start:c.end + 1] = True
        both &= mine
    shared = np.flatnonzero(both)
    window = shared[len(shared) // 2 - 7:len(shared) // 2 + 8]
    wrists = list(HANDS)
    base = np.unwrap(yaw_of(hold_object(joints, pose, sb)[:, 0, 3:]))
    twisted = joints.copy()
    centre = joints[window][:, :, wrists].mean(axis=(1, 2))[:, None, None]          # (15, 1, 1, 3)
    spin = np.pi * np.sin(np.pi * np.arange(1, 16) / 16)
    twisted[window[:, None], :, wrists] = np.swapaxes(
        centre + np.einsum("nij,nhkj->nhki", yaw_matrix(spin), joints[window][:, :, wrists] - centre), 1, 2)
    yaw = np.unwrap(yaw_of(hold_object(twisted, pose, sb)[:, 0, 3:]))
    assert np.abs(yaw - base)[window].max() < 0.15
    middle = joints[shared][:, :, wrists].mean(axis=(0, 1, 2))
    turn = np.linspace(0.0, np.pi / 2, n)
    turning = middle + np.einsum("nij,nhkj->nhki", yaw_matrix(turn), joints - middle)
    yaw = np.unwrap(yaw_of(hold_object(turning, pose, sb)[:, 0, 3:]))
    np.testing.assert_allclose((yaw - base)[shared], turn[shared], atol=0.1)


def test_no_objects():
    sb, joints = one_person()
    sb.objects, sb.contacts = [], [Contact("A", "left", 15, 19, other_agent="A", other_hand="right")]
    pose = np.zeros((len(joints), 0, 7))
    held = hold_object(joints, pose, sb)
    assert held.shape == pose.shape and object_anchors(held, sb).shape[:2] == (len(joints), 0)
    out = reach_contacts(joints, None, sb, ContactConfig(hand_gap=0.0))
    np.testing.assert_allclose(out[15:20, 0, HANDS[0]], out[15:20, 0, HANDS[1]], atol=1e-9)
    np.testing.assert_allclose(bone_lengths(out), bone_lengths(joints), atol=1e-9)
    untouched = 15 - ContactConfig().blend_frames  # frames before the ease-in
    np.testing.assert_array_equal(out[:untouched], joints[:untouched])
    assert np.abs(out[untouched:15] - joints[untouched:15]).max() > 0


def _shortfall(joints, anchors, sb, reach):
    """Per contact (in storyboard order), per frame of its span: how far its grip lies beyond
    `reach` of the straight arm."""
    flat = anchors.reshape(len(joints), -1, 3)
    out = []
    for c in sb.contacts:
        a, (shoulder, elbow, wrist) = sb.agent_index(c.agent), ARMS[0 if c.hand == "left" else 1]
        arm = (np.linalg.norm(joints[:, a, elbow] - joints[:, a, shoulder], axis=-1)
               + np.linalg.norm(joints[:, a, wrist] - joints[:, a, elbow], axis=-1))
        gap = np.linalg.norm(flat[:, sb.object_index(c.object) * 4 + c.anchor] - joints[:, a, shoulder], axis=-1)
        out.append((gap - reach * arm)[c.start:c.end + 1])
    return out


def test_a_holder_out_of_reach_steps_towards_the_grip_but_not_off_a_keyframe():
    clip = synthesize("carry_together", 3, fps=20)
    sb = sketchify(clip, 4, 0.0, 3)
    joints = clip.joints.astype(float).copy()
    joints[:, 1] += np.array([0.6, 0.0, 0.0])            # B stands 60 cm off to the side all along
    config = ContactConfig()
    anchors = object_anchors(hold_object(joints, clip.obj_pose, sb, config), sb)
    out = step_within_reach(joints, clip.obj_pose, sb, config)
    before, after = (_shortfall(j, anchors, sb, config.reach) for j in (joints, out))
    keys_b = np.array([k.frame for k in sb.keyposes if k.agent == "B"])
    checked = 0
    for c, short_before, short_after in zip(sb.contacts, before, after):
        far = np.abs(np.arange(c.start, c.end + 1)[:, None] - keys_b[None]).min(1) > 15
        if c.agent == "B" and far.any():
            assert short_before[far].max() > 0.15 and short_after[far].max() < 0.05
            checked += 1
    assert checked
    np.testing.assert_allclose(out[keys_b, 1], joints[keys_b, 1])        # the sketch says where B stands
    moved = out - joints
    np.testing.assert_allclose(moved[..., 1], 0.0)                       # stepping is horizontal
    np.testing.assert_allclose(moved, moved[:, :, :1].repeat(22, 2))     # whole bodies, no limb edits
    # Away from a key the step grows by at most a metre per frames_per_metre frames (no lunge).
    from_key = np.abs(np.arange(len(joints))[:, None] - keys_b[None]).min(1)
    assert (np.linalg.norm(moved[:, 1, 0], axis=-1) <= from_key / config.frames_per_metre + 1e-9).all()
    # ... and neither turns at a key nor where it meets that limit in a frame (4 and 6 cm kinks before).
    assert spike(moved[:, 1, 0]).max() < 0.015


def test_a_shared_hold_sits_within_every_holders_vertical_reach():
    """Two people carrying one box, one of them sunk 0.5 m (as a crouch would): the box goes
    where both reach it, not to the mean of their wrists; in the synthesized carry (a real pick-up
    from the floor) it moves by millimetres at most."""
    clip = synthesize("carry_together", 3, fps=20)
    sb = sketchify(clip, 4, 0.0, 3)
    config = ContactConfig()
    free = ContactConfig(grip_rise=100.0)
    np.testing.assert_allclose(hold_object(clip.joints, clip.obj_pose, sb, config),
                               hold_object(clip.joints, clip.obj_pose, sb, free), atol=0.005)
    joints = clip.joints.astype(float).copy()
    joints[:, 0] -= np.array([0.0, 0.5, 0.0])
    for cfg, inside in ((free, False), (config, True)):
        anchors = object_anchors(hold_object(joints, clip.obj_pose, sb, cfg), sb)[:, 0]
        worst = 0.0
        for c in sb.contacts:
            a, (shoulder, elbow, wrist) = sb.agent_index(c.agent), ARMS[0 if c.hand == "left" else 1]
            span = slice(c.start + config.lift_frames + 3, c.end - 3)   # past the lift's ease-in
            arm = (np.linalg.norm(joints[span, a, elbow] - joints[span, a, shoulder], axis=-1)
                   + np.linalg.norm(joints[span, a, wrist] - joints[span, a, elbow], axis=-1))
            rise = np.abs(anchors[span, c.anchor, 1] - joints[span, a, shoulder, 1])
            worst = max(worst, float(np.max(rise - config.grip_rise * config.reach * arm)))
        assert (worst < 0.02) == inside, worst


def test_a_hand_easing_onto_a_moving_box_reaches_for_it_where_it_is(carry):
    """A box the partner already carries: easing in before its own span, a hand reaches for the
    grip where it is then, not where it will be at the span's start (it jerked 10 cm as the hold
    began)."""
    sb, joints, _, _, anchors, _ = carry
    contact = max((c for c in sb.contacts if c.object is not None), key=lambda c: c.start)
    n, h, side = len(joints), sb.agent_index(contact.agent), ("left", "right").index(contact.hand)
    moving = anchors.copy()
    drift = np.clip(np.arange(n) - (contact.start - 8), 0, None)[:, None, None, None] * np.array([0.05, 0, 0])
    moving += drift                                                         # 5 cm a frame from 8 frames before
    out = reach_contacts(joints, moving, sb, ContactConfig())
    wrist = out[:, h, HANDS[side]]
    steps = np.linalg.norm(np.diff(wrist[contact.start - 8:contact.start + 4], axis=0), axis=-1)
    assert steps.max() < 0.095                                               # 10.1 cm held still


@pytest.mark.parametrize("seed", [3, 5])
def test_a_box_handed_over_turns_smoothly_as_hands_join_and_leave(seed):
    """Each pair of hands says a little differently which way the box faces (here the taker's
    hands turned a quarter about the box against the giver's): where hands join or leave the
    hold the box eases from one heading to the next instead of turning in a few frames."""
    sb, joints, pose = scrambled("handoff", seed)
    taker = [c for c in sb.contacts if c.agent == sb.agents[1].id]
    start, end = min(c.start for c in taker), max(c.end for c in taker)
    centre = joints[:, 1, list(HANDS)].mean(axis=1, keepdims=True)         # (N, 1, 3)
    turned = joints.copy()
    turned[start:end + 1, 1, list(HANDS)] = centre[start:end + 1] + np.einsum(
        "ij,nkj->nki", yaw_matrix(np.radians(90.0)), joints[start:end + 1, 1, list(HANDS)] - centre[start:end + 1])
    yaw = np.unwrap(yaw_of(hold_object(turned, pose, sb)[:, 0, 3:]))
    grip = np.max(np.linalg.norm(sb.objects[0].spec.anchors[:, [0, 2]], axis=-1))
    jolt = grip * np.abs(yaw[2:] - 2 * yaw[1:-1] + yaw[:-2]) / 2        # a grip's spike off its neighbours
    assert jolt.max() < 0.009                                        # 1.3 cm, eased at once


def test_a_shared_hold_moves_across_towards_a_holder_it_is_beyond_the_reach_of():
    """Two people 0.8 m apart holding a box between them, fitted (as to the mean of the wrists)
    15 cm nearer one of them: 6 cm beyond the other's reach while the near one's arms bend. It
    moves across until both reach it."""
    n, config = 4, ContactConfig()
    near = rest_pose() * [-1.0, 1.0, -1.0] + [0.0, 0.0, 0.4]           # turned to face the other
    joints = np.repeat(np.stack([rest_pose() + [0.0, 0.0, -0.4], near])[None], n, 0)   # (N, 2, 22, 3)
    grips = np.tile([[-0.2, 0.0, -0.2], [0.2, 0.0, -0.2], [0.2, 0.0, 0.2], [-0.2, 0.0, 0.2]], (n, 1, 1))
    held = np.ones((n, 4), bool)
    fitted = np.tile([0.0, 1.3, 0.15], (n, 1))

    def beyond(pos):   # (N, 4): how far each grip lies beyond the reach of its shoulder
        shoulders = joints[:, :, [ARMS[0][0], ARMS[1][0]]].reshape(n, 4, 3)
        arms = sum(np.linalg.norm(joints[:, :, [ARMS[0][k + 1], ARMS[1][k + 1]]] - joints[:, :, [ARMS[0][k], ARMS[1][k]]],
                                  axis=-1) for k in range(2)).reshape(n, 4)
        return np.linalg.norm(pos[:, None] + grips - shoulders, axis=-1) - config.reach * arms

    assert beyond(fitted)[:, :2].min() > 0.05 and beyond(fitted)[:, 2:].max() < -0.05
    moved = _within_reach_across(fitted, np.zeros(n), joints, grips, held, config)
    assert beyond(moved).max() < 0.005
    np.testing.assert_allclose(moved[:, [0, 1]], fitted[:, [0, 1]])     # across only, along the line


def test_a_resting_object_is_where_its_outline_stands_not_where_its_path_starts():
    """An artist starts an object's path in the middle of its outline; the path's ends are taken
    for the object's base, and averaged with the outline's place they put a box picked up by a
    stamped crouch 14 cm from the grips the hands were posed on. A drawn outline is the cue; a
    path's end only where no outline is drawn."""
    from engine.finishing.held import sketched_rest
    clip = synthesize("carry_together", 3, fps=20)
    sb = sketchify(clip, 4, 0.0, 3)
    base = clip.obj_pose[0, 0, :3]
    np.testing.assert_allclose(sketched_rest(sb, 0, 0, 5), base, atol=0.03)
    outlined = replace(sb, object_paths=[replace(sb.object_paths[0], points=sb.object_paths[0].points.copy())])
    outlined.object_paths[0].points[0] = next(k for k in sb.object_keys if k.frame == 0).outline.mean(axis=0)
    np.testing.assert_allclose(sketched_rest(outlined, 0, 0, 5), base, atol=0.03)
    unoutlined = replace(sb, object_keys=[k for k in sb.object_keys if k.frame > 5])
    np.testing.assert_allclose(sketched_rest(unoutlined, 0, 0, 5), base, atol=0.03)


def test_a_holder_inside_the_object_steps_back_out_of_it_but_not_off_a_keyframe():
    """Carriers drawn closer than the box is deep: B 40 cm nearer A all along, the box (fitted to
    the mean of the wrists) inside B's body. B steps back, away from its keys, until its body is
    within the bench's 2 cm (the steps are smoothed); pushes on the box itself from the two facing
    carriers cancel."""
    clip = synthesize("carry_together", 3, fps=20)
    sb = sketchify(clip, 4, 0.0, 3)
    joints = clip.joints.astype(float).copy()
    towards_a = joints[:, 0, 0] - joints[:, 1, 0]
    joints[:, 1] += 0.4 * (towards_a * [1.0, 0.0, 1.0] / np.linalg.norm(towards_a, axis=-1, keepdims=True))[:, None]
    config, spec = ContactConfig(), sb.objects[0].spec

    def inside(j):   # (N,) how deep B's body (arms aside) is in the box as the hands hold it
        pose = hold_object(j, clip.obj_pose, sb, config)[:, 0]
        points, radii = body_points(j[:, 1])
        return np.max(spec.penetration_local(world_to_local(points[:, BODY_SPHERES], pose), radii[BODY_SPHERES]), -1)

    out = step_within_reach(joints, clip.obj_pose, sb, config)
    keys_b = np.array([k.frame for k in sb.keyposes if k.agent == "B"])
    held = [c for c in sb.contacts if c.agent == "B"]
    far = np.array([any(c.start + 10 <= f <= c.end - 10 for c in held) and np.abs(f - keys_b).min() > 15
                    for f in range(len(joints))])
    assert far.any() and inside(joints)[far].max() > 0.05
    assert inside(out)[far].max() < 0.02                                 # unmoved: 7.6 cm
    np.testing.assert_allclose(out[keys_b, 1], joints[keys_b, 1])        # the sketch says where B stands


def test_a_held_object_goes_where_its_outline_is_drawn():
    """An outline drawn within a hold 6 cm above where the carriers hold the canister: it goes
    there at that frame (its centre on the outline's) and eases back within drawn_falloff frames
    after it; the hands follow it (reach_contacts)."""
    clip = synthesize("carry_together", 3, fps=20)
    sb = sketchify(clip, 4, 0.0, 3)
    config = ContactConfig()
    span = max(((c.start, c.end) for c in sb.contacts), key=lambda s: s[1] - s[0])
    frame = (span[0] + span[1]) // 2
    size = sb.objects[0].spec.size

    def centre_seen(pose):   # (N, 1, 7) -> the centre's sketch point (N, 2)
        return sb.camera.project(pose[:, 0, :3] + (0.0, size[1] / 2, 0.0))

    before = hold_object(clip.joints, clip.obj_pose, sb, config)
    drawn = centre_seen(before)[frame] + (0.0, 0.06)
    outlined = replace(sb, object_keys=sb.object_keys + [ObjectKey(sb.objects[0].id, frame, drawn + np.array(
        [[-0.2, -0.15], [0.2, -0.15], [0.2, 0.15], [-0.2, 0.15]]))])
    after = hold_object(clip.joints, clip.obj_pose, outlined, config)
    np.testing.assert_allclose(centre_seen(after)[frame], drawn, atol=0.01)
    beyond = np.arange(sb.length) > frame + config.drawn_falloff + 6   # (before it, the move eases from the key
    np.testing.assert_allclose(after[beyond], before[beyond], atol=1e-6)   # the hold begins at)
    anchors = object_anchors(after, outlined)
    assert anchor_error(reach_contacts(clip.joints.astype(float), anchors, outlined, config), anchors,
                        build_controls(outlined).contact_anchor) < 0.01


def test_a_held_object_goes_towards_its_outline_only_as_far_as_its_holders_reach():
    """The outline drawn 40 cm off the carriers' line, beyond their arms: the canister moves
    towards it, but no held grip goes further beyond its holder's reach than it was."""
    clip = synthesize("carry_together", 3, fps=20)
    sb = sketchify(clip, 4, 0.0, 3)
    config = ContactConfig()
    span = max(((c.start, c.end) for c in sb.contacts), key=lambda s: s[1] - s[0])
    frame = (span[0] + span[1]) // 2
    joints = clip.joints.astype(float)
    before = hold_object(joints, clip.obj_pose, sb, config)
    drawn = sb.camera.project(before[frame, 0, :3]) + (0.4, 0.0)
    outlined = replace(sb, object_keys=sb.object_keys + [ObjectKey(sb.objects[0].id, frame, drawn + np.array(
        [[-0.2, -0.15], [0.2, -0.15], [0.2, 0.15], [-0.2, 0.15]]))])
    after = hold_object(joints, clip.obj_pose, outlined, config)
    moved = sb.camera.project(after[frame, 0, :3]) - sb.camera.project(before[frame, 0, :3])
    assert 0.0 < moved[0] < 0.3

    def beyond_reach(pose):   # how far each held grip lies beyond `reach` of its holder's arm (N, contacts)
        anchors, arms, out = object_anchors(pose, sb)[:, 0], arm_lengths(joints), []
        for c in sb.contacts:
            a, side = sb.agent_index(c.agent), int(c.hand == "right")
            shoulder = joints[:, a, ARMS[side][0]]
            out.append(np.linalg.norm(anchors[:, c.anchor] - shoulder, axis=-1) - config.reach * arms[:, a, side])
        return np.stack(out, 1)[span[0]:span[1] + 1]
    assert np.all(beyond_reach(after) <= np.maximum(beyond_reach(before), 0.0) + 0.005)


def test_a_held_object_follows_its_drawn_path():
    """The object's path drawn 5 cm above where the carriers hold the canister: while it is
    carried, well inside the hold, its base is on the path (which says where, not when)."""
    clip = synthesize("carry_together", 3, fps=20)
    sb = sketchify(clip, 4, 0.0, 3)
    span = max(((c.start, c.end) for c in sb.contacts), key=lambda s: s[1] - s[0])
    inside = np.arange(span[0] + 15, span[1] - 15)
    before = hold_object(clip.joints, clip.obj_pose, sb)
    seen = sb.camera.project(before[:, 0, :3])
    path = replace(sb.object_paths[0], start=0, end=sb.length - 1, points=seen + (0.0, 0.05))
    after = hold_object(clip.joints, clip.obj_pose, replace(sb, object_keys=[], object_paths=[path]))
    off = point_polyline_distance(sb.camera.project(after[inside, 0, :3]), path.points)
    assert point_polyline_distance(seen[inside], path.points).mean() > 0.04
    assert off.mean() < 0.01 and off.max() < 0.03   # (the reach bands after it keep some of the gait's bob)


@pytest.mark.parametrize("fitted, kept", [(np.pi / 2, False), (0.3, True)])
def test_a_shared_object_faces_each_holder_with_their_grips(fitted, kept):
    """Two carriers facing each other along x, A holding a canister's -x grips and B its +x ones:
    wrists that fit it a quarter turn round would have each reach across it for the far side, so
    each one's grips face them instead; a fit within FACING_SLACK of that stays as it is."""
    n, spec = 20, ObjectSpec("canister")
    people = [rest_pose() @ yaw_matrix(np.array(turn)).T + (x, 0.0, 0.0)
              for turn, x in ((np.pi / 2, -0.6), (-np.pi / 2, 0.6))]
    joints = np.repeat(np.stack(people)[None], n, axis=0)                         # (N, 2, 22, 3)
    grips, held = np.zeros((n, 4, 3)), np.ones((n, 4), bool)
    sides = np.argsort(spec.anchors[:, 0])                                        # the -x grips first
    grips[:] = spec.anchors[sides]
    yaw = carried_yaw(np.full(n, fitted), joints, held.reshape(n, 2, 2).any(-1), 1.5, grips, held)
    np.testing.assert_allclose(wrap_angle(yaw), fitted if kept else 0.0, atol=1e-6)


@pytest.mark.parametrize("fitted, kept", [(0.0, False), (np.pi - 0.3, True)])
def test_one_holder_holds_an_object_left_hand_on_the_left(fitted, kept):
    """One person facing +z (their left is +x) holding a box by its ends, the left hand on its
    local -x grip: a fit that crosses the hands (that grip on their right) turns the box half
    round; one within FACING_SLACK of uncrossed stays as it is."""
    n, spec = 20, ObjectSpec("box")
    joints = np.repeat(rest_pose()[None, None], n, axis=0)                        # (N, 1, 22, 3)
    grips, held = np.zeros((n, 2, 3)), np.ones((n, 2), bool)
    grips[:] = spec.anchors[[0, 2]]                                               # local -x, +x
    yaw = carried_yaw(np.full(n, fitted), joints, held[:, None].any(-1), 1.5, grips, held)
    np.testing.assert_allclose(wrap_angle(yaw - (fitted if kept else np.pi)), 0.0, atol=1e-6)

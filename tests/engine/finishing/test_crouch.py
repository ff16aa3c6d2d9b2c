"""Holders crouch and lean to grips below their reach (crouch.py): a person standing tall over a
box on the floor lowers towards its grips while holding it, as low as a squat goes, and leans
forward for the rest, the feet staying where they stand, every bone keeping its length, smoothly,
not at a key frame, and nothing going deeper into the box."""
import numpy as np

from engine.finishing.contacts import ContactConfig, arm_lengths, object_anchors
from engine.finishing.crouch import _crouched, _depth, _lean, _leaned, _shortfall, crouch_to_grips
from engine.finishing.limbs import DEEPER
from engine.finishing.feet import reach_with_leg
from engine.objects import ObjectSpec
from engine.skeleton import ANKLES, FEET, HIPS, KNEES, SHOULDERS, bone_lengths, rest_pose
from engine.storyboard import Agent, Contact, Keypose, SceneObject, Storyboard
from engine.synth.reach import UP, yaw_matrix

N, HOLD = 80, (30, 50)


def standing_over_a_box(keys=(), ahead: float = 0.45):
    """One person standing still, a box on the floor `ahead` m in front, held by both hands over HOLD.
    Returns storyboard, joints (N, 1, 22, 3), the box's pose (N, 1, 7)."""
    sb = Storyboard(length=N, agents=[Agent("A")], objects=[SceneObject("box", ObjectSpec("box", (0.4, 0.5, 0.3)))],
                    contacts=[Contact("A", "left", *HOLD, "box", 2), Contact("A", "right", *HOLD, "box", 0)])
    sb.keyposes = [Keypose("A", k, np.zeros((22, 2)), np.arange(22) == 0) for k in keys]   # the pelvis placed
    pose = np.zeros((N, 1, 7))
    pose[:, 0, 2], pose[:, 0, 3] = ahead, 1.0                       # at z = ahead, unturned
    return sb, np.tile(knees_bent(), (N, 1, 1, 1)), pose


def knees_bent(by: float = 0.05) -> np.ndarray:
    """The rest pose (22, 3) lowered `by` m on its feet (a straight leg reaches no lower)."""
    rest = rest_pose()
    pose = rest - by * UP
    for side, foot in enumerate(FEET):
        pose = reach_with_leg(pose[None], side, rest[None, foot])[0]
    return pose


def test_a_holder_crouches_towards_grips_below_its_reach():
    sb, joints, pose = standing_over_a_box()
    config = ContactConfig()
    out = crouch_to_grips(joints, pose, sb, config)
    anchors = object_anchors(pose, sb)
    drop = joints[:, 0, 0, 1] - out[:, 0, 0, 1]
    legs = (np.linalg.norm(joints[:, 0, list(KNEES)] - joints[:, 0, list(HIPS)], axis=-1)
            + np.linalg.norm(joints[:, 0, list(ANKLES)] - joints[:, 0, list(KNEES)], axis=-1)).mean(-1)
    lowest = config.lowest_squat * legs
    middle = slice(HOLD[0] + 3, HOLD[1] - 2)
    assert np.allclose(out[middle, 0, 0, 1], lowest[middle], atol=2e-3)       # the grips are far below: a full squat
    assert (out[:, 0, 0, 1] >= lowest - 1e-9).all()
    grip = anchors[:, 0, [2, 0]]
    before = np.linalg.norm(grip - joints[:, 0, list(SHOULDERS)], axis=-1)
    after = np.linalg.norm(grip - out[:, 0, list(SHOULDERS)], axis=-1)
    assert (after[middle] < before[middle] - 0.2).all()
    np.testing.assert_allclose(out[:, 0, list(FEET)], joints[:, 0, list(FEET)], atol=1e-9)   # the feet stay
    np.testing.assert_allclose(bone_lengths(out), bone_lengths(joints), atol=1e-9)
    np.testing.assert_allclose(arm_lengths(out), arm_lengths(joints), atol=1e-9)
    assert np.abs(np.diff(drop, 2)).max() < 0.03                               # eased in and out
    # Down by the hold's start, 3 cm a frame, from where it is eased onto the grips.
    ramp = HOLD[0] - config.blend_frames - int(np.ceil(drop.max() * config.crouch_frames_per_metre))
    assert drop[ramp - 5:ramp + 1].max() < 0.02 and drop[HOLD[0]] > 0.3
    far = np.r_[:ramp - 6, 2 * np.mean(HOLD).astype(int) - ramp + 6:N]
    np.testing.assert_allclose(out[far], joints[far])                          # only around the hold


def test_a_key_frame_in_the_hold_keeps_its_pose():
    sb, joints, pose = standing_over_a_box(keys=[40])
    out = crouch_to_grips(joints, pose, sb)
    np.testing.assert_allclose(out[40], joints[40])
    assert out[33, 0, 0, 1] < joints[33, 0, 0, 1] - 0.1


def test_grips_within_reach_need_no_crouch():
    sb, joints, pose = standing_over_a_box()
    raised = pose + np.array([0.0, 0.85, -0.2, 0, 0, 0, 0])                  # at the chest, in front
    np.testing.assert_allclose(crouch_to_grips(joints, raised, sb), joints)


def test_a_crouch_takes_no_knee_into_the_box():
    """The box close in front: a full squat would put the knees into it; the crouch stops short."""
    sb, joints, pose = standing_over_a_box(ahead=0.3)
    out = crouch_to_grips(joints, pose, sb)
    objects = (pose, [o.spec for o in sb.objects])
    assert (_depth(out[:, 0], objects) <= _depth(joints[:, 0], objects) + DEEPER + 1e-9).all()
    assert _depth(_crouched(joints[:, 0], np.full(N, 0.35)), objects).max() > 0.03   # it would have


def trunk_tilt(joints: np.ndarray) -> np.ndarray:
    """Degrees (N,) of one person's pelvis-to-shoulders line from upright; joints (N, 22, 3)."""
    trunk = joints[:, list(SHOULDERS)].mean(1) - joints[:, 0]
    return np.degrees(np.arccos(trunk[:, 1] / np.linalg.norm(trunk, axis=-1)))


def test_what_a_squat_leaves_out_of_reach_a_holder_leans_forward_for():
    sb, joints, pose = standing_over_a_box()
    config = ContactConfig()
    squat = crouch_to_grips(joints, pose, sb, ContactConfig(most_lean=0.0))
    out = crouch_to_grips(joints, pose, sb, config)
    middle = slice(HOLD[0] + 3, HOLD[1] - 2)
    tilt = trunk_tilt(out[:, 0])
    assert (tilt[middle] > trunk_tilt(squat[:, 0])[middle] + 20).all() and tilt.max() <= config.most_lean + 1e-6
    grip = object_anchors(pose, sb)[:, 0, [2, 0]]
    reach = config.reach * arm_lengths(out)[:, 0]
    assert (np.linalg.norm(grip - out[:, 0, list(SHOULDERS)], axis=-1)[middle] < reach[middle] + 0.02).all()
    legs = [0, *HIPS, *KNEES, *ANKLES, *FEET]
    np.testing.assert_allclose(out[:, 0, legs], squat[:, 0, legs])           # the hips bend, the legs stay
    np.testing.assert_allclose(bone_lengths(out), bone_lengths(joints), atol=1e-9)
    assert np.abs(np.diff(tilt, 2)).max() < 1.0                                # degrees a frame per frame: eased


def test_a_lean_takes_no_chest_into_the_box():
    """A tall crate close in front: leaning as far as its grips ask would put the chest into it."""
    sb, joints, pose = standing_over_a_box(ahead=0.35)
    sb.objects = [SceneObject("box", ObjectSpec("box", (0.4, 0.8, 0.3)))]
    config = ContactConfig()
    squat = crouch_to_grips(joints, pose, sb, ContactConfig(most_lean=0.0))
    out = crouch_to_grips(joints, pose, sb, config)
    objects = (pose, [o.spec for o in sb.objects])
    assert (_depth(out[:, 0], objects) <= _depth(squat[:, 0], objects) + DEEPER + 1e-9).all()
    asked = _lean(squat, _shortfall(squat, object_anchors(pose, sb), sb, config), config)[:, 0]
    assert _depth(_leaned(squat[:, 0], asked), objects).max() > _depth(squat[:, 0], objects).max() + 0.02   # it would have
    assert 20 < trunk_tilt(out[:, 0]).max() < np.degrees(asked.max()) - 5   # leaning less


def test_two_holders_lean_no_deeper_into_each_other():
    """Two carriers face each other over a box on the floor, 60 cm apart: leaning as far as the
    grips ask, their heads would meet."""
    sb, joints, pose = standing_over_a_box(ahead=0.3)
    sb.agents.append(Agent("B"))
    sb.contacts += [Contact("B", "left", *HOLD, "box", 0), Contact("B", "right", *HOLD, "box", 2)]
    centre = np.array([0.0, 0.0, 0.3])
    facing_a = (joints[:, 0] - centre) @ yaw_matrix(np.array(np.pi)).T + centre    # half a turn about the box
    both = np.stack([joints[:, 0], facing_a], 1)
    squat = crouch_to_grips(both, pose, sb, ContactConfig(most_lean=0.0))
    out = crouch_to_grips(both, pose, sb)
    nothing = (pose[:, :0], [])

    def into_each_other(people):
        return np.maximum(_depth(people[:, 0], nothing, people[:, 1:]), 0.0)

    asked = np.stack([_leaned(squat[:, a], np.full(N, 1.0)) for a in range(2)], 1)
    assert into_each_other(asked).max() > into_each_other(squat).max() + 0.1          # they would have
    assert (into_each_other(out) <= into_each_other(squat) + DEEPER + 1e-9).all()
    assert trunk_tilt(out[:, 0]).max() > 20                                            # the first still leans

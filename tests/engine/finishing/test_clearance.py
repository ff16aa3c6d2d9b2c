"""Hands and feet that never go through the objects (engine/finishing/clearance.py)."""
from dataclasses import replace

import numpy as np
import pytest

from engine.finishing import finish
from engine.body import SPHERE_RADII, body_points
from engine.finishing.clearance import clear_feet, clear_hands
from engine.finishing.held import true_spans
from engine.objects import world_to_local
from engine.skeleton import FEET, JOINT_INDEX, bone_lengths
from engine.sketchify import sketchify
from engine.synth import synthesize

from .saved import saved_generation

WRIST = JOINT_INDEX["r_wrist"]


def stances(foot):
    """Inclusive [first, last] frame spans where foot (N, 3) stands still."""
    still = np.linalg.norm(np.diff(foot, axis=0), axis=-1) < 1e-4            # (N-1,) steps
    return [(first, last + 1) for first, last in true_spans(still)]


def wrist_depth(joints, obj_pose, spec, person):
    """How far (N,) the person's right wrist joint lies inside the object (negative: outside)."""
    local = world_to_local(joints[:, person, WRIST][:, None], obj_pose[:, 0])[:, 0]
    return -spec.sdf_local(local)


def test_a_free_hand_is_pushed_out_and_a_holding_hand_is_left_on_its_grip():
    clip = synthesize("carry_together", 0, fps=20)
    sb = sketchify(clip, 4, 0.0, 0)
    done = finish(clip, sb)
    joints, pose, spec = done.joints.astype(float), done.obj_pose.astype(float), sb.objects[0].spec
    hold = next(c for c in sb.contacts if c.hand == "right")
    person = sb.agent_index(hold.agent)
    free = np.ones(len(joints), bool)
    for c in sb.contacts:
        if c.hand == "right" and sb.agent_index(c.agent) == person:
            free[c.start:c.end + 1] = False
    # Frames just before the hold: the right wrist put 6 cm inside the box, as a generated
    # hand blending onto its grip can be.
    sunk = joints.copy()
    frames = np.arange(hold.start - 4, hold.start - 1)
    centre = pose[frames, 0, :3] + (0.0, spec.size[1] / 2, 0.0)
    sunk[frames, person, WRIST] = centre + 0.5 * (sunk[frames, person, WRIST] - centre)
    assert wrist_depth(sunk, pose, spec, person)[frames].min() > 0.0
    out = clear_hands(sunk, pose, sb)
    assert wrist_depth(out, pose, spec, person)[free].max() <= -0.02 + 1e-6      # its radius off the surface
    assert np.array_equal(out[~free, person, WRIST], sunk[~free, person, WRIST])   # on its grip
    np.testing.assert_allclose(bone_lengths(out), bone_lengths(sunk), atol=1e-9)
    moved = np.any(out != sunk, axis=-1)
    assert not np.delete(moved, [JOINT_INDEX[j] for j in ("l_elbow", "r_elbow", "l_wrist", "r_wrist")], axis=2).any()


@pytest.mark.parametrize("scenario", ["lift_adjust", "let_go"])
def test_the_finished_motion_keeps_a_free_hand_out_of_the_box(scenario):
    """A generated right hand that darts into the box before its hold: the push out of it pops,
    and the steadying that smooths the pop must not put the hand back in."""
    clip = synthesize(scenario, 0, fps=20)
    sb = sketchify(clip, 4, 0.0, 0)
    hold = next(c for c in sb.contacts if c.hand == "right")
    person = sb.agent_index(hold.agent)
    joints, pose, spec = clip.joints.astype(float), clip.obj_pose.astype(float), sb.objects[0].spec
    frames = np.arange(hold.start - 6, hold.start - 2)
    joints[frames, person, WRIST] = pose[frames, 0, :3] + (0.0, spec.size[1] / 2, 0.0)   # at its centre
    done = finish(replace(clip, joints=joints.astype(np.float32)), sb)
    free = np.ones(len(joints), bool)
    for c in sb.contacts:
        if c.hand == "right" and sb.agent_index(c.agent) == person:
            free[c.start:c.end + 1] = False
    depth = wrist_depth(done.joints.astype(float), done.obj_pose.astype(float), spec, person)
    assert depth[free].max() <= -0.02 + 1e-3                       # within a millimetre of its radius


def test_a_hand_letting_go_into_a_carried_box_stays_out_through_the_last_steadying():
    """The shipped model's motion for a hand-drawn hand-off (synthesized scene 102, drawn with
    engine.artist_sketch seed 2; saved): the giver's right hand lets go into the box the partner
    carries on. Pushed out exactly at the frames it sank and smoothed between, the push popped,
    and the final steadying smoothed the hand 5 cm back in; eased as an envelope, it stays out."""
    sb, clip = saved_generation("handoff_release")
    done = finish(clip, sb)
    joints, pose = done.joints.astype(float), done.obj_pose.astype(float)
    holding = sb.holding()
    for side, wrist in enumerate((JOINT_INDEX["l_wrist"], JOINT_INDEX["r_wrist"])):
        for h in range(joints.shape[1]):
            local = world_to_local(joints[:, h, wrist][:, None], pose[:, 0])[:, 0]
            depth = -sb.objects[0].spec.sdf_local(local)                      # > 0: inside
            assert depth[~holding[:, h, side]].max() <= -0.02 + 0.01          # within 1 cm of its radius


def test_a_foot_standing_in_a_box_steps_out_sideways_and_stays_planted():
    """The box put down where the right foot stands before the hold (as a person stepping in
    beside a box on the floor puts a foot 10 cm into it): the foot goes out to the side of the
    box's footprint, by one push through the whole stance (so the planted foot does not slide),
    the knee on both leg bones' lengths; nothing else moves, and once the box is back where it
    was, what moves is what moves without it there."""
    clip = synthesize("carry_together", 0, fps=20)
    sb = sketchify(clip, 4, 0.0, 0)
    done = finish(clip, sb)
    joints, pose, spec = done.joints.astype(float), done.obj_pose.astype(float), sb.objects[0].spec
    foot, person = JOINT_INDEX["r_foot"], 0
    first = min(c.start for c in sb.contacts)
    start = min(span[0] for span in stances(joints[:, person, foot]) if span[1] >= first - 1)
    stance = np.arange(start, first)                                       # the box there
    assert len(stance) >= 5
    box = pose.copy()
    box[:first, 0, :3] = joints[start, person, foot] * (1.0, 0.0, 1.0) + (spec.size[0] / 4, 0.0, 0.0)
    box[:first, 0, 3:] = pose[0, 0, 3:]
    sunk = lambda j: np.maximum(spec.penetration_local(
        world_to_local(body_points(j[:, person])[0], box[:, 0]), SPHERE_RADII), 0.0)   # (N, 43)
    leg = [JOINT_INDEX[j] for j in ("r_ankle", "r_foot")] + [22 + 10]               # ankle, foot, between
    assert sunk(joints)[stance][:, leg].max() > 0.05
    out = clear_feet(joints, box, sb)
    assert sunk(out)[stance][:, leg].max() <= 1e-3
    np.testing.assert_allclose(np.diff(out[stance, person, foot], axis=0), 0.0, atol=1e-4)   # planted
    np.testing.assert_allclose(out[stance, person, foot, 1], joints[stance, person, foot, 1], atol=1e-9)   # sideways
    np.testing.assert_allclose(bone_lengths(out), bone_lengths(joints), atol=1e-9)
    moved = np.any(out != joints, axis=-1)
    legs = [JOINT_INDEX[j] for j in ("r_knee", "r_ankle", "r_foot", "l_knee", "l_ankle", "l_foot")]
    assert not np.delete(moved, legs, axis=2).any()
    after = 10 + max(span[1] for foot in FEET for span in stances(joints[:, person, foot]) if span[0] < first)
    assert np.array_equal(out[after:], clear_feet(joints, pose, sb)[after:])   # the box as it was

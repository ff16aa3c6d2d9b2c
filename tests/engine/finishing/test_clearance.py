"""Hands that never go through the objects (engine/finishing/clearance.py)."""
from dataclasses import replace

import numpy as np
import pytest

from engine.finishing import finish
from engine.finishing.clearance import clear_hands
from engine.objects import world_to_local
from engine.skeleton import JOINT_INDEX, bone_lengths
from engine.sketchify import sketchify
from engine.synth import synthesize

from .saved import saved_generation

WRIST = JOINT_INDEX["r_wrist"]


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

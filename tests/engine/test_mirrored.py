"""A figure posed from the canvas's template for a person who faces away (engine.mirrored): its
template joints are taken as unplaced, and the person warped onto it keeps facing away."""
import numpy as np

from engine.artist_sketch import DRAGGED
from engine.facing import facing, towards_camera
from engine.finishing.warp import warp_to_keyposes
from engine.mirrored import TEMPLATE_JOINTS, crossed_over, without_mirrored_template
from engine.poses import standing_pose_2d
from engine.request import Request
from engine.rig import drag_pose
from engine.skeleton import FEET, JOINT_INDEX, fit_offsets, rest_pose
from engine.storyboard import Agent, Keypose, Storyboard
from engine.synth.reach import heading_of, yaw_matrix

N, KEY = 30, 15


def standing(sb: Storyboard, away: bool) -> np.ndarray:
    """The rest pose (22, 3) facing the camera (or away from it), feet on the ground, 1 m to the side."""
    pose = rest_pose() - (0.0, rest_pose()[list(FEET), 1].min() - 0.02, 0.0)
    towards = towards_camera(sb.camera)
    yaw = heading_of(-towards if away else towards) - facing(pose)
    return pose @ yaw_matrix(np.array(yaw)).T + (1.0, 0.0, 0.0)


def posed_for(sb: Storyboard, pose: np.ndarray) -> Keypose:
    """The template clicked at the pose's pelvis, its hands, feet and head dragged onto the pose's."""
    seen = sb.camera.project(pose)
    template = standing_pose_2d(sb.camera)
    points, placed = template + seen[0], np.ones(22, bool)
    for name in DRAGGED:
        points = drag_pose(points, placed, JOINT_INDEX[name], seen[JOINT_INDEX[name]], template=template)
    return Keypose("A", KEY, points, placed)


def test_a_template_posed_for_someone_facing_away_crosses_over():
    sb = Storyboard(length=N, agents=[Agent("A")])
    away, towards = standing(sb, away=True), standing(sb, away=False)
    assert crossed_over(posed_for(sb, away))
    assert not crossed_over(posed_for(sb, towards))
    drawn = Keypose("A", KEY, sb.camera.project(away), np.ones(22, bool))    # drawn by hand, facing away
    assert not crossed_over(drawn)
    turned = posed_for(sb, away)
    turned.depth = np.zeros(22)                  # a figure turned with the tool knows which way it faces
    assert not crossed_over(turned)


def test_only_its_hands_feet_and_head_stay_placed():
    sb = Storyboard(length=N, agents=[Agent("A")])
    crossed, fine = posed_for(sb, standing(sb, away=True)), posed_for(sb, standing(sb, away=False))
    fine.frame = 25
    sb.keyposes = [crossed, fine]
    mended = without_mirrored_template(sb)
    expected = crossed.mask.copy()
    expected[TEMPLATE_JOINTS] = False
    np.testing.assert_array_equal(mended.keyposes[0].mask, expected)
    assert {JOINT_INDEX[name] for name in DRAGGED} <= set(np.flatnonzero(mended.keyposes[0].mask))
    assert mended.keyposes[1] is fine and sb.keyposes[0].mask.all()      # the storyboard itself stays
    sb.keyposes = [fine]
    assert without_mirrored_template(sb) is sb
    sb.keyposes = [crossed]
    assert not Request.build(sb).storyboard.keyposes[0].mask[TEMPLATE_JOINTS].any()   # what is generated from


def test_warped_onto_it_the_person_keeps_facing_away():
    sb = Storyboard(length=N, agents=[Agent("A")])
    away = standing(sb, away=True)
    sb.keyposes = [posed_for(sb, away)]
    joints = np.tile(away, (N, 1, 1, 1))                       # the generated person faces away too
    offsets = fit_offsets(joints)

    def turn_at_key(storyboard):
        out = warp_to_keyposes(joints, offsets, storyboard)
        return abs(np.angle(np.exp(1j * (facing(out[KEY, 0]) - facing(away)))))

    assert turn_at_key(without_mirrored_template(sb)) < np.radians(10)
    assert turn_at_key(sb) > np.radians(90)                     # solved as drawn, it turns round

"""Artist-style storyboards and the animator's figures: the drawings differ from the traced one as
an artist's do, stay valid, and the figures catch what an animator would reject."""
import itertools

import numpy as np
import pytest

from engine.bench.animator import animator_metrics, bone_change, foot_float, pop, timing
from engine.artist_sketch import UNPLACED_CANDIDATES, hand_drawn, posed_with_tools
from engine.poses import standing_pose_2d
from engine.rig import STRAIGHTEN
from engine.skeleton import JOINT_INDEX, PARENTS, rest_pose
from engine.sketchify import sketchify
from engine.synth import synthesize


@pytest.fixture(scope="module")
def scene():
    clip = synthesize("handoff", 3)
    return clip, sketchify(clip, 4, 0.0, 3)


def test_hand_drawn_storyboards_look_drawn_and_stay_valid(scene):
    clip, clean = scene
    drawn = hand_drawn(clean, 7)
    drawn.validate()
    assert drawn.to_json() == hand_drawn(clean, 7).to_json() and drawn.to_json() != hand_drawn(clean, 8).to_json()
    assert all(8 <= len(t.points) <= 20 for t in drawn.trajectories)
    assert all(len(k.outline) == 4 for k in drawn.object_keys)
    spine = [JOINT_INDEX[n] for n in UNPLACED_CANDIDATES]
    assert any(not k.mask[spine].all() for k in drawn.keyposes)
    moved = [np.linalg.norm(d.points[d.mask] - c.points[d.mask], axis=-1)
             for d, c in zip(drawn.keyposes, clean.keyposes) if d.frame == c.frame]
    assert moved and all(m.min() > 0.0 for m in moved)
    assert {k.frame for k in drawn.keyposes} != {k.frame for k in clean.keyposes}   # interior keys moved


def test_posed_storyboards_are_the_template_posed_with_the_rig(scene):
    clip, clean = scene
    posed = posed_with_tools(clean, 7)
    posed.validate()
    assert all(k.mask.all() for k in posed.keyposes)
    template = standing_pose_2d(clean.camera)
    limbs = [JOINT_INDEX[f"{s}_{j}"] for s in "lr" for j in ("elbow", "wrist", "knee", "ankle", "foot")]
    drawn = {(k.agent, k.frame): k for k in clean.keyposes}
    reached = 0
    straightened = 0
    for p in posed.keyposes:   # the rig keeps the template's bones or straightens a limb; a hand in reach lands on its drag
        grown = _bones(p.points) / np.maximum(_bones(template), 1e-9)
        others = [j for j in range(1, 22) if j not in limbs]
        assert np.allclose(grown[others], 1.0) and np.all((grown[limbs] > 1 - 1e-9) & (grown[limbs] < STRAIGHTEN + 1e-9))
        for side, (upper, lower) in itertools.product("lr", (("elbow", "wrist"), ("knee", "ankle"))):
            assert np.isclose(grown[JOINT_INDEX[f"{side}_{upper}"]], grown[JOINT_INDEX[f"{side}_{lower}"]])   # both bones alike
        straightened += int(np.any(grown[limbs] > 1 + 1e-6))
        c = drawn.get((p.agent, p.frame))
        for side in "lr":
            wrist, shoulder = JOINT_INDEX[f"{side}_wrist"], JOINT_INDEX[f"{side}_shoulder"]
            arm = _bones(template)[[JOINT_INDEX[f"{side}_elbow"], wrist]].sum()
            if c is not None and np.linalg.norm(c.points[wrist] - p.points[shoulder]) < arm - 0.04:
                assert np.linalg.norm(p.points[wrist] - c.points[wrist]) <= 0.031
                reached += 1
    assert reached > 0 and straightened > 0


def _bones(points: np.ndarray) -> np.ndarray:
    """(22, 2) -> each joint's drawn bone length to its parent (22,), the pelvis' 0."""
    return np.linalg.norm(points - points[[max(p, 0) for p in PARENTS]], axis=-1)


def test_the_animator_figures_catch_pops_floats_stretches_and_bad_timing(scene):
    clip, clean = scene
    walk = np.linspace(0.0, 3.0, 120)[:, None, None, None] * np.array([1.0, 0.0, 0.0])
    joints = rest_pose()[None, None] + walk + np.array([[[[0.0, 0.0, 0.0]]], [[[0.0, 0.0, 1.0]]]]).reshape(1, 2, 1, 3)
    assert pop(joints) < 1e-9 and bone_change(joints) < 1e-9
    popped = joints.copy()
    popped[60, 0, JOINT_INDEX["r_wrist"]] += (0.0, 0.3, 0.0)
    assert pop(popped) > 0.25
    assert foot_float(joints + (0.0, 0.1, 0.0)) > foot_float(joints) + 0.09
    stretched = joints.copy()
    stretched[30:, 0, JOINT_INDEX["l_wrist"]] += (0.05, 0.0, 0.0)
    assert bone_change(stretched) > 0.04
    hurried = joints[np.arange(len(joints)) ** 2 // len(joints)]     # stands still, then hurries
    assert timing(hurried, joints, clean) > 0.2 and timing(joints, joints, clean) == 0.0
    figures = animator_metrics(clip, clean, clip)
    assert figures["Wrist@key"] == 0.0 and figures["Detour"] == 0.0 and figures["Timing"] == 0.0

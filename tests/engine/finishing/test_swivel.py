"""Finishing, swivel: an elbow whose arm passes through an object turns about the shoulder-wrist
line to where it does not, keeping both bones, and over frames gradually."""
import numpy as np

from engine.finishing.contacts import ContactConfig
from engine.finishing.swivel import arm_penetration, swivel_clear
from engine.objects import ObjectSpec


def test_an_elbow_in_an_object_swivels_out_keeping_its_bones():
    shoulder, wrist = np.array([[0.0, 1.4, 0.0]]), np.array([[0.45, 1.0, 0.0]])
    elbow = np.array([[0.3, 1.45, 0.0]])                   # bent up and out, into the box above
    box = ObjectSpec("box")
    pose = np.array([[[0.35, 1.3, 0.0, 1.0, 0.0, 0.0, 0.0]]])  # (M, O, 7): the box's base at 1.3 m
    before = arm_penetration(shoulder[:, None], elbow[:, None], wrist[:, None], pose, [box])
    one = [np.array([0])]                                  # one frame: a run of its own
    moved = swivel_clear(shoulder, elbow, wrist, pose, [box], ContactConfig(), one)
    after = arm_penetration(shoulder[:, None], moved[:, None], wrist[:, None], pose, [box])
    assert before[0, 0] > 0.05 and after[0, 0] <= 0.0
    clear = np.array([[0.15, 1.0, 0.1]])                   # an elbow already clear stays, exactly
    assert np.array_equal(swivel_clear(shoulder, clear, wrist, pose, [box], ContactConfig(), one), clear)
    for a, b in ((shoulder, elbow), (wrist, elbow)):
        np.testing.assert_allclose(np.linalg.norm(moved - a, axis=-1), np.linalg.norm(b - a, axis=-1))


def test_an_elbow_swivels_out_of_an_object_gradually_not_in_one_frame():
    """Over consecutive frames the swivel is chosen as a path: an arm that must clear a box
    from some frame on turns over several frames, never flipping by more than a few cm a frame."""
    n = 20
    shoulder, wrist = np.tile([0.0, 1.4, 0.0], (n, 1)), np.tile([0.45, 1.0, 0.0], (n, 1))
    elbow = np.tile([0.3, 1.45, 0.0], (n, 1))
    box = ObjectSpec("box")
    pose = np.tile([0.35, 1.3, 0.0, 1.0, 0.0, 0.0, 0.0], (n, 1, 1))
    pose[:10, 0, 1] = 3.0                                  # the box arrives at frame 10
    moved = swivel_clear(shoulder, elbow, wrist, pose, [box], ContactConfig(), [np.arange(n)])
    after = arm_penetration(shoulder[:, None], moved[:, None], wrist[:, None], pose, [box])
    assert after[:10].max() <= 0.0 and after[13:].max() <= 0.005   # clear within a few frames
    swing, steps = np.linalg.norm(moved[-1] - moved[0]), np.linalg.norm(np.diff(moved, axis=0), axis=-1)
    assert swing > 0.2 and steps.max() < 0.4 * swing      # a per-frame choice made it in one step

"""Two-bone reach helpers (engine/synth/reach.py)."""
import numpy as np

from engine.synth.reach import continuous_pole, two_bone_ik


def test_an_elbow_whose_bend_passes_through_straight_keeps_its_side():
    """An arm reaching down the way its fallback bend points: the pole's part across the arm
    shrinks through zero and comes back reversed; the elbow stays on its side, moving a little
    each frame, where it jumped to the other side in one frame."""
    n = 21
    axis = np.tile([0.0, -1.0, 0.0], (n, 1))
    pole = np.stack([np.linspace(0.02, -0.02, n), np.full(n, -0.05), np.zeros(n)], -1)   # 5 cm along the arm
    shoulder, goal = np.zeros((n, 3)), np.tile([0.0, -0.45, 0.0], (n, 1))
    jumpy, _ = two_bone_ik(shoulder, goal, 0.28, 0.25, pole)
    steady, _ = two_bone_ik(shoulder, goal, 0.28, 0.25, continuous_pole(pole, axis))
    step = lambda elbow: np.linalg.norm(np.diff(elbow, axis=0), axis=-1).max()
    assert step(jumpy) > 0.1 and step(steady) < 0.01
    assert np.all(steady[:, 0] > 0)


def test_a_well_bent_elbow_keeps_its_own_side():
    n = 10
    axis = np.tile([0.0, -1.0, 0.0], (n, 1))
    pole = np.tile([0.0, 0.0, -0.15], (n, 1))                                      # bent 15 cm back
    pole[:5] = [0.0, 0.0, 0.15]                                                   # ... after 15 cm forward
    side = continuous_pole(pole, axis)
    assert np.all(side[:5, 2] > 0) and np.all(side[5:, 2] < 0)

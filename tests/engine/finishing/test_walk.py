"""Walking through the made-up steps' hops: feet in turn, from the stretch's plants to its plants."""
import numpy as np

from engine.finishing.blend import spike
from engine.finishing.feet import FeetConfig
from engine.finishing.walk import walk_through_flights
from engine.skeleton import FEET, rest_pose

N = 40
CONFIG = FeetConfig()


def hopping(distance: float = 0.6):
    """A person (N, 22, 3) gliding `distance` m along +z over frames 5-35 whose feet goals (two
    (N, 3)) stand still before frame 10 and after 30 and fly together, 8 cm up, in between."""
    travel = np.clip((np.arange(N) - 5) / 30, 0, 1) * distance
    pose = rest_pose()[None] + travel[:, None, None] * [0.0, 0.0, 1.0]
    goals = []
    for foot in FEET:
        goal = np.repeat(pose[:1, foot], N, axis=0)
        goal[30:] = pose[-1, foot]
        share = np.linspace(0, 1, 21)[1:-1, None]
        goal[11:30] = (1 - share) * goal[10] + share * goal[31]
        goal[11:30, 1] = 0.08
        goals.append(goal)
    return pose, goals


def test_a_hop_becomes_a_walk_one_foot_at_a_time():
    pose, goals = hopping()
    assert (np.minimum(goals[0][:, 1], goals[1][:, 1]) > CONFIG.stance_height).sum() == 19
    walked = walk_through_flights(goals, pose, [], CONFIG)
    lowest = np.minimum(walked[0][:, 1], walked[1][:, 1])
    assert lowest.max() <= CONFIG.foot_height + 1e-9                      # one foot always stands
    assert all(np.ptp(w[11:30, 1]) > 0.05 for w in walked)                # and each one steps
    for before, after in zip(goals, walked):
        np.testing.assert_array_equal(after[:9], before[:9])              # the plants around it stay
        np.testing.assert_array_equal(after[33:], before[33:])
        assert spike(after).max() <= CONFIG.walk_pop


def test_a_hop_is_left_where_a_walk_cannot_go_smoothly_or_a_key_is():
    pose, goals = hopping()
    for keys, config, pose_used in (([20], CONFIG, pose),                                  # a key inside
                                    ([], FeetConfig(walk_pop=0.001), pose),                # too jolting
                                    ([], CONFIG, pose + [0.0, 0.5, 0.0])):                 # legs too short
        walked = walk_through_flights(goals, pose_used, keys, config)
        for before, after in zip(goals, walked):
            np.testing.assert_array_equal(after, before)


def test_every_step_of_a_walk_moves_as_fast_against_the_body():
    """Three steps: one foot steps once, all the way to its end plant, the other twice. Each step
    takes its share of the body's travel by the distance it covers, so neither foot rushes."""
    pose, goals = hopping(2.0)
    walked = walk_through_flights(goals, pose, [], FeetConfig(walk_pop=1.0, plant_reach=10.0))   # taken
    fastest = [np.linalg.norm(np.diff(w[:, [0, 2]], axis=0), axis=-1).max() for w in walked]
    body = np.linalg.norm(np.diff(pose[:, 0, [0, 2]], axis=0), axis=-1).max()
    assert max(fastest) < 1.3 * min(fastest)
    assert max(fastest) < 7.0 * body            # equal windows: 8.9x, the end step 1.9x the other's

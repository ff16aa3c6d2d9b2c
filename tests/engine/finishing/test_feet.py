"""Feet finishing: grounding and foot locking keep bones, fix sliding and floating, spare good motion."""
import numpy as np
import pytest

from engine.finishing import lasting_as_long
from engine.finishing.blend import ease_frames
from engine.finishing.feet import (HIPS, HOP_HEIGHT, KNEES, STRAIGHTEST, FeetConfig, _foot_goal, _foot_turn_smoothed,
                                  _lift_glides, _lower_in_hops, _with_room_to_step, lock_feet, reach_with_leg, settle_on_ground, stance_intervals)
from engine.metrics import foot_skate_ratio
from engine.skeleton import ANKLES, FEET, bone_lengths, rest_pose
from engine.synth import SCENARIOS, synthesize

FPS = 20.0


@pytest.fixture(scope="module")
def clean() -> dict[str, np.ndarray]:
    """Synthesized clips: planted feet never move, so they are good motion. name -> (N, 2, 22, 3)."""
    return {s: synthesize(s, 0, fps=FPS).joints.astype(float) for s in SCENARIOS}


def slid(joints: np.ndarray, speed: float = 0.7) -> np.ndarray:
    """The whole clip drifting along +x at `speed` m/s, plus a little jitter: every planted
    foot slides, as in the generator's output."""
    n = len(joints)
    drift = np.zeros((n, 1, 1, 3))
    drift[:, 0, 0, 0] = speed * np.arange(n) / FPS
    jitter = np.random.default_rng(0).normal(0.0, 0.003, joints.shape[:2] + (1, 3))
    return joints + drift + jitter


def finish(joints: np.ndarray) -> np.ndarray:
    return lock_feet(settle_on_ground(joints), FPS)


def lowest_foot(joints: np.ndarray) -> np.ndarray:
    return joints[:, :, list(FEET), 1].min(axis=-1)


def test_bone_lengths_are_kept_exactly(clean):
    for joints in clean.values():
        noisy = slid(joints)
        out = finish(noisy)
        assert out.shape == noisy.shape and np.isfinite(out).all()
        assert np.abs(bone_lengths(out) - bone_lengths(noisy)).max() < 1e-9


def test_sliding_feet_are_locked(clean):
    joints = slid(clean["carry_together"])
    before = foot_skate_ratio(joints, FPS)
    after = finish(joints)
    assert before > 0.3
    assert foot_skate_ratio(after, FPS) < 0.05
    # The people still go where they went: only legs move, the pelvis keeps its path.
    assert np.allclose(after[:, :, 0, [0, 2]], joints[:, :, 0, [0, 2]])


def test_planted_foot_holds_still_unless_out_of_reach(clean):
    """A stance pins the foot; where the body has drifted too far from the plant for the leg to
    reach it, the leg is straight instead."""
    joints = settle_on_ground(slid(clean["carry_together"]))
    out = lock_feet(joints, FPS)
    held = stance = 0
    for h in range(out.shape[1]):
        busy = np.ones(len(joints), bool)                  # as lock_feet: the right foot's steps
        for hip, knee, ankle, foot, other in zip(HIPS, KNEES, ANKLES, FEET, FEET[::-1]):   # wait for the left's
            intervals = stance_intervals(joints[:, h, foot], FPS, busy=None if foot == FEET[0] else busy,
                                         other=joints[:, h, other])
            for start, stop in intervals:
                busy[start:stop] = False
            reach = (np.linalg.norm(out[:, h, knee] - out[:, h, hip], axis=-1)
                     + np.linalg.norm(out[:, h, ankle] - out[:, h, knee], axis=-1))
            straight = np.linalg.norm(out[:, h, ankle] - out[:, h, hip], axis=-1) > reach * (1 - 1e-5)
            for start, stop in intervals:
                pinned = out[start:stop, h, foot][~straight[start:stop]]
                if len(pinned):
                    assert np.ptp(pinned[:, [0, 2]], axis=0).max() < 1e-9
                held, stance = held + len(pinned), stance + stop - start
    assert held > 0.9 * stance


@pytest.mark.parametrize("lift", [0.2, -0.1])
def test_floating_and_sinking_people_are_grounded(clean, lift):
    joints = clean["let_go"] + np.array([0.0, lift, 0.0])
    out = settle_on_ground(joints)
    assert np.abs(lowest_foot(out) - FeetConfig().foot_height).max() < 0.01
    # A rigid vertical shift: the horizontal motion is untouched.
    assert np.allclose(out[..., [0, 2]], joints[..., [0, 2]])


def test_settle_does_not_pop():
    """A body that jumps up 5 cm from one frame to the next is brought down gradually."""
    joints = np.repeat(rest_pose()[None, None], 40, 0)
    joints[20:] += np.array([0.0, 0.05, 0.0])
    shift = settle_on_ground(joints)[:, 0, 0, 1] - joints[:, 0, 0, 1]
    assert np.abs(np.diff(shift)).max() < 0.01
    assert abs(shift[0]) < 1e-3 and abs(shift[-1] + 0.05) < 1e-3


def test_a_stance_holding_a_key_frame_plants_the_foot_where_the_key_has_it(clean):
    """Finishing hands the feet the keyposes' frames: the warp placed those poses on the sketch,
    so a stance holding a key plants the foot there (the stance's mean moved sketched feet by
    5 cm)."""
    joints = settle_on_ground(slid(clean["carry_together"]))
    keys = [[30, 70], [50]]
    out = lock_feet(joints, FPS, keys=keys)
    pinned = 0
    for h, frames in enumerate(keys):
        for foot in FEET:
            for start, stop in stance_intervals(joints[:, h, foot], FPS):
                for k in (k for k in frames if start <= k < stop):
                    np.testing.assert_allclose(out[k, h, foot, [0, 2]], joints[k, h, foot, [0, 2]], atol=1e-6)
                    pinned += 1
    assert pinned >= 2


def test_a_glide_before_a_key_is_cut_into_plants_too():
    """A foot gliding 1.5 m along the floor with a key frame near the end: the plant holding the
    key is the key's, and the glide before it is cut into plants of at most max_drift (one
    plant over all of it put the foot 0.6 m ahead of the body: a lunge)."""
    n, config = 40, FeetConfig()
    foot = np.zeros((n, 3))
    foot[:, 0] = np.linspace(0.0, 1.5, n)
    foot[:, 1] = config.foot_height
    intervals = stance_intervals(foot, FPS, config, keys=[35])
    assert any(start <= 35 < stop for start, stop in intervals)
    for start, stop in intervals:
        assert np.ptp(foot[start:stop, 0]) <= config.max_drift + 1e-9


def test_a_fast_glide_between_plants_becomes_a_step_without_a_jolt():
    """The generator's foot slides 0.77 m along the floor in 4 frames between two stands. The
    made-up step gets frames enough and is followed exactly: its foot spikes off its neighbours'
    midpoint by at most step_pop (held to the stands' ends, it spiked 7 cm and the knee 11 cm)."""
    n, config = 60, FeetConfig()
    t = np.arange(n)
    foot = np.zeros((n, 3))
    foot[:, 0] = 0.77 * np.clip((t - 29) / 5, 0, 1)
    foot[:, 1] = config.foot_height
    intervals = stance_intervals(foot, FPS, config)
    assert len(intervals) == 2 and intervals[1][0] - intervals[0][1] >= 7
    busy = np.zeros(n, bool)           # the other foot up at those frames too: a brief hop beats the jolt
    busy[27:38] = True
    for other_up in (None, busy):
        intervals = stance_intervals(foot, FPS, config, other_up)
        goal = _foot_goal(foot, intervals, config)
        spike = np.linalg.norm(goal[1:-1] - 0.5 * (goal[:-2] + goal[2:]), axis=-1)
        assert spike.max() <= config.step_pop + 0.005
        assert goal[:, 1].max() > 0.05                           # it lifts: no slide


def gait(n: int, phase: int, glide: float, config: FeetConfig) -> tuple[np.ndarray, np.ndarray]:
    """A runner's foot path (n, 3): 8-frame swings 6 cm up at 3 m/s, and between them 8 frames
    gliding along the floor at `glide` m/s, from frame `phase` of the cycle; and its gliding
    frames (n,) bool."""
    t = np.arange(n) + phase
    swing = (t // 8) % 2 == 0
    x = np.cumsum(np.where(swing, 3.0, glide)) / FPS
    y = config.foot_height + np.where(swing, 0.06 * np.sin(np.pi * (t % 8 + 0.5) / 8), 0.0)
    return np.stack([x, y, np.zeros(n)], -1), ~swing


def test_a_low_foot_gliding_under_the_other_foots_swing_is_planted():
    """A runner's foot glides at 1 m/s between its swings: amid the swings' speed too fast for a
    stance of its own (it skated), but the other foot swings then, so it bears the weight and
    is planted."""
    n, config = 64, FeetConfig()
    foot, gliding = gait(n, 0, 1.0, config)
    other, _ = gait(n, 8, 1.0, config)
    glides = [np.flatnonzero(gliding)[i:i + 8] for i in range(0, gliding.sum(), 8)]

    def planted(intervals, frames):
        return any(start <= frames[1] and frames[-2] < stop for start, stop in intervals)

    assert not any(planted(stance_intervals(foot, FPS, config), frames) for frames in glides[:-1])
    intervals = stance_intervals(foot, FPS, config, other=other)
    goal = _foot_goal(foot, intervals, config)
    for frames in glides:
        assert planted(intervals, frames)
        assert np.ptp(goal[frames[1]:frames[-1], 0]) < 1e-9             # still while the other swings


def test_a_step_with_no_room_while_the_other_foot_stands_takes_a_brief_hop():
    """Two plants 0.77 m apart, 4 frames between them, the second short, the other foot up
    before the gap: rather than a 4-frame step (a jolt) the first plant ends early."""
    n, config = 50, FeetConfig()
    foot = np.zeros((n, 3))
    foot[42:, 0] = 0.77
    busy = np.zeros(n, bool)
    busy[30:38] = True
    (_, end), (start, _) = _with_room_to_step([(0, 38), (42, 46)], foot, config, busy=busy)
    assert start - end >= 7


def test_a_fast_swing_of_the_foots_own_gets_frames_enough_to_leave_and_land_slowly():
    """The decoder's stride: planted until frame 20, over 0.8 m by frame 25, lifting 10 cm. Its
    plants give it frames enough to jolt at most swing_pop (held to them, it spiked 6-12 cm)."""
    n, config = 40, FeetConfig()
    foot = np.full((n, 3), [0.0, config.foot_height, 0.0])
    s = np.arange(1, 5) / 5
    foot[20:24] = np.stack([0.8 * s, config.foot_height + 0.1 * np.sin(np.pi * s), 0 * s], -1)
    foot[24:, 0] = 0.8
    (_, end), (start, _) = _with_room_to_step([(3, 20), (24, 37)], foot, config)
    need = ease_frames(0.8, config.swing_pop, config.step_frames, config.max_step_frames)
    assert start - end >= need > 4
    assert _with_room_to_step([(3, 20), (24, 37)], foot, config, keys=[19, 24]) == [(3, 20), (24, 37)]


def test_a_foot_gliding_fast_while_the_other_stands_is_lifted_into_a_step():
    """The decoder drags a swinging foot along the floor at 1.5 m/s for 16 frames, too long a gap
    for a made-up step: it rises with its speed, smoothly, where the other foot stands, and not
    where that one is up too (a hop) or at a key (the warp's feet)."""
    n, config = 40, FeetConfig()
    glide = np.zeros((n, 3))
    glide[:, 0] = 1.5 * np.clip(np.arange(n) - 10, 0, 16) / FPS
    glide[:, 1] = config.foot_height
    stand = np.array([0.0, config.foot_height, 0.2]) * np.ones((n, 1))
    lifted, kept = _lift_glides([glide, stand], FPS, config)
    y = lifted[:, 1]
    assert y[13:24].min() > 0.07 and y[:9].max() == y[28:].max() == config.foot_height
    assert np.abs(y[1:-1] - 0.5 * (y[:-2] + y[2:])).max() < config.step_pop       # no jolt
    assert np.array_equal(lifted[:, [0, 2]], glide[:, [0, 2]]) and np.array_equal(kept, stand)
    up = stand + [0.0, 0.1, 0.0]
    assert np.array_equal(_lift_glides([glide, up], FPS, config)[0], glide)
    assert _lift_glides([glide, stand], FPS, config, keys=[18])[0][18, 1] == config.foot_height


def test_a_body_too_tall_for_its_planted_legs_crouches_until_the_feet_reach_the_ground():
    """Straight legs 2 cm too short for the ground: without the crouch the planted feet hover."""
    joints = settle_on_ground(np.repeat(rest_pose()[None, None], 40, 0)) + np.array([0.0, 0.02, 0.0])
    out = lock_feet(joints, FPS)
    np.testing.assert_allclose(out[:, 0, list(FEET), 1], FeetConfig().foot_height, atol=1e-3)
    assert 0.015 < float(np.max(joints[:, 0, 0, 1] - out[:, 0, 0, 1])) <= FeetConfig().max_crouch
    assert np.abs(bone_lengths(out) - bone_lengths(joints)).max() < 1e-9


def distance_to_path(points: np.ndarray, path: np.ndarray) -> np.ndarray:
    """Distance (M,) of each point (M, 3) to the polyline path (P, 3)."""
    a, b = path[:-1], path[1:]
    t = np.clip(np.einsum("mpk,pk->mp", points[:, None] - a, b - a) / np.maximum(np.sum((b - a) ** 2, -1), 1e-12), 0, 1)
    return np.linalg.norm(a + t[..., None] * (b - a) - points[:, None], axis=-1).min(-1)


def test_good_motion_is_left_alone(clean):
    """But for a body lowered by a centimetre at most where a stance leg is straighter than
    leg_extension allows (the synthesizer's stand at 97-98%), and feet that leave or reach their
    plants at swing speed, which go along their own paths at an eased pace (the legs with them),
    and a hop's lower foot, which comes down to HOP_HEIGHT."""
    for name, joints in clean.items():
        out = finish(joints)
        moved = np.linalg.norm(out - joints, axis=-1)
        for h in range(joints.shape[1]):
            for foot in FEET:
                still = np.linalg.norm(np.diff(joints[:, h, foot], axis=0), axis=-1) < 1e-4
                planted = np.concatenate([still, [False]]) & np.concatenate([[False], still])
                assert moved[planted, h, foot].max() < 0.003, name      # the plants stay where they were
                # So do the paths, but for the lower foot of a hop (its run's flight) 2 cm lower at most.
                assert distance_to_path(out[:, h, foot], joints[:, h, foot]).max() < 0.02, name
        legs = [*HIPS, *KNEES, *ANKLES, *FEET]
        assert np.delete(moved, legs, axis=2).max() < 0.015, name   # the body a centimetre lower at most


def test_a_foot_released_at_swing_speed_leaves_and_lands_slowly():
    """A swing of the foot's own that covers 1 m in 4 frames from a standstill jolts 12 cm off its
    plant; retimed along its path, it leaves and lands at an eased pace, plants and path kept."""
    n, config = 40, FeetConfig()
    foot = np.zeros((n, 3))
    foot[:, 1] = config.foot_height
    foot[20:25, 0] = np.arange(1, 6) * 0.25
    foot[25:, 0] = 1.25
    foot[20:25, 1] += 0.1 * np.sin(np.pi * np.arange(1, 6) / 6)
    intervals = [(0, 20), (25, n)]
    goal = _foot_goal(foot, intervals, config)
    spikes = lambda path: np.linalg.norm(path[1:-1] - 0.5 * (path[:-2] + path[2:]), axis=-1).max()
    assert spikes(foot) > 0.12
    assert spikes(goal) < 0.08
    np.testing.assert_allclose(goal[:20], foot[:20], atol=1e-9)
    np.testing.assert_allclose(goal[25:], foot[25:], atol=1e-9)
    assert distance_to_path(goal, foot).max() < 1e-6


def test_a_heel_that_rises_in_one_frame_turns_the_foot_over_a_few_frames_by_a_centimetre_at_most():
    """The decoder's heel rises as its foot leaves the plant: on a foot held planted and then
    lifted in the same frame, the ankle spiked more than the foot. The foot's direction about
    its ankle is smoothed, its length kept, and no frame turned by more than most_foot_turn."""
    config, n = FeetConfig(), 20
    poses = np.repeat(rest_pose()[None], n, axis=0)
    toe, ankle = FEET[1], ANKLES[1]
    foot = poses[:, toe] - poses[:, ankle]
    heel_up = np.where(np.arange(n) < 10, 0.0, 0.5)                              # radians, about x
    c, s = np.cos(heel_up), np.sin(heel_up)
    poses[:, toe] = poses[:, ankle] + np.stack([foot[:, 0], c * foot[:, 1] - s * foot[:, 2],
                                                s * foot[:, 1] + c * foot[:, 2]], -1)
    out = _foot_turn_smoothed(poses, 1, config.foot_turn_sigma, config.most_foot_turn)
    spikes = lambda p: np.linalg.norm(p[1:-1] - 0.5 * (p[:-2] + p[2:]), axis=-1).max()
    assert spikes(out[:, toe] - out[:, ankle]) < 0.8 * spikes(poses[:, toe] - poses[:, ankle])
    np.testing.assert_allclose(np.linalg.norm(out[:, toe] - out[:, ankle], axis=-1),
                               np.linalg.norm(foot, axis=-1), atol=1e-12)
    assert np.linalg.norm(out[:, toe] - poses[:, toe], axis=-1).max() <= 1.01 * config.most_foot_turn   # back on its length
    np.testing.assert_array_equal(np.delete(out, toe, axis=1), np.delete(poses, toe, axis=1))


@pytest.mark.parametrize("n, h", [(1, 1), (1, 2), (2, 1), (7, 1)])
def test_tiny_clips(n, h):
    joints = np.repeat(rest_pose()[None, None], n, 0).repeat(h, 1)
    joints[..., 1] += 0.03
    out = finish(joints)
    assert out.shape == joints.shape and np.isfinite(out).all()
    assert np.allclose(lowest_foot(out), FeetConfig().foot_height)


def test_straight_legs_and_unreachable_plants_stay_finite():
    """Rest pose legs are straight (no knee direction); a body that runs off faster than the leg
    can follow leaves plants out of reach. Neither may produce NaN or stretch a bone."""
    n = 40
    joints = np.repeat(rest_pose()[None, None], n, 0)
    joints[:, 0, :, 2] += np.linspace(0.0, 0.8, n)[:, None]          # 0.4 m/s, slow enough to plant
    out = lock_feet(joints, FPS, FeetConfig(max_drift=10.0))
    assert np.isfinite(out).all()
    assert not np.allclose(out, joints)                                 # the feet were held back
    assert np.abs(bone_lengths(out) - bone_lengths(joints)).max() < 1e-9


def test_durations_last_as_long_at_any_frame_rate():
    at40 = lasting_as_long(FeetConfig(), 40.0)
    assert (at40.blend_frames, at40.speed_sigma, at40.max_step_frames) == (6, 6.0, 16)
    assert at40.stance_speed == FeetConfig().stance_speed and at40.max_drift == FeetConfig().max_drift
    assert lasting_as_long(FeetConfig(), 20.0) == FeetConfig()
    assert lasting_as_long(FeetConfig(), 1.0).min_stance_frames == 1      # never below one frame


def test_a_nearly_straight_leg_never_bends_its_knee_backwards():
    """A standing leg whose knee sits 4 cm behind the hip-ankle line (noise): reaching a foot
    goal 10 cm higher bends the knee forward, the way the body faces."""
    poses = np.repeat(rest_pose()[None], 5, 0)
    hip, knee, ankle, foot = HIPS[0], KNEES[0], ANKLES[0], FEET[0]
    facing = np.cross(poses[0, HIPS[0]] - poses[0, HIPS[1]], (0.0, 1.0, 0.0))
    facing /= np.linalg.norm(facing)
    poses[:, knee] -= 0.04 * facing
    goal = poses[:, foot] + (0.0, 0.1, 0.0)
    out = reach_with_leg(poses, 0, goal)
    line = out[:, ankle] - out[:, hip]
    bend = out[:, knee] - out[:, hip]
    bend -= np.sum(bend * line, -1, keepdims=True) / np.sum(line * line, -1, keepdims=True) * line
    assert (bend @ facing > 0.05).all()
    np.testing.assert_allclose(out[:, foot], goal, atol=1e-6)


def test_a_leg_never_straightens_so_its_knee_never_swings_fast():
    """A foot goal drawn in from beyond the leg's reach to within it, 1% of the leg a frame: the
    leg stops short of straight, and the knee moves a few cm a frame, not the 6 cm of the
    last percent before straight."""
    n = 11
    poses = np.repeat(rest_pose()[None], n, 0)
    hip, knee, ankle, foot = HIPS[0], KNEES[0], ANKLES[0], FEET[0]
    leg = np.linalg.norm(poses[0, knee] - poses[0, hip]) + np.linalg.norm(poses[0, ankle] - poses[0, knee])
    down = (poses[0, ankle] - poses[0, hip]) / np.linalg.norm(poses[0, ankle] - poses[0, hip])
    share = np.linspace(1.05, 0.95, n)[:, None]
    goal = poses[:, hip] + share * leg * down + (poses[:, foot] - poses[:, ankle])
    out = reach_with_leg(poses, 0, goal)
    knee_steps = np.linalg.norm(np.diff(out[:, knee], axis=0), axis=-1)
    assert knee_steps.max() < 0.035
    reach = np.linalg.norm(out[:, ankle] - out[:, hip], axis=-1) / leg
    assert reach.max() <= STRAIGHTEST + 1e-9
    np.testing.assert_allclose(out[share[:, 0] <= STRAIGHTEST, foot], goal[share[:, 0] <= STRAIGHTEST], atol=1e-6)


def test_the_lower_foot_of_a_hop_comes_down_to_skim_the_floor():
    """Both feet up for six frames (one stepping, one hovering at 9 cm): the stepping one comes
    down to HOP_HEIGHT there, eased, never under stance_height where it was over; the other is
    untouched."""
    n, config = 30, FeetConfig()
    step, hover = np.zeros((n, 3)), np.zeros((n, 3))
    step[:, 1] = hover[:, 1] = config.foot_height
    step[10:18, 1] = 0.02 + 0.06 * np.sin(np.pi * np.arange(1, 9) / 9)
    hover[8:20, 1] = 0.09
    left, right = _lower_in_hops([step, hover], config)
    assert np.array_equal(right, hover)
    up = (step[:, 1] > HOP_HEIGHT) & (hover[:, 1] > HOP_HEIGHT)
    assert up.sum() >= 4 and (left[up, 1] <= HOP_HEIGHT + 1e-12).all()
    assert (left[:, 1] >= np.minimum(step[:, 1], config.stance_height) - 1e-12).all()
    assert np.abs(np.diff(left[:, 1], 2)).max() <= np.abs(np.diff(step[:, 1], 2)).max() + 1e-9

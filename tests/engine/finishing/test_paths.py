"""Pelvis strokes walked on time (engine/finishing/paths.py)."""
from dataclasses import replace

import numpy as np
import pytest

from engine.finishing import consistent_skeleton
from engine.finishing.keys import key_frames
from engine.finishing.paths import PathConfig, follow_paths, matched, timed_way
from engine.finishing.warp import warp_to_keyposes
from engine.geometry.polylines import point_polyline_distance
from engine.storyboard import Trajectory, floor_path_points

from .test_warp import disturbed, scene  # noqa: F401 (a fixture)


def test_follow_paths_puts_the_pelvis_on_its_stroke_and_leaves_the_keyposes_where_they_are(scene):
    clip, sb = scene
    joints, offsets = consistent_skeleton(disturbed(clip.joints) + (0.3, 0.0, 0.0))
    keyed = warp_to_keyposes(joints, offsets, sb)
    moved = follow_paths(keyed, sb)
    for stroke in sb.trajectories:
        if stroke.joint != "pelvis":
            continue
        h, span = sb.agent_index(stroke.agent), slice(stroke.start, stroke.end + 1)
        err = lambda j: point_polyline_distance(sb.camera.project(j[span, h, 0]), stroke.points).mean()
        assert err(moved) < 0.035 < 0.07 < err(joints)
    for h, frames in enumerate(key_frames(sb)):
        np.testing.assert_allclose(moved[frames, h], keyed[frames, h], atol=1e-9)


def test_a_pelvis_on_its_stroke_that_bows_in_depth_moves_a_share_of_the_way_back(scene):
    """The motion on its strokes in the sketch plane, but bowed 30 cm along the camera ray between
    the keys (a sketch cannot see it; another view can): a quarter of the way to the lifted
    stroke's depth (PathConfig.depth_share), the sketch plane unchanged."""
    clip, sb = scene
    joints, offsets = consistent_skeleton(clip.joints.astype(float))
    back = sb.camera.basis()[2]
    keyed = warp_to_keyposes(joints, offsets, sb)
    h, frames = 0, key_frames(sb)[0]
    bow = np.zeros(len(keyed))
    a, b = frames[1], frames[2]
    bow[a:b + 1] = 0.3 * np.sin(np.linspace(0.0, np.pi, b - a + 1))
    bowed = keyed.copy()
    bowed[:, h] += bow[:, None, None] * back
    depth = lambda j: (j[:, h, 0] - keyed[:, h, 0]) @ back
    plain = follow_paths(keyed, sb)
    moved = follow_paths(bowed, sb)
    left = (depth(moved) - depth(plain))[(a + b) // 2] / 0.3
    assert 1.0 - PathConfig().depth_share - 0.1 < left < 1.0 - PathConfig().depth_share + 0.1
    np.testing.assert_allclose(sb.camera.project(moved[:, h, 0]), sb.camera.project(plain[:, h, 0]), atol=0.03)


def test_a_stroke_keyed_only_at_its_start_is_walked_to_its_end(scene):
    """The people stand still in the generated motion; their pelvis strokes (keys only at the
    first frame) still take them from the strokes' first points to their last, going on evenly."""
    clip, sb = scene
    sb = replace(sb, keyposes=[k for k in sb.keyposes if k.frame == 0])
    joints, offsets = consistent_skeleton(np.repeat(clip.joints[:1], len(clip.joints), axis=0))
    moved = follow_paths(warp_to_keyposes(joints, offsets, sb), sb)
    strokes = [t for t in sb.trajectories if t.joint == "pelvis"]
    assert strokes
    for stroke in strokes:
        h = sb.agent_index(stroke.agent)
        pelvis = sb.camera.project(moved[stroke.start:stroke.end + 1, h, 0])
        assert np.linalg.norm(pelvis[-1] - stroke.points[-1]) < 0.04
        steps = ground_steps(moved[stroke.start:stroke.end + 1, h, 0])
        assert 0.25 < steps[:len(steps) // 2].sum() / steps.sum() < 0.75      # on the way all along


def ground_steps(pelvis: np.ndarray) -> np.ndarray:
    """How far (M-1,) a pelvis path (M, 3) goes over the ground from frame to frame."""
    return np.linalg.norm(np.diff(pelvis[:, [0, 2]], axis=0), axis=-1)


def test_a_stroke_ending_early_or_keyed_midway_is_walked_evenly_and_stays_at_its_end(scene):
    """A person standing still in the generated motion, keyed at frames 0 and 40, with a pelvis
    stroke over frames 0-80 of 120: walked to the stroke's end by frame 80, evenly from the key at
    40 (no slide before the key, no rush after it), and standing there after frame 80."""
    clip, sb = scene
    stroke = next(t for t in sb.trajectories if t.joint == "pelvis")
    h = sb.agent_index(stroke.agent)
    stroke = replace(stroke, start=0, end=80)
    keys = [k for k in sb.keyposes if k.agent == stroke.agent and k.frame == 0]
    keys.append(replace(keys[0], frame=40))
    sb = replace(sb, keyposes=keys, trajectories=[stroke])
    joints, offsets = consistent_skeleton(np.repeat(clip.joints[:1], len(clip.joints), axis=0))
    keyed = warp_to_keyposes(joints, offsets, sb)
    moved = follow_paths(keyed, sb)
    pelvis = sb.camera.project(moved[:, h, 0])
    assert np.linalg.norm(pelvis[80] - stroke.points[-1]) < 0.04
    assert np.abs(pelvis[80:] - pelvis[80]).max() < 0.02                      # it stays there
    step = ground_steps(moved[40:81, h, 0])
    # evenly after the key: no rush, and no standing but where the stroke turns back on itself (twice)
    assert step.max() < 1.5 * np.median(step) and np.sum(step < 0.3 * np.median(step)) <= 2
    np.testing.assert_allclose(moved[40, h], keyed[40, h], atol=1e-9)


def test_matched_walks_a_looping_path_in_order_where_the_nearest_point_jumps_across():
    """A dancer's figure-of-eight: at the crossing the nearest point of the path is as often on the
    other branch; the match goes on along the branch the motion is on."""
    s = np.linspace(0, 2 * np.pi, 200)
    path = np.stack([np.sin(s), np.sin(2 * s) / 2], -1)                    # crosses itself at the origin
    t = np.linspace(0, 2 * np.pi, 60)
    points = np.stack([np.sin(t), np.sin(2 * t) / 2], -1) + 0.01
    index = matched(points, path, most_step=10)
    assert np.all(np.diff(index) >= 0) and index[0] == 0 and index[-1] == len(path) - 1
    assert np.abs(s[index] - t).max() < 0.1


def test_timed_way_keeps_a_pause_of_the_motion_and_walks_evenly_where_it_rushes():
    config = PathConfig()
    paused = np.concatenate([np.linspace(0, 1, 20), np.full(20, 1.0), np.linspace(1, 2, 21)[1:]])  # 1.0 m/s
    way = timed_way(paused, 2.0, [], np.zeros(60, bool), 20.0, config)
    np.testing.assert_allclose(way, paused, atol=1e-9)                     # the pause stays
    rushed = np.concatenate([np.zeros(50), np.linspace(0, 2, 11)])         # stands, then 4 m/s
    way = timed_way(rushed, 2.0, [], np.zeros(61, bool), 20.0, config)
    np.testing.assert_allclose(way, np.linspace(0, 2, 61), atol=1e-9)      # evenly instead
    keyed = timed_way(rushed, 2.0, [30], np.zeros(61, bool), 20.0, config)
    assert keyed[30] == 0.0 and keyed[-1] == 2.0                            # through the key's place
    brisk = np.concatenate([np.zeros(47), np.arange(1, 15) * 0.15])        # stands, then 3 m/s
    assert np.abs(timed_way(brisk, brisk[-1], [], np.zeros(61, bool), 20.0, config) - brisk).max() > 0.3
    held = timed_way(brisk, brisk[-1], [], np.arange(61) > 55, 20.0, config)          # holding a box: its pace
    np.testing.assert_allclose(held, brisk, atol=1e-9)


def test_a_stroke_drawn_as_a_single_point_keeps_the_person_there(scene):
    """A click on the canvas, not a drag: every point of the stroke is one; the person stays
    over it, and nothing breaks."""
    clip, sb = scene
    stroke = next(t for t in sb.trajectories if t.joint == "pelvis")
    dot = replace(stroke, points=np.repeat(stroke.points[:1], 5, axis=0))
    sb = replace(sb, trajectories=[dot], keyposes=[])
    joints, _ = consistent_skeleton(clip.joints.astype(float))
    moved = follow_paths(joints, sb)
    h = sb.agent_index(dot.agent)
    assert np.isfinite(moved).all()
    assert np.linalg.norm(sb.camera.project(moved[dot.start:dot.end + 1, h, 0]) - dot.points[0], axis=-1).max() < 0.06


@pytest.mark.parametrize("seed", range(6))
def test_any_stroke_an_artist_can_draw_is_walked_without_breaking(scene, seed):
    """Strokes as the canvas makes them: a few points or many, over part of the clip or all of
    it, on the floor plan or in the sketch plane, keyed inside, outside or not at all, drawn
    back and forth over themselves: the motion stays finite, on its stroke's span ends and off
    nothing else."""
    clip, sb = scene
    rng = np.random.default_rng(seed)
    n = len(clip.joints)
    start = int(rng.integers(0, n - 2))
    end = int(rng.integers(start + 1, n))
    count = int(rng.integers(2, 30))
    floor = np.cumsum(rng.normal(0, 0.3, (count, 2)), axis=0) + clip.joints[start, 0, 0, [0, 2]]
    stroke = Trajectory("A", "pelvis", start, end, floor_path_points(sb.camera, floor),
                        floor if seed % 2 else None)
    keys = [k for k in sb.keyposes if k.agent == "A"][: seed % 4]
    sb = replace(sb, trajectories=[stroke], keyposes=keys + [k for k in sb.keyposes if k.agent != "A"])
    joints, _ = consistent_skeleton(clip.joints.astype(float))
    moved = follow_paths(joints, sb)
    assert np.isfinite(moved).all()
    np.testing.assert_allclose(moved[:, 1], joints[:, 1])                     # B has no stroke
    np.testing.assert_allclose(moved[:, 0] - moved[:, 0, :1], joints[:, 0] - joints[:, 0, :1], atol=1e-9)  # A moves whole

"""Paths drawn on the floor plan: kept in the file, seen from the camera, walked exactly."""
from dataclasses import replace

import numpy as np
import pytest

from engine.generate import generate
from engine.geometry.polylines import closest_on_polyline
from engine.sampling.config import sampler_config
from engine.skeleton import FEET
from engine.storyboard import Storyboard, StoryboardError, floor_path_points

EXAMPLE = "resources/examples/box_handoff.json"


def with_floor_path(sb: Storyboard, agent: str) -> tuple[Storyboard, int]:
    """The agent's pelvis path replaced by a floor path straight from where one keypose stands to
    where the next does. -> (storyboard, index of the path)."""
    keys = sorted((k for k in sb.keyposes if k.agent == agent), key=lambda k: k.frame)
    stands = [sb.camera.unproject_to_height(k.points[list(FEET)], 0.0).mean(0)[[0, 2]] for k in keys]
    floor = np.concatenate([np.linspace(a, b, 8, endpoint=False) for a, b in zip(stands[:-1], stands[1:])] + [stands[-1:]])
    i = next(i for i, t in enumerate(sb.trajectories) if t.agent == agent and t.joint == "pelvis")
    paths = list(sb.trajectories)
    paths[i] = replace(paths[i], points=floor_path_points(sb.camera, floor), floor=floor)
    return replace(sb, trajectories=paths), i


def test_a_floor_path_is_saved_and_checked():
    sb, i = with_floor_path(Storyboard.load(EXAMPLE), "A")
    again = Storyboard.from_json(sb.to_json())
    assert np.array_equal(again.trajectories[i].floor, sb.trajectories[i].floor)
    assert "floor" not in Storyboard.load(EXAMPLE).to_dict()["trajectories"][0]
    bad = replace(sb.trajectories[i], floor=sb.trajectories[i].floor[:3])
    with pytest.raises(StoryboardError, match=r"trajectories\[\d\]\.floor: "):
        replace(sb, trajectories=[bad]).validate()


def test_people_walk_on_the_floor_path():
    """Away from the keys (which place the figure themselves), the pelvis is over the floor path;
    the same path sketched in the camera view leaves depth to the warp's guess."""
    sb, i = with_floor_path(Storyboard.load(EXAMPLE), "A")
    sketched = replace(sb, trajectories=[replace(t, floor=None) for t in sb.trajectories])
    path = sb.trajectories[i]
    keys = [k.frame for k in sb.keyposes if k.agent == "A"]
    frames = [f for f in range(path.start, path.end + 1) if min(abs(f - k) for k in keys) > 12]
    config = sampler_config(steps=6, seed=2)

    def off_path(storyboard):
        pelvis = generate(storyboard, config, quiet=True).clips[0].joints[frames, 0, 0][:, [0, 2]]
        return np.linalg.norm(closest_on_polyline(pelvis, path.floor) - pelvis, axis=-1).max()

    drawn, guessed = off_path(sb), off_path(sketched)
    assert drawn < 0.1 and drawn < 0.6 * guessed, (drawn, guessed)

"""The shipped bundle on the bundled example storyboards, end to end: what an artist opening the
app sees first meets the sampler issue's targets (feet planted, on the keyposes, hands on the
object, nothing inside anything)."""
from pathlib import Path

import numpy as np
import pytest
import torch

from engine.generate import generate
from engine.metrics import adherence
from engine.models.bundle import load_default
from engine.sampling.config import SamplerConfig, sampler_config
from engine.skeleton import FEET
from engine.storyboard import Storyboard

EXAMPLES = sorted(Path("resources/examples").glob("*.json"))


@pytest.fixture(scope="module")
def bundle():
    torch.set_num_threads(2)
    loaded = load_default()
    if not loaded.trained:
        pytest.skip("no trained bundle in resources/models")
    return loaded


@pytest.mark.parametrize("path", EXAMPLES, ids=lambda p: p.stem)
def test_bundled_example_meets_the_targets(bundle, path):
    sb = Storyboard.load(path)
    clip = generate(sb, SamplerConfig(), bundle).clips[0]
    assert np.isfinite(clip.joints).all()
    figures = adherence(clip, sb)
    assert figures["FootSkate"] < 0.08
    assert figures["K2D"] < 0.06 and figures["T2D"] < 0.08
    assert figures["Pen"] < 0.02
    assert figures.get("Anc", 0.0) < 0.05


@pytest.mark.parametrize("path", EXAMPLES, ids=lambda p: p.stem)
def test_the_preview_of_a_bundled_example_is_finished_like_the_full_motion(bundle, path):
    """What follows the pointer while an artist drags: feet planted, hands on the object (with
    keyposes and paths alone, feet skated in 70% of the frames and boxes floated 1.2 m off)."""
    sb = Storyboard.load(path)
    figures = adherence(generate(sb, sampler_config(preview=True), bundle).clips[0], sb)
    assert figures["FootSkate"] < 0.08 and figures.get("Anc", 0.0) < 0.05
    assert figures["K2D"] < 0.06 and figures["T2D"] < 0.08


def test_a_walk_sketched_at_30_fps_steps_as_often_as_at_20(bundle):
    """The model learnt motion at 20 fps; a 30 fps storyboard of the same scene must not come out
    as the 20 fps motion squeezed into fewer seconds (before: 1.4x the step rate). Six seeds: the
    count of one is chaotic (whether the feet walk a stretch or step it each on its own turns on
    one-frame overlaps): seeds 0-1 gave 1.23 on one CPU and under 1.2 on another, seeds 0-5 1.15."""
    sb = Storyboard.load("resources/examples/carry_table.json")

    def steps_per_second(storyboard):
        rates = []
        for seed in range(6):
            clip = generate(storyboard, SamplerConfig(seed=seed), bundle).clips[0]
            height = clip.joints[:, :, list(FEET), 1]
            lifts = ((height[1:] > 0.07) & (height[:-1] <= 0.07)).sum()
            rates.append(lifts / clip.duration / clip.num_humans)
        return np.mean(rates)

    assert steps_per_second(sb.retimed(30.0)) / steps_per_second(sb) == pytest.approx(1.0, abs=0.2)

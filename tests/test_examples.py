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
from engine.sampling.sampler import SamplerConfig
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

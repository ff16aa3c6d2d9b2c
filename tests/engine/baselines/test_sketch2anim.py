"""Sketch2Anim-INT as a method: the sampler's streaming contract, the storyboard's shape, our finishing."""
from dataclasses import replace

import numpy as np
import torch

from engine.baselines.sketch2anim import sample_sketch2anim
from engine.demo import EXAMPLES
from engine.models.bundle import build_parts, untrained_bundle
from engine.request import Request
from engine.sampling.config import SamplerConfig
from engine.storyboard import Storyboard
from tests.engine.training.test_training import TINY_MODEL

torch.set_num_threads(1)


def test_streams_every_ddim_step_then_finished_clips_of_the_storyboards_people():
    bundle = untrained_bundle(TINY_MODEL)
    baseline = build_parts(TINY_MODEL, ("sketch2anim",))
    torch.nn.init.normal_(baseline["sketch2anim"].denoiser.backbone.main.output.weight, 0, 0.5)   # not the zero motion
    bundle = replace(bundle, parts={**bundle.parts, **baseline})
    storyboard = Storyboard.load(EXAMPLES / "box_handoff.json")
    gen = sample_sketch2anim(bundle, Request.build(storyboard, SamplerConfig(steps=3, variations=2)))
    events = []
    try:
        while True:
            events.append(next(gen))
    except StopIteration as stop:
        result = stop.value
    assert [e.step for e in events] == [0, 1, 2] and events[-1].t == 0.0
    assert events[0].preview.joints.shape[1] == len(storyboard.agents)
    assert len(result.clips) == 2 and result.network_evals == 3
    clip = result.clips[0]
    assert clip.joints.shape[:2] == (storyboard.length, len(storyboard.agents))
    assert np.isfinite(clip.joints).all()

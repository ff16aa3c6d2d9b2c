"""One generation asked for: the storyboard read once, with how to generate it.

    request = Request.build(storyboard, config)   # the command line, the app, the benchmark, the demo
    view = request.for_model(stride)               # the sampler: the model's rate, padded, its controls

The storyboard stays as drawn (its frames, its frame rate; only shared or crossed grips are
mended, engine.grips, and a figure posed from a template facing the other way keeps only its
hands, feet and head, engine.mirrored): finishing and the output use it. The networks animate
at MODEL_FPS in fixed slots (engine.models.slots); `for_model` retimes the storyboard to that
rate, pads it to the decoder's frame stride and builds its controls once, for the network's
conditioning and the guidance energies alike.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import cached_property

import numpy as np

from .controls import Controls, build_controls
from .grips import with_grips_fitted
from .mirrored import without_mirrored_template
from .models.slots import MODEL_FPS, NUM_HUMANS, NUM_OBJECTS, fixed_controls
from .sampling.config import SamplerConfig, SamplerError
from .storyboard import Storyboard
from .text import tokenize


@dataclass(frozen=True)
class ModelView:
    """The request as the networks see it."""
    storyboard: Storyboard          # retimed to MODEL_FPS and padded (the tail is unconstrained)
    frames: int                     # frames of motion at MODEL_FPS; the rest is padding
    controls: Controls              # of `storyboard` (N padded frames)
    fixed: dict[str, np.ndarray]    # `controls` in the model's slots (fixed_controls) and the text's tokens

    @property
    def length(self) -> int:
        """Padded frames N, a multiple of the decoder's stride."""
        return self.storyboard.length


@dataclass(frozen=True, eq=False)
class Request:
    storyboard: Storyboard
    config: SamplerConfig = field(default_factory=SamplerConfig)

    @classmethod
    def build(cls, storyboard: Storyboard, config: SamplerConfig | None = None) -> "Request":
        """Check that the storyboard and settings can be generated (SamplerError otherwise)."""
        config = config or SamplerConfig()
        config.check()
        if not storyboard.agents:
            raise SamplerError("nothing to animate: the storyboard has no people")
        if len(storyboard.agents) > NUM_HUMANS or len(storyboard.objects) > NUM_OBJECTS:
            raise SamplerError(f"the model animates at most {NUM_HUMANS} people and {NUM_OBJECTS} object; the "
                               f"storyboard has {len(storyboard.agents)} people and {len(storyboard.objects)} objects")
        return cls(without_mirrored_template(with_grips_fitted(storyboard)), config)

    @property
    def method(self) -> str:
        return self.config.method

    def for_model(self, stride: int) -> ModelView:
        """The storyboard at MODEL_FPS, padded to a multiple of `stride` frames, with its controls
        (built once per stride)."""
        if stride not in self._views:
            model_sb = self.storyboard.retimed(MODEL_FPS)
            frames = model_sb.length
            padded = -(-frames // stride) * stride
            if padded != frames:
                model_sb = replace(model_sb, length=padded)
            controls = build_controls(model_sb)
            fixed = {**fixed_controls(controls), **tokenize(self.storyboard.text)}
            self._views[stride] = ModelView(model_sb, frames, controls, fixed)
        return self._views[stride]

    @cached_property
    def _views(self) -> dict[int, ModelView]:
        return {}

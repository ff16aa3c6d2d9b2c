"""engine.controls: an object path read as its base's, whether traced so or through the object."""
from dataclasses import replace

import numpy as np
import pytest

from engine.controls import base_path, build_controls
from engine.sketchify import sketchify
from engine.synth import synthesize


@pytest.mark.parametrize("noise", [0.0, 0.25])
def test_an_object_path_through_the_middle_of_its_outlines_is_read_as_its_base(noise):
    """sketchify traces the base: read as it is. Drawn through the object's middle, as an artist
    draws it in the app (and at a wrist's wobble), it is read as the base's all the same."""
    clip = synthesize("carry_together", 3, fps=20)
    sb = sketchify(clip, 4, noise, 3)
    path = sb.object_paths[0]
    np.testing.assert_array_equal(base_path(sb, path), path.points)
    half = sb.camera.project(np.array([0.0, sb.objects[0].spec.size[1] / 2, 0.0])) - sb.camera.project(np.zeros(3))
    through_the_middle = replace(sb, object_paths=[replace(path, points=path.points + half)])
    np.testing.assert_allclose(base_path(through_the_middle, through_the_middle.object_paths[0]), path.points)
    np.testing.assert_allclose(build_controls(through_the_middle).objpath2d, build_controls(sb).objpath2d)
    unoutlined = replace(through_the_middle, object_keys=[])   # nothing says otherwise: the base's
    np.testing.assert_array_equal(base_path(unoutlined, unoutlined.object_paths[0]), path.points + half)

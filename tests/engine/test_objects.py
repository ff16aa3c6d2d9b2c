"""Objects: a drawn object is as large as it is drawn."""
import numpy as np
import pytest

from engine.camera import StoryboardCamera
from engine.objects import DEFAULT_SIZES, SIZE_RANGE, drawn_size, resized_outline


def silhouette(size, camera) -> np.ndarray:
    """The four corners (4, 2) of an upright box's silhouette's bounding rectangle."""
    w, h, d = size
    corners = np.array([[sx * w / 2, y, sz * d / 2] for sx in (-1, 1) for y in (0.0, h) for sz in (-1, 1)])
    uv = camera.project(corners + (0.7, 0.0, -0.3))
    lo, hi = uv.min(0), uv.max(0)
    return np.array([lo, [hi[0], lo[1]], hi, [lo[0], hi[1]]])


@pytest.mark.parametrize("kind", list(DEFAULT_SIZES))
def test_a_drawn_object_is_as_large_as_its_drawing(kind):
    camera = StoryboardCamera()
    default = DEFAULT_SIZES[kind]
    assert drawn_size(kind, silhouette(default, camera), camera) == pytest.approx(default)
    wide = (2 * default[0], default[1], 2 * default[2])               # drawn twice as wide
    assert drawn_size(kind, silhouette(wide, camera), camera)[0] == pytest.approx(wide[0], rel=0.1)
    tiny = drawn_size(kind, silhouette(default, camera) * 0.001, camera)   # a click, not a drag
    assert min(tiny) >= SIZE_RANGE[0] - 1e-9


def test_a_resized_object_is_redrawn_at_its_new_size_on_the_same_floor():
    camera = StoryboardCamera()
    old, new = DEFAULT_SIZES["box"], (0.4, 0.4, 0.4)
    drawn = silhouette(old, camera)
    resized = resized_outline(drawn, old, new, camera)
    np.testing.assert_allclose(np.ptp(resized, axis=0), np.ptp(silhouette(new, camera), axis=0))   # as large as drawn so
    assert resized[:, 1].min() == pytest.approx(drawn[:, 1].min())                                # its bottom stays
    assert resized[:, 0].mean() == pytest.approx(drawn[:, 0].mean())
    np.testing.assert_allclose(resized_outline(resized, new, old, camera), drawn)                 # and back

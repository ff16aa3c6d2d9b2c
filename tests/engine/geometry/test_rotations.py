import numpy as np
import pytest

from engine.geometry.rotations import _kabsch_svd, axis_angle_to_matrix, cross, kabsch, norm
from engine.skeleton import CHILDREN, REST_OFFSETS


def test_cross_is_numpys():
    a, b = np.random.default_rng(0).normal(size=(2, 5, 7, 3))
    np.testing.assert_allclose(cross(a, b), np.cross(a, b), atol=1e-15)


def test_norm_is_numpys_to_the_bit():
    rng = np.random.default_rng(0)
    for shape in [(3,), (120, 2), (98, 21, 3)]:
        v = rng.normal(size=shape)
        assert np.array_equal(norm(v), np.linalg.norm(v, axis=-1))
        assert np.array_equal(norm(v, keepdims=True), np.linalg.norm(v, axis=-1, keepdims=True))


@pytest.mark.parametrize("joint", [0, 9])   # the pelvis's and spine3's children: nearly in one plane
def test_kabsch_is_the_svd_fit(joint):
    rng = np.random.default_rng(1)
    src = np.broadcast_to(REST_OFFSETS[list(CHILDREN[joint])], (500, 3, 3))
    turn = axis_angle_to_matrix(rng.normal(size=(500, 3)) * 2)
    dst = src @ np.swapaxes(turn, -1, -2) + rng.normal(scale=0.02, size=(500, 3, 3))
    fit = kabsch(src, dst)
    np.testing.assert_allclose(fit, _kabsch_svd(src, dst), atol=1e-9)
    np.testing.assert_allclose(kabsch(src, src @ np.swapaxes(turn, -1, -2)), turn, atol=1e-9)


def test_kabsch_gives_a_rotation_where_a_mirror_fits_best():
    src = np.eye(3)[None]
    mirrored = src * [1, 1, -1]
    fit = kabsch(src, mirrored)
    assert np.isclose(np.linalg.det(fit[0]), 1.0)
    np.testing.assert_allclose(fit[0] @ fit[0].T, np.eye(3), atol=1e-12)


def test_kabsch_of_a_degenerate_fit_is_still_a_rotation():
    src = np.array([[[1.0, 0, 0], [0, 1, 0], [0, 0, 1]]])
    dst = np.array([[[1.0, 0, 0], [0, 1, 0], [0, 0, 0]]])     # one target collapsed: M is singular
    fit = kabsch(src, dst)
    np.testing.assert_allclose(fit[0], np.eye(3), atol=1e-9)

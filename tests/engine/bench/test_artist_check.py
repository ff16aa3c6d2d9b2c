"""The artist-style check (engine.bench.artist_check): a put-down is told from a drop."""
import numpy as np

from engine.bench.artist_check import release_drops
from engine.clip import MotionClip
from engine.objects import ObjectSpec
from engine.storyboard import Agent, Contact, SceneObject, Storyboard

N = 30


def carried(heights: np.ndarray) -> tuple[MotionClip, Storyboard]:
    """A box at heights (N,) held by one hand over frames 5-14 and 20-24."""
    sb = Storyboard(length=N, agents=[Agent("A")], objects=[SceneObject("box", ObjectSpec("box"))],
                    contacts=[Contact("A", "left", 5, 14, "box", 0), Contact("A", "left", 20, 24, "box", 0)])
    pose = np.zeros((N, 1, 7))
    pose[:, 0, 1], pose[:, 0, 3] = heights, 1.0
    return MotionClip(fps=20.0, joints=np.zeros((N, 1, 22, 3)), rot6d=np.zeros((N, 1, 22, 6)), obj_pose=pose), sb


def test_a_box_let_go_of_in_the_air_drops_and_one_set_down_does_not():
    dropped = np.zeros(N)
    dropped[5:15] = 0.4                          # let go 40 cm up at frame 14
    dropped[20:25] = 0.3                         # and 30 cm up at frame 24
    clip, sb = carried(dropped)
    np.testing.assert_allclose(release_drops(clip, sb), [0.4, 0.3])
    set_down = dropped.copy()
    set_down[14] = set_down[24] = 0.0           # lowered onto the floor as the hand lets go
    np.testing.assert_allclose(release_drops(*carried(set_down)), [0.0, 0.0])


def test_a_hold_to_the_end_is_no_release():
    heights = np.zeros(N)
    heights[5:] = 0.5
    clip, sb = carried(heights)
    sb.contacts = [Contact("A", "left", 5, N - 1, "box", 0)]
    assert release_drops(clip, sb) == []

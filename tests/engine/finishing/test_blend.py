"""Finishing, blend: corrections and jumps eased over time without a jolt."""
import numpy as np

from engine.finishing.blend import ease_frames, ease_jumps, eased_push, spike


def test_an_eased_jump_continues_the_motion_then_reaches_its_own():
    frames = np.arange(40, dtype=float)
    values = np.where(frames < 20, 0.01 * frames, 0.01 * frames + 0.5)[:, None]   # a 50 cm jump at 20
    length = ease_frames(0.5, 0.02, 3, 30)
    eased = ease_jumps(values, [20], lambda jump: ease_frames(jump, 0.02, 3, 30))
    assert np.array_equal(eased[:20], values[:20])                     # before the jump: as it was
    assert np.array_equal(eased[20 + length + 1:], values[20 + length + 1:])   # after the ease: its own
    assert abs(eased[20, 0] - 0.20) < 1e-12                            # it goes on at its pace
    assert spike(eased).max() <= 0.02 + 1e-9 and spike(values).max() > 0.2


def test_ease_frames_grow_with_the_way_within_their_bounds():
    assert ease_frames(0.0, 0.02, 4, 16) == 4 and ease_frames(10.0, 0.02, 4, 16) == 16
    assert ease_frames(0.1, 0.02, 1, 16) < ease_frames(0.4, 0.02, 1, 16)


def test_a_push_eases_as_an_envelope_never_shorter_than_asked():
    """A push out of something asked at a frame or two (and a longer one the other way): as long
    as asked there, eased in and out over the frames around, nothing far from it."""
    push = np.zeros((40, 3))
    push[10] = (0.0, 0.08, 0.0)
    push[25:28] = (0.05, 0.0, 0.0)
    eased = eased_push(push, 1.5)
    length = np.linalg.norm(eased, axis=-1)
    assert np.all(length >= np.linalg.norm(push, axis=-1) - 1e-12)
    assert length[8] > 0.04 and length[12] > 0.04                      # eased in and out around
    assert np.all(length[:4] < 1e-3) and np.all(length[17:19] < 1e-3)   # nothing far from it
    assert eased[10, 1] > 0.0 and eased[26, 0] > 0.0 and abs(eased[26, 1]) < 1e-9

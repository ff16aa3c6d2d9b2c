"""Per-key timing: holds keyed through by the generator, eases as retimed motion, kept in files."""
from dataclasses import replace

import numpy as np
import pytest

from engine.finishing.timing import hermite_time, retime_to_keys, source_times
from engine.generate import generate
from engine.sampling.config import sampler_config
from engine.storyboard import Keypose, Storyboard, StoryboardError

EXAMPLE = "resources/examples/box_handoff.json"


def first_key(sb: Storyboard, agent: str, after: int = -1) -> int:
    """Index in sb.keyposes of the agent's earliest key after frame `after`."""
    return min((i for i, k in enumerate(sb.keyposes) if k.agent == agent and k.frame > after),
               key=lambda i: sb.keyposes[i].frame)


def timed(sb: Storyboard, index: int, **timing) -> Storyboard:
    keys = list(sb.keyposes)
    keys[index] = replace(keys[index], **timing)
    return replace(sb, keyposes=keys)


def test_timing_is_saved_only_where_set_and_checked():
    sb = Storyboard.load(EXAMPLE)
    assert all("hold" not in k and "ease_in" not in k for k in sb.to_dict()["keyposes"])
    i = first_key(sb, "A")
    sb = timed(sb, i, hold=10, ease_in=True, ease_out=True)
    key = Storyboard.from_json(sb.to_json()).keyposes[i]
    assert (key.hold, key.ease_in, key.ease_out) == (10, True, True)
    assert sb.retimed(2 * sb.fps).keyposes[i].hold == 20
    too_long = timed(sb, i, hold=sb.length)
    with pytest.raises(StoryboardError, match=r"keyposes\[\d\]\.hold: .*runs past the clip's last frame"):
        too_long.validate()
    assert too_long.cut_to(sb.length).keyposes[i].hold == sb.length - 1 - key.frame


def test_a_hold_stands_still_then_plays_the_motion_to_the_next_key():
    keys = [Keypose("A", f, np.zeros((22, 2)), np.ones(22, bool)) for f in (10, 40, 70)]
    keys[0].hold, keys[1].hold = 10, 100                        # the second is cut before the third
    s = source_times(keys, 100)
    assert np.allclose(s[:11], np.arange(11)) and np.all(s[10:21] == 10)     # held 10..20
    assert np.allclose(s[20:41], np.linspace(10, 40, 21))                         # 30 frames in 20
    assert np.all(s[40:70] == 40) and s[70] == 70 and np.all(np.diff(s) >= 0)
    assert source_times([Keypose("A", 10, np.zeros((22, 2)), np.ones(22, bool))], 100) is None


def test_easing_slows_into_the_key_and_keeps_the_keys():
    assert np.allclose(hermite_time(np.linspace(0, 1, 9), 1.0, 1.0), np.linspace(0, 1, 9))
    sb = Storyboard.load(EXAMPLE)
    a_keys = sorted(k.frame for k in sb.keyposes if k.agent == "A")
    key = a_keys[1]
    sb = timed(sb, first_key(sb, "A", after=a_keys[0]), ease_in=True)
    n = sb.length
    joints = np.zeros((n, 2, 22, 3))
    joints[..., 0] = np.arange(n)[:, None, None] * 0.05          # everyone walks at 1 m/s
    eased = retime_to_keys(joints, sb)
    assert np.array_equal(eased[:, 1], joints[:, 1])                # B has no eased key
    assert np.array_equal(eased[a_keys, 0], joints[a_keys, 0])      # keys stay
    speed = np.abs(np.diff(eased[:, 0, 0, 0]))
    assert speed[key - 1] < 0.2 * speed[a_keys[0]] and np.all(speed > -1e-12)
    assert np.allclose(eased[key + 1:, 0], joints[key + 1:, 0])     # the next span is not eased
    assert abs(speed[a_keys[0]] - 0.05) < 0.01                     # speed continuous where it starts


def test_a_generated_hold_stands_still():
    sb = Storyboard.load(EXAMPLE)
    i = first_key(sb, "B")
    key = sb.keyposes[i]
    config = sampler_config(steps=6, seed=1)
    h = [a.id for a in sb.agents].index("B")
    plain = generate(sb, config, quiet=True).clips[0].joints[:, h]
    hold = (sb.keyposes[first_key(sb, "B", after=key.frame)].frame - key.frame) // 3
    held = generate(timed(sb, i, hold=hold), config, quiet=True).clips[0].joints[:, h]
    span = slice(key.frame, key.frame + hold + 1)

    def drift(joints):
        return np.linalg.norm(joints[span] - joints[key.frame], axis=-1).max()

    def fastest(joints):          # the largest joint step in a frame
        return np.linalg.norm(np.diff(joints, axis=0), axis=-1).max()

    assert drift(held) < 0.04 and drift(plain) > 0.1, (drift(held), drift(plain))
    # The motion to the next key plays 1.5 times as fast after the hold: no faster than that.
    assert fastest(held) < 1.6 * fastest(plain), (fastest(held), fastest(plain))

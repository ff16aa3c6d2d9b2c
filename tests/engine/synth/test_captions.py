"""Captions written from the motion: the scenario's words, who does what, paraphrased."""
import numpy as np

from engine.synth import synthesize
from engine.synth.captions import caption
from engine.text import VOCABULARY, words


def _captions(scenario, seed, count=12):
    clip = synthesize(scenario, seed)
    rng = np.random.default_rng(0)
    return clip, [caption(clip, rng) for _ in range(count)]


def test_each_scenario_is_described_with_its_own_words_in_several_ways():
    expect = {"handshake": {"shake", "meet"}, "handoff": {"hands", "gives", "takes", "pass"},
              "let_go": {"lets"}, "lift_adjust": {"higher", "up", "lower", "down"},
              "carry_together": {"together", "ends"}}
    for scenario, some in expect.items():
        clip, texts = _captions(scenario, 1)
        assert len(set(texts)) >= 3, scenario                            # paraphrased
        for text in texts:
            assert set(words(text)) & some, (scenario, text)
            assert set(words(text)) <= set(VOCABULARY), text              # every word has its own id
            assert "  " not in text and " ," not in text


def test_roles_follow_the_motion():
    clip, texts = _captions("handoff", 2, 40)
    held = clip.contact.any(-1)
    giver = int(np.argmin([np.flatnonzero(held[:, h]).min() for h in range(2)]))
    names = (("first", "one"), ("second", "two"))
    for text in texts:
        if " gives it to " in text:
            assert any(w in text.split(" gives it to ")[0].split()[-2:] for w in names[giver]), text


def test_real_capture_gets_a_caption():
    clip = synthesize("handshake", 3)
    clip = type(clip)(**{**clip.__dict__, "scenario": "bvh:60_01+61_01", "obj_pose": None, "obj_anchors": None,
                         "obj_type": None, "obj_size": None, "contact": None, "phase": None})
    assert "dance" in " ".join(caption(clip, np.random.default_rng(k)) for k in range(5))

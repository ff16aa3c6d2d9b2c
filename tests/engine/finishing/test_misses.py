"""Holds finishing could not make exact, told to the artist (engine/finishing/misses.py)."""
from dataclasses import replace

import numpy as np

from engine.finishing.misses import missed_holds
from engine.skeleton import HANDS
from engine.sketchify import sketchify
from engine.synth import synthesize


def test_a_hand_off_its_grip_is_one_note_with_who_how_far_and_when():
    clip = synthesize("carry_together", 3, fps=20)
    sb = sketchify(clip, 4, 0.0, 3)
    assert missed_holds(clip, sb) == []                       # the synthesized carry holds its grips
    hold = next(c for c in sb.contacts if c.object is not None)
    h = sb.agent_index(hold.agent)
    joints = clip.joints.copy()
    frames = np.arange(hold.start + 5, hold.start + 11)
    joints[frames, h, HANDS[("left", "right").index(hold.hand)]] += (0.0, 0.2, 0.0)
    notes = missed_holds(replace(clip, joints=joints), sb)
    assert len(notes) == 1
    assert notes[0].startswith(f"{hold.agent}'s {hold.hand} hand misses the {hold.object}'s grip by up to 20 cm")
    assert f"(frames {frames[0]}-{frames[-1]})" in notes[0]
    worse = next(c for c in sb.contacts if c.object is not None and c is not hold)     # a later hold, further off
    joints[worse.start + 2, sb.agent_index(worse.agent), HANDS[("left", "right").index(worse.hand)]] += (0.0, 0.4, 0.0)
    notes = missed_holds(replace(clip, joints=joints), sb)
    assert len(notes) == 2 and "by up to 40 cm" in notes[0] and "by up to 20 cm" in notes[1]   # the worst first

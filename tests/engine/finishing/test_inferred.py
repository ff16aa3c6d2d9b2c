"""Contacts the sketch leaves open are the generated motion's: a carry without drawn contacts
still carries the object."""
from dataclasses import replace

import numpy as np

from engine.finishing import finish
from engine.finishing.inferred import with_generated_contacts
from engine.sketchify import sketchify
from engine.synth import synthesize


def test_holds_are_read_off_the_motion_where_the_storyboard_draws_none():
    clip = synthesize("carry_together", 3)
    drawn = sketchify(clip, 4, 0.0, 3)
    assert drawn.contacts
    bare = replace(drawn, contacts=[])
    inferred = with_generated_contacts(clip, bare)
    assert len(inferred.contacts) >= 2 and {c.agent for c in inferred.contacts} == {a.id for a in drawn.agents}
    for c in inferred.contacts:                 # each matches a drawn span of that hand within a few frames
        same = [d for d in drawn.contacts if (d.agent, d.hand) == (c.agent, c.hand)]
        assert same and min(abs(d.start - c.start) + abs(d.end - c.end) for d in same) <= 12, c
    assert with_generated_contacts(clip, drawn) is drawn                       # drawn contacts are left alone
    # Finished without them, the object still travels with its carriers.
    moved = finish(clip, bare).obj_pose
    assert np.linalg.norm(moved[-1, 0, :3] - moved[0, 0, :3]) > 0.5


def test_a_passing_hand_is_not_a_hold():
    clip = synthesize("handshake", 4)
    sb = replace(sketchify(clip, 4, 0.0, 4), contacts=[])
    assert all(c.object is None for c in with_generated_contacts(clip, sb).contacts)   # the box on the floor: nobody

"""Grips two hands cannot share (engine/grips.py)."""
import pytest

from engine.artist_sketch import hand_drawn
from engine.grips import free_anchors, held_by_others, with_grips_fitted
from engine.request import Request
from engine.sketchify import sketchify
from engine.storyboard import Storyboard
from engine.synth import synthesize


def hand_off() -> Storyboard:
    """The bundled hand-off (A holds grips 2 and 0 until frame 48, B grips 1 and 3 from 44)."""
    return Storyboard.load("resources/examples/box_handoff.json")


def grips(sb: Storyboard) -> dict[tuple[str, str], int]:
    return {(c.agent, c.hand): c.anchor for c in sb.contacts}


def test_a_storyboard_whose_hands_hold_grips_of_their_own_is_read_as_drawn():
    sb = hand_off()
    assert grips(with_grips_fitted(sb)) == grips(sb) == {("A", "left"): 2, ("A", "right"): 0,
                                                       ("B", "left"): 1, ("B", "right"): 3}


def test_a_taker_drawn_on_the_givers_grips_takes_the_free_ones_at_the_same_ends_left_hand_left():
    sb = hand_off()
    for c in sb.contacts:                    # both people clicked the box's two ends
        if c.agent == "B":
            c.anchor = 2 if c.hand == "left" else 0
    b_left = next(c for c in sb.contacts if (c.agent, c.hand) == ("B", "left"))
    assert held_by_others(b_left, sb.contacts) == {0, 2}
    assert free_anchors(sb, b_left)[0] == 3             # grip 2's partner on the same (+x) end
    apart = with_grips_fitted(sb)                           # and uncrossed: the bundled example's
    assert grips(apart) == grips(hand_off())
    assert grips(sb)[("B", "left")] == 2                 # the storyboard itself is left as drawn
    assert grips(Request.build(sb).storyboard) == grips(apart)


def test_one_grip_held_at_different_times_is_not_shared():
    sb = hand_off()
    for c in sb.contacts:
        if c.agent == "B":
            c.start, c.anchor = 50, (2 if c.hand == "left" else 0)   # B takes the box after A let go
    assert grips(with_grips_fitted(sb)) == grips(sb)


def test_a_hand_with_no_free_grip_keeps_its_own():
    sb = hand_off()
    sb.objects[0].spec.anchors = sb.objects[0].spec.anchors[:2]      # a box with two grips
    for c in sb.contacts:
        c.anchor = 0 if c.hand == "left" else 1
    assert grips(with_grips_fitted(sb)) == grips(sb)


def test_a_person_holding_the_near_side_with_crossed_hands_swaps_them():
    """The giver's left hand on the near side's grip at their right (the app's artist clicked the
    box's left end for the left hand): no turn of the box fits both hands."""
    sb = hand_off()
    for c in sb.contacts:
        if c.agent == "A":
            c.anchor = 0 if c.hand == "left" else 2
    assert grips(with_grips_fitted(sb))[("A", "left")] == 2 and grips(with_grips_fitted(sb))[("A", "right")] == 0


def test_both_hands_on_one_end_hold_it_left_hand_left():
    sb = hand_off()
    for c in sb.contacts:
        if c.agent == "A":
            c.anchor = 1 if c.hand == "left" else 0       # A at the -x end, facing +x: left is -z
        else:
            c.start = 50                                  # A holds alone: no drawing to fit
    assert (grips(with_grips_fitted(sb))[("A", "left")], grips(with_grips_fitted(sb))[("A", "right")]) == (0, 1)


def test_people_drawn_at_the_two_ends_of_a_box_they_lift_hold_its_ends():
    """Both lifters joined to the same two grips, one on each end (the app's artist clicked the box's
    ends for both): of the grips no two hands share and no person crosses, those that fit the drawn
    hands are the ends' (each person's hands on one end), not the long sides' 20 cm apart for
    people a metre apart."""
    sb = sketchify(synthesize("lift_adjust", 3, fps=20), 4, 0.0, 3)
    own = sorted(sorted(c.anchor for c in sb.contacts if c.agent == agent) for agent in "AB")
    assert own == [[0, 1], [2, 3]]                                       # the synthesizer's
    for c in sb.contacts:
        c.anchor = 2 if c.hand == "left" else 0
    fitted = with_grips_fitted(sb)
    held = sorted(sorted(c.anchor for c in fitted.contacts if c.agent == agent) for agent in "AB")
    assert held == [[0, 1], [2, 3]]


def test_grips_that_are_possible_stay_whatever_the_drawing():
    sb = hand_off()
    for c in sb.contacts:                    # each person on one end: possible, if not as drawn
        c.anchor = {("A", "left"): 0, ("A", "right"): 1, ("B", "left"): 3, ("B", "right"): 2}[(c.agent, c.hand)]
    assert grips(with_grips_fitted(sb)) == grips(sb)


def faces_held(sb: Storyboard) -> list[set[int]]:
    """Each person's two grips where both hands hold one object at once."""
    return [{left.anchor, right.anchor} for left in sb.contacts for right in sb.contacts
            if (left.agent, left.hand, right.hand) == (right.agent, "left", "right") and left.object
            and left.object == right.object and left.start <= right.end and right.start <= left.end]


@pytest.mark.parametrize("drawing", [5, 6, 9])
def test_lifters_drawn_by_hand_hold_one_face_each(drawing):
    """Joined to the grips nearest their stretched, shifted drawing, the lifters of this box were
    fitted to diagonal corners (the near grip of one end, the far one of the other), which no hand
    reaches without an arm across the box: 8-13 cm inside it, a hand 18 cm off its grip."""
    sb = hand_drawn(sketchify(synthesize("lift_adjust", 7, fps=20), 4, 0.0, 7), drawing)
    assert faces_held(sb) and all(pair in ({0, 1}, {2, 3}, {0, 2}, {1, 3}) for pair in faces_held(sb))


def test_one_holder_on_diagonal_corners_holds_one_face():
    sb = hand_off()
    for c in sb.contacts:
        if c.agent == "A":
            c.anchor = 0 if c.hand == "left" else 3
        else:
            c.start = 50                                  # A holds alone
    assert faces_held(with_grips_fitted(sb))[0] in ({0, 1}, {2, 3}, {0, 2}, {1, 3})   # an end or a side
    assert with_grips_fitted(with_grips_fitted(sb)).contacts == with_grips_fitted(sb).contacts


def test_carriers_of_a_table_joined_to_its_long_sides_hold_its_ends():
    """Each carrier joined to the two grips of one long side of a table (1.2 m apart): on one face,
    but no carry holds it so (fitted to it, both hands were 45-60 cm off their grips the whole
    carry). Fitted to the drawn hands, each holds an end, as the synthesizer's carriers do."""
    sb = sketchify(synthesize("carry_together", 5, fps=20), 4, 0.0, 5)
    assert sb.objects[0].spec.type == "table" and sorted(faces_held(sb), key=min) == [{0, 1}, {2, 3}]
    for c in sb.contacts:
        c.anchor = {("A", "left"): 1, ("A", "right"): 3, ("B", "left"): 2, ("B", "right"): 0}[(c.agent, c.hand)]
    assert sorted(faces_held(with_grips_fitted(sb)), key=min) == [{0, 1}, {2, 3}]

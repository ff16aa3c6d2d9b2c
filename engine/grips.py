"""Which grip each hand holds: one hand to a grip, and a person's left hand on their left.

An object's anchors are the places a hand holds it (engine.objects.default_anchors: a box has a
near and a far grip on each end). In the app an artist joins a hand to the side of an object the
hand is drawn at; which of the grips there is a detail no 2D drawing settles, and mistakes
follow. Two hands on one grip at once (both people at a hand-off clicked the box's ends): finishing
put the giver's hands on the taker's, 58 cm from where they were drawn. A person's two hands
crossed (the left on the grip at their right): no turn of the box fits both hands, and at the
hand-off the hands ended 20 cm off their grips. Or on diagonal corners (the near grip of one end,
the far one of the other), which no hand reaches without an arm across the object: two lifters
fitted so to their drawing had wrists 8-13 cm inside the box and a hand 18 cm off its grip. Or
on one face but wider apart than a carry holds (a table's long side: hands 45-60 cm off). A
storyboard is read with these mended, and the app mends them as contacts are drawn.
"""
from __future__ import annotations

import copy
import itertools
from dataclasses import replace

import numpy as np

from .camera import StoryboardCamera
from .skeleton import HANDS
from .storyboard import HANDS as HAND_NAMES
from .storyboard import Contact, Storyboard
from .synth.reach import yaw_matrix

UP = np.array([0.0, 1.0, 0.0])
TURNS = 72          # turns of an object about the vertical tried when fitting its grips to drawn hands
NEAR_FRAMES = 8     # a person's keypose this close to a shared hold draws their hands in it
ONE_FACE = 0.01     # m: two grips whose midpoint is this far off the object's centre share a face
MOST_SPAN = 1.0     # m: the farthest apart one person's two grips may be (a table's long side, 1.2-1.4 m:
                    # a carrier fitted to it had both hands 45-60 cm off their grips the whole carry)


def _overlap(a: Contact, b: Contact) -> bool:
    """Whether two contacts' spans share a frame."""
    return a.start <= b.end and b.start <= a.end


def held_by_others(contact: Contact, contacts: list[Contact]) -> set[int]:
    """Anchors of `contact`'s object that another hand among `contacts` holds at some frame of
    its span."""
    return {c.anchor for c in contacts if c.object == contact.object and _overlap(c, contact)
            and (c.agent, c.hand) != (contact.agent, contact.hand)}


def free_anchors(storyboard: Storyboard, contact: Contact) -> list[int]:
    """`contact`'s object's anchors that no other hand holds over its span, nearest its own first
    (in the object's frame)."""
    anchors = _anchors(storyboard, contact)
    taken = held_by_others(contact, storyboard.contacts)
    order = np.argsort(np.linalg.norm(anchors - anchors[contact.anchor], axis=-1), kind="stable")
    return [int(k) for k in order if k not in taken]


def anchors_in_sketch(anchors: np.ndarray, outline: np.ndarray, camera: StoryboardCamera) -> np.ndarray:
    """Where an object's K anchors (K, 3) show on its sketched outline (P, 2), as the app's contact
    tool offers them: on the -x end at the outline's left side, +x at its right, each moved by its
    depth (local z) as the camera sees it (near and far grips) -> (K, 2)."""
    lo, hi = outline.min(axis=0), outline.max(axis=0)
    sides = np.where(anchors[:, :1] < 0, [[lo[0], (lo[1] + hi[1]) / 2]], [[hi[0], (lo[1] + hi[1]) / 2]])
    depth = np.stack([np.zeros(len(anchors)), np.zeros(len(anchors)), anchors[:, 2]], -1)
    return sides + depth @ camera.basis()[:2].T


def _anchors(storyboard: Storyboard, contact: Contact) -> np.ndarray:
    """(K, 3) local anchors of the contact's object."""
    return storyboard.objects[storyboard.object_index(contact.object)].spec.anchors


def _uncrossed(storyboard: Storyboard, left: Contact, right: Contact) -> bool:
    """Whether a person holding `left`'s and `right`'s grips of one object at once holds them as
    hands can: both grips on one face (not diagonal corners, whose midpoint is the object's
    centre) and within MOST_SPAN of each other, standing off that face, facing it, the left hand on
    their left."""
    anchors = _anchors(storyboard, left)
    a, b = anchors[left.anchor], anchors[right.anchor]
    outward = (a + b) * (1.0, 0.0, 1.0)              # from the object's centre to the face held
    return bool(np.linalg.norm(outward) > ONE_FACE and np.linalg.norm(a - b) <= MOST_SPAN
                and np.cross(UP, -outward) @ (a - b) >= 0.0)


def _held_together(storyboard: Storyboard, holds: list[Contact]) -> list[tuple[list[int], np.ndarray | None]]:
    """Holds of one object (indices into `holds`) that overlap in time, two or more people's, with
    each hand as its person's keypose nearest the frames they share draws it (hands, 2), or None
    where some hand no keypose within NEAR_FRAMES draws."""
    out = []
    for obj in dict.fromkeys(c.object for c in holds):
        mine = [i for i, c in enumerate(holds) if c.object == obj]
        while mine:
            group, grown = [mine.pop(0)], True
            while grown:                          # every hold overlapping one in the group joins it
                grown = [i for i in mine if any(_overlap(holds[i], holds[g]) for g in group)]
                group += grown
                mine = [i for i in mine if i not in grown]
            if len({holds[i].agent for i in group}) < 2:
                continue
            shared = (max(holds[i].start for i in group), min(holds[i].end for i in group))
            out.append((group, _drawn_hands(storyboard, [holds[i] for i in group], shared)))
    return out


def _drawn_hands(storyboard: Storyboard, holds: list[Contact], frames: tuple[int, int]) -> np.ndarray | None:
    """The holds' hands (hands, 2) as drawn near the frames [first, last] (_drawn_near), or None
    where one of them is not."""
    drawn = [_drawn_near(storyboard, c, frames) for c in holds]
    return None if any(d is None for d in drawn) else np.stack(drawn)


def _drawn_near(storyboard: Storyboard, contact: Contact, frames: tuple[int, int]) -> np.ndarray | None:
    """The contact's hand (2,) as its person's keypose nearest the frames [first, last] draws it,
    or None where none within NEAR_FRAMES does."""
    wrist = HANDS[HAND_NAMES.index(contact.hand)]
    first, last = min(frames), max(frames)
    keys = [k for k in storyboard.keyposes if k.agent == contact.agent and k.mask[wrist]]
    away = [max(first - k.frame, k.frame - last, 0) for k in keys]
    if not keys or min(away) > NEAR_FRAMES:
        return None
    return keys[int(np.argmin(away))].points[wrist]


def _misfit(storyboard: Storyboard, holds: list[Contact], drawn: np.ndarray,
            anchors: np.ndarray) -> np.ndarray:
    """How far (m^2, summed) the best turn of the object about the vertical, moved anywhere, puts
    its grips from the drawn hands (hands, 2), for each row of grip choices `anchors` (A, hands)
    -> (A,)."""
    local = _anchors(storyboard, holds[0])[anchors]                                 # (A, hands, 3)
    turns = np.linspace(0.0, 2 * np.pi, TURNS, endpoint=False)
    shown = np.einsum("tjk,ahk->athj", yaw_matrix(turns), local)                     # (A, T, hands, 3)
    shown = shown @ storyboard.camera.basis()[:2].T                                  # (A, T, hands, 2)
    gap = drawn - shown
    gap = gap - gap.mean(axis=2, keepdims=True)                                      # moved anywhere
    return (gap ** 2).sum(axis=(2, 3)).min(axis=1)


def _fit_to_drawing(storyboard: Storyboard, holds: list[Contact], drawn: np.ndarray | None) -> None:
    """Hands that hold one object together and share or cross grips get the grips (one each, no
    person's hands crossed) that fit their drawn places (hands, 2) best (_chosen); grips that are
    possible stay (the drawing is a few frames and centimetres off, the artist's choice is not)."""
    given = tuple(c.anchor for c in holds)
    if len(set(given)) == len(given) and _uncrossed_choice(storyboard, holds, given):
        return
    count = len(_anchors(storyboard, holds[0]))
    options = [p for p in itertools.permutations(range(count), len(holds))
               if _uncrossed_choice(storyboard, holds, p)]
    _chosen(storyboard, holds, options, drawn)


def _chosen(storyboard: Storyboard, holds: list[Contact], options: list[tuple[int, ...]],
            drawn: np.ndarray | None) -> None:
    """`holds` given the grip choice of `options` (one grip a hold each) that fits their drawn
    hands (hands, 2) best, or with no drawing (None) the one that keeps the most grips given."""
    if not options:
        return
    if drawn is not None:
        best = options[int(np.argmin(_misfit(storyboard, holds, drawn, np.array(options))))]
    else:
        best = max(options, key=lambda o: sum(a == c.anchor for a, c in zip(o, holds)))
    for c, anchor in zip(holds, best):
        c.anchor = anchor


def _uncrossed_choice(storyboard: Storyboard, holds: list[Contact], choice: tuple[int, ...]) -> bool:
    """Whether giving `holds` the grips `choice` (one each) crosses no person's hands."""
    trial = [copy.copy(c) for c in holds]
    for c, anchor in zip(trial, choice):
        c.anchor = anchor
    return all(_uncrossed(storyboard, a, b) for a in trial for b in trial
               if a.agent == b.agent and a.hand == "left" and b.hand == "right")


def with_grips_fitted(storyboard: Storyboard) -> Storyboard:
    """The storyboard with its object holds' grips mended (its contacts copied): people holding
    one object at once, sharing or crossing grips, get the grips that fit their drawn hands best
    (_fit_to_drawing); then every hold whose grip an earlier hold's hand holds over part of its span
    has the nearest grip no other hand holds then (or keeps its own where none is free), and a
    person's two hands holding one object at once swap grips where the left one holds the grip on
    their right (_pair_mended where that is not enough: hands on diagonal corners)."""
    out = replace(storyboard, contacts=copy.deepcopy(storyboard.contacts))   # the rest is only read
    holds = [c for c in out.contacts if c.object is not None]
    for together, drawn in _held_together(out, holds):
        _fit_to_drawing(out, [holds[i] for i in together], drawn)
    for i, c in enumerate(holds):
        if c.anchor in held_by_others(c, holds[:i]):
            c.anchor = (free_anchors(out, c) or [c.anchor])[0]
    for left in (c for c in holds if c.hand == "left"):
        for right in (c for c in holds
                      if c.hand == "right" and c.agent == left.agent and c.object == left.object):
            if _overlap(left, right) and left.anchor != right.anchor and not _uncrossed(out, left, right):
                left.anchor, right.anchor = right.anchor, left.anchor
                if not _uncrossed(out, left, right):
                    _pair_mended(out, [c for c in holds if c is not left and c is not right], left, right)
    return out


def _pair_mended(storyboard: Storyboard, others: list[Contact], left: Contact, right: Contact) -> None:
    """A person's two hands on grips of one object that no hands hold so (diagonal corners): the two
    grips that `others` leave free over their spans, on one face, left hand left (_chosen: as the
    person's keypose near the frames both hold draws the hands)."""
    count = len(_anchors(storyboard, left))
    free = [[k for k in range(count) if k not in held_by_others(c, others)] for c in (left, right)]
    options = [(a, b) for a in free[0] for b in free[1]
               if a != b and _uncrossed_choice(storyboard, [left, right], (a, b))]
    shared = (max(left.start, right.start), min(left.end, right.end))
    _chosen(storyboard, [left, right], options, _drawn_hands(storyboard, [left, right], shared))

"""Which grip each hand holds: one hand to a grip, and a person's left hand on their left.

An object's anchors are the places a hand holds it (engine.objects.default_anchors: a box has a
near and a far grip on each end). In the app an artist joins a hand to the side of an object the
hand is drawn at; which of the grips there is a detail no 2D drawing settles, and two mistakes
follow. Two hands on one grip at once (both people at a hand-off clicked the box's ends): finishing
put the giver's hands on the taker's, 58 cm from where they were drawn. A person's two hands
crossed (the left on the grip at their right): no turn of the box fits both hands, and at the
hand-off the hands ended 20 cm off their grips. A storyboard is read with both mended, and the
app mends them as contacts are drawn.
"""
from __future__ import annotations

import copy

import numpy as np

from .storyboard import Contact, Storyboard

UP = np.array([0.0, 1.0, 0.0])


def _overlap(a: Contact, b: Contact) -> bool:
    return a.start <= b.end and b.start <= a.end


def held_by_others(contact: Contact, contacts: list[Contact]) -> set[int]:
    """Anchors of `contact`'s object that another hand among `contacts` holds at some frame of
    its span."""
    return {c.anchor for c in contacts
            if c.object == contact.object and (c.agent, c.hand) != (contact.agent, contact.hand) and _overlap(c, contact)}


def free_anchors(storyboard: Storyboard, contact: Contact) -> list[int]:
    """`contact`'s object's anchors that no other hand holds over its span, nearest its own first
    (in the object's frame)."""
    anchors = _anchors(storyboard, contact)
    taken = held_by_others(contact, storyboard.contacts)
    order = np.argsort(np.linalg.norm(anchors - anchors[contact.anchor], axis=-1), kind="stable")
    return [int(k) for k in order if k not in taken]


def _anchors(storyboard: Storyboard, contact: Contact) -> np.ndarray:
    """(K, 3) local anchors of the contact's object."""
    return storyboard.objects[storyboard.object_index(contact.object)].spec.anchors


def _uncrossed(storyboard: Storyboard, left: Contact, right: Contact) -> bool:
    """Whether a person holding `left`'s and `right`'s grips of one object at once has their left
    hand on their left: standing off the face the two grips are on, facing it."""
    anchors = _anchors(storyboard, left)
    a, b = anchors[left.anchor], anchors[right.anchor]
    outward = (a + b) * (1.0, 0.0, 1.0)              # from the object's centre to the face held
    return bool(np.cross(UP, -outward) @ (a - b) >= 0.0)


def with_grips_fitted(storyboard: Storyboard) -> Storyboard:
    """A copy of the storyboard in which every object contact whose grip an earlier contact's hand
    holds over part of its span has the nearest grip no other hand holds then (or keeps its own
    where none is free), and a person's two hands holding one object at once swap grips where the
    left one holds the grip on their right."""
    out = copy.deepcopy(storyboard)
    holds = [c for c in out.contacts if c.object is not None]
    for i, c in enumerate(holds):
        if c.anchor in held_by_others(c, holds[:i]):
            c.anchor = (free_anchors(out, c) or [c.anchor])[0]
    for left in (c for c in holds if c.hand == "left"):
        for right in (c for c in holds if c.hand == "right" and c.agent == left.agent and c.object == left.object):
            if _overlap(left, right) and left.anchor != right.anchor and not _uncrossed(out, left, right):
                left.anchor, right.anchor = right.anchor, left.anchor
    return out

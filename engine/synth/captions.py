"""Captions for clips: what the storyboard's optional text says, written from the motion itself.

`caption(clip, rng)` describes a clip in one sentence drawn from several templates and synonyms
(so that a text encoder trained on them learns the content, not one template): the scenario's
verbs, the object, who does what (the first or second person, as the storyboard orders its
people), how fast they move and when the hands go on. Everything is read off the clip (its
scenario name, object type, per-hand contact labels, pelvis speed, object height), so imported
capture gets captions too.
"""
from __future__ import annotations

import numpy as np

from ..clip import MotionClip

PEOPLE = ("two people", "a pair", "both people", "two friends", "the two")
FIRST = ("the first person", "person one", "the first one")
SECOND = ("the second person", "person two", "the second one")
OBJECTS = {"box": ("box", "crate", "carton"), "table": ("table", "desk"), "canister": ("canister", "drum", "barrel")}
SLOW, FAST = ("slowly", "carefully", "unhurriedly"), ("quickly", "briskly", "fast")
EARLY, LATE = ("right away", "soon", "early on"), ("after a while", "later", "near the end")
CARRY = ("carry", "move", "haul")
CARRIES = ("carries", "moves", "hauls")
LIFT = ("lift", "pick up", "raise")
PUT = ("put it down", "set it down", "place it on the floor")
SLOW_SPEED, FAST_SPEED = 0.55, 0.9     # m/s of pelvis travel while moving


def caption(clip: MotionClip, rng: np.random.Generator) -> str:
    """One sentence for the clip (lower case, no final full stop)."""
    pick = lambda options: options[int(rng.integers(len(options)))]          # noqa: E731
    scenario = clip.scenario if not clip.scenario.startswith("bvh:") else "dance"
    noun = pick(OBJECTS.get(str(clip.obj_type[0]), ("object",))) if clip.num_objects and clip.obj_type is not None else "object"
    pace = _pace(clip)
    adverb = pick(SLOW) if pace == "slow" else pick(FAST) if pace == "fast" else ""
    when = _when(clip)
    timing = pick(EARLY) if when == "early" else pick(LATE) if when == "late" else ""
    first, second = _roles(clip)
    who = {0: pick(FIRST), 1: pick(SECOND)}
    people = pick(PEOPLE)
    if scenario == "handshake":
        text = pick((f"{people} walk up to each other {adverb} and shake right hands {timing}",
                     f"{people} meet {timing} and shake hands",
                     f"{who[0]} and {who[1]} approach {adverb} and shake hands"))
    elif scenario == "handoff":
        text = pick((f"{who[first]} {pick(CARRIES)} the {noun} {adverb} and hands it to {who[second]} {timing}",
                     f"{who[first]} brings the {noun} over and {who[second]} takes it and {pick(CARRIES)} it away",
                     f"{people} pass a {noun}: {who[first]} gives it to {who[second]} {timing}"))
    elif scenario == "let_go":
        text = pick((f"{people} {pick(LIFT)} the {noun} and {pick(CARRY)} it {adverb}, then {who[first]} lets go "
                     f"and {who[second]} finishes alone",
                     f"{people} {pick(CARRY)} a {noun} together until {who[first]} lets go {timing}",
                     f"{who[second]} ends up carrying the {noun} alone after {who[first]} lets go"))
    elif scenario == "lift_adjust":
        change = pick(("raise it higher", "lift it up")) if _raised(clip) else pick(("lower it", "bring it down"))
        text = pick((f"{people} {pick(CARRY)} the {noun} {adverb} and {change} on the way, then {pick(PUT)}",
                     f"{people} {pick(LIFT)} a {noun} together and {change} while walking",
                     f"carrying the {noun} together, {people} {change} halfway"))
    elif scenario == "carry_together":
        text = pick((f"{people} {pick(LIFT)} the {noun} and {pick(CARRY)} it together {adverb}, then {pick(PUT)}",
                     f"{people} {pick(CARRY)} a {noun} together {timing}",
                     f"{who[0]} and {who[1]} {pick(LIFT)} the {noun} by its ends and {pick(CARRY)} it {adverb}"))
    elif scenario == "dance":
        text = pick((f"{people} dance salsa {adverb}", f"{people} dance together, holding hands",
                     f"a couple dances salsa {adverb}"))
    else:
        text = f"{people} move {adverb}"
    return " ".join(text.split()).replace(" ,", ",")


def _pace(clip: MotionClip) -> str:
    """"slow", "fast" or "" from the people's mean pelvis speed while moving."""
    pelvis = clip.joints[:, :, 0, [0, 2]]                                    # (N, H, 2)
    speed = np.linalg.norm(np.diff(pelvis, axis=0), axis=-1) * clip.fps      # (N-1, H)
    moving = speed[speed > 0.2]
    if moving.size < clip.fps:                                               # under a second of walking
        return ""
    mean = float(moving.mean())
    return "slow" if mean < SLOW_SPEED else "fast" if mean > FAST_SPEED else ""


def _when(clip: MotionClip) -> str:
    """"early", "late" or "" from the first frame any hand holds something."""
    if clip.contact is None or not clip.contact.any():
        return ""
    start = int(np.argmax(clip.contact.reshape(clip.num_frames, -1).any(1))) / max(clip.num_frames - 1, 1)
    return "early" if start < 0.25 else "late" if start > 0.5 else ""


def _roles(clip: MotionClip) -> tuple[int, int]:
    """(first, second): who holds first in a hand-off, who lets go first in a shared carry."""
    if clip.contact is None or clip.num_humans < 2 or not clip.contact.any():
        return 0, 1
    held = clip.contact.any(-1)                                              # (N, H)
    if clip.scenario == "let_go":
        last = [np.flatnonzero(held[:, h]).max() if held[:, h].any() else -1 for h in range(2)]
        return (0, 1) if last[0] <= last[1] else (1, 0)
    first = [np.flatnonzero(held[:, h]).min() if held[:, h].any() else clip.num_frames for h in range(2)]
    return (0, 1) if first[0] <= first[1] else (1, 0)


def _raised(clip: MotionClip) -> bool:
    """Whether the carried object goes higher mid-carry than where it was first lifted to."""
    if clip.obj_pose is None:
        return True
    height = clip.obj_pose[:, 0, 1]
    lifted = height > height.min() + 0.2
    if lifted.sum() < 3:
        return True
    carried = height[lifted]
    middle = carried[len(carried) // 3: 2 * len(carried) // 3]
    return float(middle.mean() - carried[: len(carried) // 6 + 1].mean()) >= 0.0

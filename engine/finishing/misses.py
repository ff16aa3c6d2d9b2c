"""What finishing could not make exact, said the way an artist can act on it.

A hold drawn where the body cannot reach (a keypose a step too far from the object, a hold that
starts before its holder gets there) leaves the hand short of its grip: finishing keeps the
sketched keypose and reaches as far as the arm goes. Rather than leave that silent, each such
hold becomes one line for the person who drew it.
"""
from __future__ import annotations

import numpy as np

from ..clip import MotionClip
from ..geometry.rotations import norm
from ..skeleton import HANDS
from ..storyboard import HANDS as HAND_NAMES
from ..storyboard import Contact, Storyboard

GRIP_TOLERANCE = 0.03   # m: a hand this close to its grip holds it (issue 18's hand-to-grip bound)


def hold_gaps(clip: MotionClip, storyboard: Storyboard) -> list[tuple[Contact, np.ndarray, np.ndarray]]:
    """For each object hold: the contact, its frames (M,) and the wrist-to-grip distance (M,) in
    them (the clip at the storyboard's frames). Nothing without object anchors."""
    if clip.obj_anchors is None:
        return []
    out = []
    for c in storyboard.contacts:
        if c.object is None:
            continue
        h, o = storyboard.agent_index(c.agent), storyboard.object_index(c.object)
        frames = np.arange(c.start, c.end + 1)
        wrist = np.asarray(clip.joints[frames, h, HANDS[HAND_NAMES.index(c.hand)]], float)
        out.append((c, frames, norm(wrist - clip.obj_anchors[frames, o, c.anchor])))
    return out


def missed_holds(clip: MotionClip, storyboard: Storyboard, tolerance: float = GRIP_TOLERANCE) -> list[str]:
    """One note per object hold whose hand ends farther than `tolerance` from its grip in any of
    its frames: who, which hand, how far at worst, in which frames; the worst miss first."""
    notes = []
    for c, frames, gap in hold_gaps(clip, storyboard):
        short = frames[gap > tolerance]
        if len(short):
            runs = np.split(short, np.flatnonzero(np.diff(short) > 1) + 1)
            where = ", ".join(f"{r[0]}" if len(r) == 1 else f"{r[0]}-{r[-1]}" for r in runs)
            frames_word = "frame" if len(short) == 1 else "frames"
            notes.append((gap.max(), f"{c.agent}'s {c.hand} hand misses the {c.object}'s grip by up to "
                          f"{100 * gap.max():.0f} cm ({frames_word} {where}): move {c.agent} closer there, or the "
                          f"hold's start or end"))
    return [note for _, note in sorted(notes, key=lambda n: -n[0])]

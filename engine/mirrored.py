"""Figures posed from a template that faces the other way: only their hands, feet and head are
the artist's.

The canvas's pose tool places a standing template facing the camera; an artist posing a person
who faces away drags the hands and feet to where they belong, and the template's hips, shoulders,
knees and elbows stay facing the camera, its left on the right of the picture. Solved as drawn,
such a keypose turns the person round by half a turn (two carriers of a box stood back to back,
one walked through the other to its grips: hands 22 cm off them, a chest 24 cm inside the box).
Its tell is both arms and both legs crossed over: hands on the far side of their own shoulders'
line, feet on the far side of their own hips' (no hand-drawn key of 240 artist-style ones crossed
both; 112 of 131 posed keys of people facing away did: 60 storyboards of the artist-style
protocol). There, those joints are taken as unplaced.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from .skeleton import JOINT_INDEX, NUM_JOINTS
from .storyboard import Keypose, Storyboard

TEMPLATE_JOINTS = [JOINT_INDEX[name] for name in ("l_hip", "r_hip", "l_knee", "r_knee", "l_collar", "r_collar",
                                                  "l_shoulder", "r_shoulder", "l_elbow", "r_elbow")]
TEMPLATE = np.isin(np.arange(NUM_JOINTS), TEMPLATE_JOINTS)   # (22,) bool
# (left, right, left end, right end): the shoulders and the wrists, the hips and the ankles
_CROSSINGS = [tuple(JOINT_INDEX[name] for name in names) for names in
              (("l_shoulder", "r_shoulder", "l_wrist", "r_wrist"), ("l_hip", "r_hip", "l_ankle", "r_ankle"))]


def crossed_over(keypose: Keypose) -> bool:
    """Whether both of the figure's arms and both of its legs cross over: each pair of hands (feet)
    lies the other way round from its shoulders (hips). A figure whose depth is known (a turned or
    library pose) faces the way it was turned: never."""
    if keypose.depth is not None:
        return False
    p = keypose.points
    return all(keypose.mask[list(joints)].all() and np.dot(p[right] - p[left], p[right_end] - p[left_end]) < 0.0
               for joints in _CROSSINGS for left, right, left_end, right_end in [joints])


def without_mirrored_template(storyboard: Storyboard) -> Storyboard:
    """The storyboard with the template's joints of each crossed-over keypose unplaced (itself
    where none crosses over)."""
    if not any(crossed_over(k) for k in storyboard.keyposes):
        return storyboard
    return replace(storyboard, keyposes=[replace(k, mask=k.mask & ~TEMPLATE) if crossed_over(k) else k
                                         for k in storyboard.keyposes])

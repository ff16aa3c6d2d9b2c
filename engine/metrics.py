"""Evaluation metrics, defined exactly as in DESIGN.md section 4. numpy in, floats out.

Units are metres on world joints; frames at the clip's fps; Y up.
"""
from __future__ import annotations

import numpy as np

from .skeleton import FEET

FOOT_CONTACT_HEIGHT = 0.05   # m
FOOT_SKATE_SPEED = 0.5       # m/s


def foot_skate_ratio(joints: np.ndarray, fps: float, window: int = 1) -> float:
    """Share of frames in which a planted foot slides.

    joints: (N, 22, 3) one person, or (N, H, 22, 3) (the mean over people is returned).
    A foot (l_foot, r_foot) is in contact at frame n when its height is under 0.05 m at n and
    n + window (consecutive frames for window 1); such a frame skates when the foot's horizontal speed exceeds 0.5 m/s, the speed
    measured over `window` frames (1 = consecutive frames; DESIGN also reports 5).
    Ratio = skating frames / (N - window), a frame counting once if either foot skates.
    """
    joints = np.asarray(joints, float)
    if joints.ndim == 4:
        return float(np.mean([foot_skate_ratio(joints[:, h], fps, window) for h in range(joints.shape[1])]))
    n = joints.shape[0]
    if n <= window:
        return 0.0
    feet = joints[:, FEET]                                        # (N, 2, 3)
    low = feet[:, :, 1] < FOOT_CONTACT_HEIGHT
    contact = low[:-window] & low[window:]                        # (N - w, 2)
    horiz = np.linalg.norm(feet[window:, :, [0, 2]] - feet[:-window, :, [0, 2]], axis=-1)
    speed = horiz * fps / window
    skating = np.any(contact & (speed > FOOT_SKATE_SPEED), axis=1)
    return float(skating.sum() / (n - window))

"""A pelvis that turns half round in a frame, spread over the frames around it.

In a fast turn the decoder moves each joint straight to where it will be, so the hips pass
through each other: their width shrinks to a few centimetres and the facing read off them
reverses between two frames (a 170-degree turn in 50 ms). The rigid skeleton fitted to that turns
the whole lower body at once, and the feet's plants re-solved after it swung a knee 50 cm in a
frame. Here such a flip of the pelvis' heading, far faster than any person turns (a real salsa
dancer's fastest, 230 degrees in three frames, is 77 a frame), is spread over the frames either
side of it, the rest of the skeleton refitted to the same joints from the turned pelvis (the
caller puts the turned legs back on the feet the unturned fit had). Joint arrays are one
person's, (N, 22, 3) in metres.
"""
from __future__ import annotations

import numpy as np
from scipy.ndimage import binary_dilation, label

from ..skeleton import inverse_kinematics
from ..synth.reach import heading_of, yaw_matrix

FLIP = np.deg2rad(120.0)   # a heading change in one frame faster than this is the decoder's, not a turn
SPREAD = 4                  # frames either side of a flip that share its turn


def spread_flips(joints: np.ndarray, rotations: np.ndarray, offsets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """One person's local rotations (N, 22, 3, 3) fitted to joints (N, 22, 3) with bone offsets
    (22, 3), with every flip of the pelvis' heading spread over SPREAD frames either side: the
    heading eased linearly (the shorter way round) across, the pelvis' tilt and every other joint
    refitted as before -> (rotations (N, 22, 3, 3), the frames changed (M,)). Clips without a
    flip come back as they are."""
    n = len(rotations)
    heading = heading_of(rotations[:, 0, :, 2])                                 # the pelvis' forward (+Z)
    step = np.angle(np.exp(1j * np.diff(heading)))                              # (N-1,) wrapped
    flips = np.abs(step) > FLIP
    # Two flips close together are a spin through a full turn (the real dancers': spread, their
    # pops grew from 4.2-6.2 to 4.7-9.0 cm), left as fitted.
    at = np.flatnonzero(flips)
    for f, gap in zip(at, np.minimum(np.diff(at, prepend=-n), np.diff(at, append=2 * n))):
        flips[f] = gap > 2 * SPREAD
    if not flips.any():
        return rotations, np.zeros(0, int)
    # frames whose heading is eased: the flip's two frames and SPREAD either side of them
    around = binary_dilation(np.concatenate([flips, [False]]) | np.concatenate([[False], flips]),
                             iterations=SPREAD)
    spans, count = label(around)
    unwrapped = heading[0] + np.concatenate([[0.0], np.cumsum(step)])
    eased = unwrapped.copy()
    for s in range(1, count + 1):
        frames = np.flatnonzero(spans == s)
        a, b = max(frames[0] - 1, 0), min(frames[-1] + 1, n - 1)
        eased[frames] = np.interp(frames, [a, b], [unwrapped[a], unwrapped[b]])
    frames = np.flatnonzero(around)
    root = yaw_matrix(eased[frames] - unwrapped[frames]) @ rotations[frames, 0]
    out = rotations.copy()
    out[frames] = inverse_kinematics(joints[frames], offsets, root=root)
    return out, frames
